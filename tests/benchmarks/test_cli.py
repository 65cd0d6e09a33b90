"""Every benchmark runs as ``python -m benchmarks.NAME``: its help, and options refused before any work."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Every benchmark with a command line (``python -m benchmarks.NAME``).
COMMANDS = (
    "speed",
    "statics",
    "scaling",
    "scale",
    "engines",
    "mujoco_step",
    "robust_cost",
    "numerics",
    "auto_numerics",
    "zero_kpa",
    "link_count",
    "room_returns",
    "warp_batch",
    "original_fig6.__main__",
    "original_fig6.run_original_cells",
    "original_fig6.compare_cells",
    "original_fig6.merge_cells",
    "original_fig6.merge_steps",
)


@pytest.mark.parametrize("name", COMMANDS)
def test_every_benchmark_has_a_help_that_names_how_to_run_it(
    name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    module = importlib.import_module(f"benchmarks.{name}")
    with pytest.raises(SystemExit) as stop:
        module.main(["--help"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: python -m benchmarks.{name.removesuffix('.__main__')}")


def test_a_benchmark_runs_from_the_repository_root_as_a_module() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks.statics", "--help"], cwd=ROOT, capture_output=True, text=True
    )
    assert out.returncode == 0 and "solved vs dynamic relaxation" in out.stdout


@pytest.mark.parametrize("name", ["numerics", "speed"])
@pytest.mark.parametrize("repeats", ["0", "-3", "101", "three"])
def test_timing_repeats_outside_1_to_100_are_refused(
    name: str, repeats: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """0 was 'min() arg is an empty sequence'."""
    module = importlib.import_module(f"benchmarks.{name}")
    with pytest.raises(SystemExit) as stop:
        module.main(["--repeats", repeats])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "--repeats" in err and "Traceback" not in err


@pytest.mark.parametrize("jobs", ["0", "100000"])
def test_a_number_of_workers_the_machine_cannot_hold_is_refused(
    jobs: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from benchmarks import robust_cost

    with pytest.raises(SystemExit) as stop:
        robust_cost.main(["--jobs", jobs])
    assert stop.value.code == 2 and "--jobs/-j: must be from 1 to" in capsys.readouterr().err


def test_the_engine_benchmark_without_mujoco_installed_says_so_before_running_anything(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from benchmarks import engines

    monkeypatch.setitem(sys.modules, "mujoco", None)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        engines.main(["--out", str(out)])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "engine mujoco needs MuJoCo" in err and "Traceback" not in err
    assert not out.exists()
