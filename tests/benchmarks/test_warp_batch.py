"""The GPU benchmark (``make bench-warp``): what it refuses before any work, and a short run on
Warp's CPU device that fills its throughput and its label agreement with C MuJoCo."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from benchmarks import warp_batch

AUDIT_JOBS = warp_batch.audit_jobs


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--device", "gpu"], "--device must be cpu, cuda or cuda:N, got 'gpu'"),
        (["--device", "cuda:x"], "--device must be cpu, cuda or cuda:N, got 'cuda:x'"),
        (["--time-limit-s", "0"], "--time-limit-s must be > 0, got 0.0"),
        (["--time-limit-s", "nan"], "--time-limit-s must be > 0, got nan"),
        (["--batch-size", "0"], "--batch-size: must be >= 1, got 0"),
        (["--cells", "151"], "--cells: must be from 1 to 150, got 151"),
    ],
)
def test_a_bad_option_is_refused_in_one_line_before_anything_runs(
    argv: list[str], says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("mujoco_warp")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        warp_batch.main([*argv, "--out", str(out)])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and says in err and "Traceback" not in err
    assert not out.exists()


def test_a_gpu_the_machine_lacks_is_refused_naming_what_warp_sees() -> None:
    wp = pytest.importorskip("warp")
    count = wp.get_cuda_device_count()
    with pytest.raises(warp_batch.SomoError, match=f"--device cuda:{count}: Warp sees {count} CUDA device"):
        warp_batch.check_device(f"cuda:{count}")
    warp_batch.check_device("cpu")


def test_without_mujoco_warp_installed_it_says_how_to_get_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "mujoco_warp", None)
    monkeypatch.setattr("importlib.util.find_spec", lambda name, *a: None if name == "mujoco_warp" else 1)
    with pytest.raises(SystemExit) as stop:
        warp_batch.main(["--device", "cpu", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "somo-sweep[warp]" in err and "missing: mujoco_warp" in err
    assert not (tmp_path / "out").exists()


def _short_audit(limit: int | None = None) -> list[warp_batch.Job]:
    """The audit's first cells with every phase cut to 40 ms (the labels are beside the point)."""
    short = {"approach_s": 0.04, "ramp_s": 0.04, "lift_s": 0.04, "hold_s": 0.04}
    return [dataclasses.replace(job, params=job.params.model_copy(update=short)) for job in AUDIT_JOBS(limit)]


def test_a_short_cpu_run_reports_throughput_and_each_cells_labels_against_c_mujoco(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("mujoco_warp")
    monkeypatch.setattr(warp_batch, "audit_jobs", _short_audit)
    warp_batch.main(["--device", "cpu", "--cells", "3", "--batch-size", "2", "--out", str(tmp_path)])
    summary = json.loads((tmp_path / "warp_batch.json").read_text())
    cells = warp_batch.pd.read_csv(tmp_path / "warp_batch_cells.csv")
    assert summary["cells_on_warp"] == summary["cells_planned"] == 3 and summary["batches"] == 2
    assert summary["world_steps_per_s"] > 0 and summary["trials_per_s"] > 0
    assert summary["world_steps_per_s"] >= summary["trial_steps_per_s"]
    agree = cells["warp_grasp"] == cells["c_grasp"]
    assert summary["labels_equal"]["grasp"] == int(agree.sum())
    assert summary["cells_disagreeing"] == cells.loc[~cells["agree"], "cell"].tolist()
    assert cells["cell"].tolist() == [0, 1, 2] and cells["c_status"].eq("ok").all()
    assert cells["audit_robust_grasp"].tolist() == [False, True, True]  # the stored engine audit's
    assert cells["object_width_m"].tolist() == [j.params.object_width_m for j in _short_audit(3)]


def test_a_time_limit_spent_compiling_launches_no_batch_and_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    pytest.importorskip("mujoco_warp")
    monkeypatch.setattr(warp_batch, "audit_jobs", _short_audit)
    out = warp_batch.build("cpu", batch_size=2, time_limit_s=1e-6, cells=2)
    summary = out.json["warp_batch.json"]
    assert summary["cells_on_warp"] == 0 and summary["batches"] == 0 and summary["labels_equal"]["grasp"] == 0
    assert out.lines[0].startswith("0 of 2 audit cells on MuJoCo Warp")
