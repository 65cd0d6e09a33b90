"""A bench CSV is opened and decoded once; its headers and rows are parsed from that one text."""

from __future__ import annotations

import builtins
from pathlib import Path
from typing import Any

import pytest

from somo_sweep.calibration import bench_file as bench_file_module
from somo_sweep.calibration.bench_file import read_bench_file
from somo_sweep.calibration.bench_header import bench_header
from somo_sweep.calibration.finger import finger_header
from somo_sweep.calibration.measurements import parse_measurements
from somo_sweep.calibration.workflow import CalibrationOptions, Reporter, calibrate_csv
from somo_sweep.diagnosis.workflow import DiagnosisOptions, diagnose_csv
from somo_sweep.errors import MeasurementError

CSV = (
    "# finger: {length_mm: 100, segments: 10, mass_g: 0}\n"
    "# bench: {stop: fingertip}\n"
    "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm\n"
    "tip_load,0,0.01,1.5,,,\n"
    "tip_load,0,0.02,3.0,,,\n"
    "blocked_force,50,,,0.2,,\n"
    "blocked_force,100,,,0.4,,\n"
)


def _counting_opens(monkeypatch: pytest.MonkeyPatch, path: Path) -> list[str]:
    """One entry each time ``path`` is opened (Path.open, which read_bytes and read_text use, or open())."""
    seen: list[str] = []
    target = path.resolve()
    real_path_open, real_open = Path.open, builtins.open

    def path_open(self: Path, *args: Any, **kwargs: Any) -> Any:
        if self.resolve() == target:
            seen.append("open")
        return real_path_open(self, *args, **kwargs)

    def open_(file: Any, *args: Any, **kwargs: Any) -> Any:
        if isinstance(file, str | Path) and Path(file).resolve() == target:
            seen.append("open")
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(Path, "open", path_open)
    monkeypatch.setattr(builtins, "open", open_)
    return seen


def test_calibrate_reads_the_csv_once_and_uses_both_of_its_header_lines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    csv = tmp_path / "bench.csv"
    csv.write_text(CSV)
    reads = _counting_opens(monkeypatch, csv)
    said: list[str] = []
    result = calibrate_csv(csv, CalibrationOptions(method="paper", n_jobs=1), Reporter(say=said.append))
    assert reads == ["open"]
    assert result.model.manipulator is not None
    assert len(result.model.manipulator.actuators[0].joints) >= 1
    assert any("fingertip stop" in line for line in said)  # the # bench: line was read from the text


def test_diagnose_reads_the_csv_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without a model, diagnose reads the rows and both header lines to calibrate the finger
    first: all from one read (the fit itself is cut short here, only the reads matter)."""
    csv = tmp_path / "bench.csv"
    csv.write_text(CSV)
    reads = _counting_opens(monkeypatch, csv)

    def stop(*args: object, **kwargs: object) -> None:
        raise RuntimeError("the fit would start here")

    monkeypatch.setattr("somo_sweep.diagnosis.workflow.solve_fit", stop)
    said: list[str] = []
    with pytest.raises(RuntimeError, match="the fit would start here"):
        diagnose_csv(csv, DiagnosisOptions(n_jobs=1), Reporter(say=said.append))
    assert reads == ["open"]
    assert any("fingertip stop" in line for line in said)


def test_headers_and_rows_come_from_one_text(tmp_path: Path) -> None:
    csv = tmp_path / "bench.csv"
    csv.write_text(CSV)
    file = read_bench_file(csv)
    csv.unlink()  # nothing below reads the disk again
    assert finger_header(file) == {"length_mm": 100, "segments": 10, "mass_g": 0}
    assert bench_header(file).stop == "fingertip" and bench_header(file).line == 2
    rows = parse_measurements(file)
    assert list(rows["line"]) == [4, 5, 6, 7]


def test_the_size_limit_is_checked_before_the_file_is_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    csv = tmp_path / "big.csv"
    csv.write_text(CSV)
    monkeypatch.setattr(bench_file_module, "MAX_FILE_BYTES", 100)
    reads = _counting_opens(monkeypatch, csv)
    with pytest.raises(MeasurementError, match="allowed: at most"):
        read_bench_file(csv)
    assert reads == []
