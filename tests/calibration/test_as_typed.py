"""The user's own usage lines, exactly as typed: ``somo-sweep calibrate measurements.csv`` and
``somo-sweep diagnose measurements.csv`` in a folder holding only the CSV."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from somo_sweep.calibration.finger import read_finger_header
from somo_sweep.calibration.measurements import read_measurements
from somo_sweep.cli import app
from somo_sweep.errors import MeasurementError
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path

BUNDLED = bundled_path("tables", "planar_finger_bench_2.csv")


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    shutil.copy(BUNDLED, tmp_path / "measurements.csv")
    cwd = Path.cwd()
    os.chdir(tmp_path)
    yield tmp_path
    os.chdir(cwd)


def test_calibrate_as_typed_reads_the_finger_line_and_writes_under_results(folder: Path) -> None:
    result = CliRunner().invoke(app, ["calibrate", "measurements.csv"])
    assert result.exit_code == 0, result.output
    written = folder / "results" / "calibration" / "measurements" / "model.yaml"
    assert f"wrote {written.relative_to(folder)}" in result.output
    manip = load_model(written).manipulator
    assert manip is not None and manip.length_m == pytest.approx(0.100)
    assert manip.actuators[0].segments == 20 and manip.actuators[0].joint_placement == "midpoint"


def test_diagnose_as_typed_calibrates_first_and_names_the_bundled_effect(folder: Path) -> None:
    result = CliRunner().invoke(app, ["diagnose", "measurements.csv"])
    assert result.exit_code == 0, result.output
    assert "missing effect: actuation_saturation" in result.output
    assert (folder / "results" / "diagnosis" / "measurements" / "diagnosis.json").is_file()


def test_a_csv_without_finger_line_or_model_says_how_to_give_one(tmp_path: Path) -> None:
    lines = [ln for ln in BUNDLED.read_text().splitlines() if not ln.startswith("# finger:")]
    (tmp_path / "m.csv").write_text("\n".join(lines) + "\n")
    result = CliRunner().invoke(app, ["calibrate", str(tmp_path / "m.csv"), "-o", str(tmp_path / "x.yaml")])
    assert result.exit_code == 2
    assert "no finger to calibrate" in result.output and "# finger: {length_mm: 100" in result.output
    assert "--length-mm, --segments, --mass-g" in result.output


@pytest.mark.parametrize(
    ("line", "message"),
    [
        (
            "# finger: {length_mm: 100, segments: 20}",
            "line 1, finger header: mass_g (mass of the bending part, g; 0: weightless) is required",
        ),
        (
            "# finger: {length_mm: 100, segments: 0, mass_g: 20}",
            "segments must be a whole number from 1 to 126 (a base, the segments and a tip in PyBullet's "
            "128 links of a body), got 0",
        ),
        (
            "# finger: {length_mm: .nan, segments: 20, mass_g: 20}",
            "length_mm must be a finite number > 0, got nan",
        ),
        (
            "# finger: {length_mm: 100, segments: 20, mass_g: -1}",
            "mass_g must be a finite number >= 0, got -1",  # 0 is a weightless finger
        ),
        (
            "# finger: {lenght_mm: 100, segments: 20, mass_g: 20}",
            "unknown key 'lenght_mm'; allowed: length_mm",
        ),
        ("# finger: 100 mm", "write a mapping"),
        (
            "# finger: {length_mm: 100, segments: 20, mass_g: 20, mass_g: 3}",
            "key 'mass_g' is given twice",
        ),
        (
            "# finger: {length_mm: 100, segments: 20, mass_g: 20, width_mm: " + "[" * 100 + "]" * 100 + "}",
            "nested deeper than 64 levels; allowed: at most 64",
        ),
        (  # past libyaml's own limit of 1000 levels (PyYAML >= 6.0.4), once a RecursionError
            "# finger: {length_mm: 100, segments: 20, mass_g: 20, width_mm: " + "[" * 1500 + "]" * 1500 + "}",
            "nested deeper than 64 levels; allowed: at most 64",
        ),
        (
            "# finger: {length_mm: 100, segments: 20, mass_g: 20, note: '" + "a" * 100_000 + "'}",
            "longer than 4096 bytes; allowed: one short line",
        ),
    ],
)
def test_a_bad_finger_line_names_the_line_and_the_key(tmp_path: Path, line: str, message: str) -> None:
    path = tmp_path / "m.csv"
    path.write_text(line + "\ntest,pressure_kpa\n")
    with pytest.raises(MeasurementError, match="finger header") as info:
        read_finger_header(path)
    assert message in str(info.value)


def test_flags_override_the_finger_line(folder: Path) -> None:
    result = CliRunner().invoke(app, ["calibrate", "measurements.csv", "--segments", "10", "-o", "ten.yaml"])
    assert result.exit_code == 0, result.output
    manip = load_model(folder / "ten.yaml").manipulator
    assert manip is not None and manip.actuators[0].segments == 10


def test_a_huge_measurement_file_is_refused_with_the_limit(tmp_path: Path) -> None:
    path = tmp_path / "huge.csv"
    row = "free_bending,100,,,,90.0,-30.0\n"
    path.write_text(
        "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm\n" + row * 100_000
    )
    result = CliRunner().invoke(app, ["calibrate", str(path), "--model", "nope.yaml"])
    assert result.exit_code == 2
    assert "100000 data rows; a bench file may have at most 5000" in result.output
    assert len(result.output) < 2000


def test_many_bad_rows_are_listed_up_to_twenty_and_counted(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    row = "free_bending,abc,,,,90.0,-30.0\n"
    path.write_text(
        "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm\n" + row * 1000
    )
    with pytest.raises(MeasurementError) as info:
        read_measurements(path)
    # two per row: not a number, and then empty where the test needs it
    assert len(info.value.problems) == 2000
    text = str(info.value)
    assert text.startswith(f"{path}: 2000 problem(s)\n") and text.endswith("\n  … and 1980 more problem(s)")
    assert text.count("\n  - ") == 20


def test_the_problem_count_counts_every_problem_not_the_lines_listed(tmp_path: Path) -> None:
    """An all-inf file said "21 problem(s)", listed 20, then "… and 88 more problem(s)"."""
    path = tmp_path / "inf.csv"
    path.write_text(
        "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm\n"
        + "tip_load,inf,inf,inf,inf,inf,inf\n" * 18
    )
    result = CliRunner().invoke(app, ["calibrate", str(path), "--model", "ihm_finger"])
    assert result.exit_code == 2
    listed = [ln for ln in result.output.splitlines() if ln.startswith("  - ")]
    assert f"error: {path}: 108 problem(s)" in result.output and len(listed) == 20
    assert result.output.rstrip().endswith("  … and 88 more problem(s)")


def test_a_long_file_describes_its_rows_in_one_short_line() -> None:
    from somo_sweep.calibration.problem import line_numbers

    rows = pd.DataFrame({"line": range(2, 3002)})
    assert line_numbers(rows) == "2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, … (2988 more)"
