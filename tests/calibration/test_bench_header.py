"""The bench protocol stated in the CSV: ``# bench: {stop_z_mm: ...}``.

The blocked-force stop defaults to the straight finger's underside; a CSV may put it elsewhere
below it. ``calibrate`` and ``diagnose`` say which geometry they used; a bad line is refused like
a bad ``# finger:`` line (exit 2, the line named, nothing written).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from somo_sweep.calibration.bench_header import read_bench_header
from somo_sweep.calibration.measurements import measurements_csv
from somo_sweep.calibration.synthetic import (
    TRUE_GAIN_N_M_PER_KPA,
    TRUE_STIFFNESS_N_M_PER_RAD,
    bench_plan,
    example_finger,
    synthetic_rows,
)
from somo_sweep.cli.app import app
from somo_sweep.errors import MeasurementError
from somo_sweep.statics.bench import BenchSettings

runner = CliRunner()
FINGER = "finger: {length_mm: 100, segments: 20, mass_g: 20, width_mm: 20, thickness_mm: 15}"
#: The stop 3 mm below the 15-mm finger's underside (-7.5 mm).
STOP_MM = -10.5


def _csv(tmp_path: Path, header: str, name: str = "bench.csv") -> Path:
    """The example finger's rows (tip loads, blocked force 0–240 kPa), the stop at STOP_MM."""
    pressures = [float(p) for p in range(0, 241, 20)]
    rows = synthetic_rows(
        example_finger(),
        bench_plan([0.02 * i for i in range(1, 6)], pressures, pressures[::3]),
        0.0,
        np.random.default_rng(0),
        BenchSettings(stop_z_m=STOP_MM * 1e-3),
    )
    path = tmp_path / name
    path.write_text(measurements_csv(rows, header))
    return path


def test_calibrate_says_which_stop_it_used_and_fits_the_finger_only_with_the_right_one(
    tmp_path: Path,
) -> None:
    stated = _csv(tmp_path, f"{FINGER}\nbench: {{stop_z_mm: {STOP_MM}}}", "stated.csv")
    res = runner.invoke(
        app, ["calibrate", str(stated), "-o", str(tmp_path / "m.yaml"), "--report", str(tmp_path / "r")]
    )
    assert res.exit_code == 0, res.output
    said = " ".join(res.output.split())  # the console wraps long lines
    assert (
        f"bench: blocked-force stop at {STOP_MM:g} mm from the finger's centre line (3 mm below its "
        "underside), from line 2 of" in said
    )
    record = json.loads((tmp_path / "r" / "calibration.json").read_text())
    assert record["bench_stop_z_mm"] == pytest.approx(STOP_MM)
    values = {k: v["value"] for k, v in record["parameters"].items()}
    assert values["stiffness_n_m_per_rad[grasp]"] == pytest.approx(TRUE_STIFFNESS_N_M_PER_RAD, rel=2e-3)
    assert values["pressure_gain_n_m_per_kpa"] == pytest.approx(TRUE_GAIN_N_M_PER_KPA, rel=2e-3)

    # The same rows without the line: the default stop, said so, and a biased gain.
    default = _csv(tmp_path, FINGER, "default.csv")
    res = runner.invoke(
        app, ["calibrate", str(default), "-o", str(tmp_path / "d.yaml"), "--report", str(tmp_path / "d")]
    )
    assert res.exit_code == 0, res.output
    said = " ".join(res.output.split())
    assert (
        "bench: blocked-force stop at the finger's underside, -7.5 mm from its centre line (the default"
        in said
    )
    record = json.loads((tmp_path / "d" / "calibration.json").read_text())
    assert record["bench_stop_z_mm"] == "underside"
    gain = record["parameters"]["pressure_gain_n_m_per_kpa"]["value"]
    assert abs(gain / TRUE_GAIN_N_M_PER_KPA - 1) > 0.05


def test_diagnose_says_which_stop_it_used(tmp_path: Path) -> None:
    stated = _csv(tmp_path, f"{FINGER}\nbench: {{stop_z_mm: {STOP_MM}}}")
    res = runner.invoke(
        app, ["diagnose", str(stated), "--out", str(tmp_path / "o"), "--effects", "self_weight"]
    )
    assert res.exit_code == 0, res.output
    assert f"bench: blocked-force stop at {STOP_MM:g} mm from the finger's centre line" in res.output
    record = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    assert record["bench_stop_z_mm"] == pytest.approx(STOP_MM)
    assert record["missing_effect"] == "none"


@pytest.mark.parametrize(
    ("lines", "message"),
    [
        (
            ["bench: {stop_z_mm: -9}", "bench: {stop_z_mm: -10}"],
            "lines 2 and 3: the bench header is given twice",
        ),
        (["bench: {stop_mm: -9}"], "line 2, bench header: unknown key 'stop_mm'; allowed: stop_z_mm"),
        (["bench: {stop_z_mm: deep}"], "line 2, bench header: stop_z_mm (blocked-force stop's top"),
        (["bench: {stop_z_mm: .nan}"], "must be a finite number from -100000 to 100000, got nan"),
        (["bench: stop 9 mm down"], "line 2, bench header: write a mapping, e.g. {stop_z_mm: -9}"),
        (["bench: {stop: tip}"], "line 2, bench header: stop (what the blocked-force stop touches: plate"),
        (["bench: {stop: [plate]}"], "must be one of plate, fingertip, got ['plate']"),
        (
            ["bench: {stop_z_mm: -0.5}"],
            "line 2, bench header: the blocked-force stop at -0.5 mm from the finger's centre line is "
            "above the straight finger's underside (-7.5 mm",
        ),
        (
            ["bench: {stop_z_mm: -150}"],
            "line 2, bench header: the blocked-force stop at -150 mm is more than the finger's length",
        ),
    ],
)
def test_a_bad_bench_line_exits_2_naming_the_line_and_writes_nothing(
    tmp_path: Path, lines: list[str], message: str
) -> None:
    csv = _csv(tmp_path, "\n".join([FINGER, *lines]))
    for command in (
        ["calibrate", str(csv), "-o", str(tmp_path / "m.yaml")],
        ["diagnose", str(csv), "--out", str(tmp_path / "o")],
    ):
        res = runner.invoke(app, command)
        assert res.exit_code == 2, res.output
        assert message in " ".join(res.output.split()), res.output
        assert not (tmp_path / "m.yaml").exists() and not (tmp_path / "o").exists()


def test_a_bench_line_after_the_column_header_is_refused_naming_its_line(tmp_path: Path) -> None:
    """It was ignored without a word: the stop stayed at the default."""
    csv = _csv(tmp_path, FINGER)
    lines = csv.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines, start=1) if not ln.startswith("#"))
    lines.insert(header + 2, "# bench: {stop_z_mm: -9}")
    csv.write_text("\n".join(lines) + "\n")
    message = (
        f"line {header + 3}: the bench header is after the column header (line {header}), where it is "
        "not read; allowed: one '# bench:' line above the header"
    )
    with pytest.raises(MeasurementError) as info:
        read_bench_header(csv)
    assert str(csv) in str(info.value) and message in str(info.value)
    res = runner.invoke(app, ["calibrate", str(csv), "-o", str(tmp_path / "m.yaml")])
    assert res.exit_code == 2, res.output
    assert message in " ".join(res.output.split()), res.output
    with pytest.raises(MeasurementError, match="bench header is given twice"):
        read_bench_header(_csv(tmp_path, "bench: {stop_z_mm: -9}\nBENCH: {stop_z_mm: -9}", "twice.csv"))


def test_a_fingertip_stop_is_read_said_and_passed_to_the_bench(tmp_path: Path) -> None:
    csv = _csv(tmp_path, f"{FINGER}\nbench: {{stop: fingertip, stop_z_mm: {STOP_MM}}}")
    header = read_bench_header(csv)
    assert (header.stop, header.stop_z_mm, header.line) == ("fingertip", STOP_MM, 2)
    manip = example_finger().manipulator
    assert manip is not None
    settings = header.settings(BenchSettings(), manip)
    assert (settings.stop, settings.stop_z_m) == ("fingertip", pytest.approx(STOP_MM * 1e-3))
    assert "; a fingertip stop (only the finger's end touches it), from line 2 of" in header.describe(manip)
    plain = read_bench_header(_csv(tmp_path, FINGER, "plain.csv"))
    assert plain.stop == "plate" and plain.settings(BenchSettings(), manip).stop == "plate"
    assert "fingertip" not in plain.describe(manip)
