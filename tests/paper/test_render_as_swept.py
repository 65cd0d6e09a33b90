"""``somo-sweep render`` reruns a trial exactly as its sweep ran it (a blow-up rerun at half the
step, as :func:`~somo_sweep.sweep.run.trial.run_job` does), and a render that writes no image
exits non-zero with one line naming the trial, its status and why."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import UnstableSimulation
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.trial import run_job
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.pinch_grasp import task as grasp_task
from somo_sweep.tasks.registry import TaskResult

STEP_S = 5.0e-4


def _study(folder: Path, params: str, step_s: float = STEP_S) -> Path:
    shutil.copytree(MODELS, folder / "models")
    path = folder / "one.yaml"
    path.write_text(
        "name: one\ntask: pinch_grasp\nmodel: models/pinch_gripper.yaml\n"
        f"params: {{{params}}}\nsweep:\n  task.distal_segment_ratio: [0.1]\n"
        f"simulation: {{time_step_s: {step_s}, scale: 20, solver_iterations: 50, "
        "body_per_manipulator: true, friction_rows_every: 1}\n"
    )
    return path


class _World:
    """What a snapshot reads of a world: its image."""

    def render(self, camera: Any) -> np.ndarray:
        return np.zeros((camera.height_px, camera.width_px, 3), dtype=np.uint8)


def _blows_up_at(blow_up_s: dict[float, float]) -> Any:
    """A stand-in for the grasp trial: at each step (s), observed until it blows up at the time
    given (or finishes ``ok`` as a power grasp when the step has none); records the steps run."""
    runs: list[float] = []

    def run(
        model: Any, params: Any, settings: Any, seed: int, *, observe: Any, observe_at_s: Any
    ) -> TaskResult:
        dt = settings.time_step_s
        runs.append(dt)
        end = blow_up_s.get(dt)
        for t in observe_at_s:
            if end is not None and t >= end:
                return TaskResult(status="unstable", message=str(UnstableSimulation("speed_cap", end)))
            observe(_World(), round(t / dt) * dt)
        return TaskResult(status="ok", labels={"grasp": "power"})

    run.runs = runs  # type: ignore[attr-defined]
    return run


def _render(path: Path, out: Path, at_s: str) -> Any:
    return CliRunner().invoke(app, ["render", str(path), "--trial", "0", "--at-s", at_s, "--out", str(out)])


def test_run_job_retries_a_blow_up_of_the_function_it_is_given_at_half_the_step(tmp_path: Path) -> None:
    steps: list[float] = []

    def run(model: Any, params: Any, settings: Any, seed: int) -> TaskResult:
        steps.append(settings.time_step_s)
        if settings.time_step_s == STEP_S:
            return TaskResult(status="unstable", message="simulation unstable at t=0.9 s (speed_cap)")
        return TaskResult(status="ok", labels={"grasp": "power"})

    (job,) = build_jobs(load_study(_study(tmp_path, "object_width_m: 0.02"))).jobs
    out = run_job(job, run)
    assert steps == [STEP_S, STEP_S / 2]
    assert (out.status, dict(out.labels), out.retried_half_step, out.time_step_used_s) == (
        "ok",
        {"grasp": "power"},
        True,
        STEP_S / 2,
    )


def test_a_trial_the_sweep_retried_at_half_the_step_renders_as_the_retry(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The sweep stores the half-step rerun of a blow-up; render shows that run, not the blow-up
    (it printed 'unstable; step 0.5 ms', wrote nothing and exited 0)."""
    fake = _blows_up_at({STEP_S: 0.9})
    monkeypatch.setattr(grasp_task, "run_pinch_grasp", fake)
    out = tmp_path / "r"
    res = _render(_study(tmp_path, "object_width_m: 0.02, centering_position_m: 0.16"), out, "1,2")
    assert res.exit_code == 0, res.output
    assert fake.runs == [STEP_S, STEP_S / 2]
    retried = "(the run at 0.5 ms blew up; rerun at half the step, as the sweep does)"
    assert res.output.startswith(f"trial 0: power; step 0.25 ms {retried}\n")
    assert sorted(p.name for p in out.iterdir()) == [
        "one_dsr0.10_w20mm_c160mm_t1.00s.png",
        "one_dsr0.10_w20mm_c160mm_t2.00s.png",
    ]


def test_a_trial_that_blows_up_before_any_snapshot_exits_1_and_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(grasp_task, "run_pinch_grasp", _blows_up_at({STEP_S: 0.9, STEP_S / 2: 0.95}))
    out = tmp_path / "r"
    res = _render(_study(tmp_path, "object_width_m: 0.02"), out, "1,4")
    assert res.exit_code == 1, res.output
    (line,) = res.output.splitlines()
    assert line.startswith(
        "error: trial 0: unstable (first run at 0.0005 s blew up (simulation unstable at t=0.9000"
    )
    assert "retried at 0.00025 s: simulation unstable at t=0.9500 s (speed_cap)" in line
    assert line.endswith(
        "; no snapshot at 1, 4 s: the run ended before; step 0.25 ms (the run at 0.5 ms blew up; "
        "rerun at half the step, as the sweep does); no image written"
    )
    assert not out.exists()


def test_a_blow_up_after_some_snapshots_writes_them_and_names_the_missed_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(grasp_task, "run_pinch_grasp", _blows_up_at({STEP_S: 0.9, STEP_S / 2: 0.95}))
    out = tmp_path / "r"
    res = _render(_study(tmp_path, "object_width_m: 0.02"), out, "0.5,1")
    assert res.exit_code == 0, res.output
    assert "trial 0: unstable (first run at 0.0005 s blew up" in res.output
    assert "; no snapshot at 1 s: the run ended before; step 0.25 ms" in res.output
    assert sorted(p.name for p in out.iterdir()) == ["one_dsr0.10_w20mm_c100mm_t0.50s.png"]


def test_snapshots_only_after_an_early_end_exit_2_naming_the_end(tmp_path: Path) -> None:
    """DSR 0.1, a 10-mm box at c = 175 mm: no contact by the end of the squeeze, the trial ends at
    2.08 s (the real simulation, 0.5 ms)."""
    out = tmp_path / "r"
    res = _render(_study(tmp_path, "object_width_m: 0.01, centering_position_m: 0.175"), out, "3.5")
    assert res.exit_code == 2, res.output
    (line,) = res.output.splitlines()
    assert line.startswith("error: trial 0: no_grasp (ended early at 2.")
    assert line.endswith(": no_contact_after_squeeze; no snapshot after it); step 0.5 ms; no image written")
    assert not out.exists()


@pytest.mark.slow
def test_the_demo_trial_the_sweep_retried_renders_as_stored(tmp_path: Path) -> None:
    """The demo's trial 3 (DSR 0.1, 20-mm box, c = 160 mm) blows up at 0.5 ms and is stored as the
    0.25-ms rerun, a power grasp; render must agree (about 15 s of CPU)."""
    path = _study(tmp_path, "object_width_m: 0.02, centering_position_m: 0.16")
    stored = tmp_path / "results"
    ran = CliRunner().invoke(app, ["run", str(path), "--out", str(stored), "-j", "1", "--no-plots"])
    assert ran.exit_code == 0, ran.output
    from somo_sweep.sweep.views.results import open_results

    row = open_results(stored).trials.iloc[0]
    assert (row["status"], bool(row["retried_half_step"]), row["time_step_used_s"]) == (
        "ok",
        True,
        STEP_S / 2,
    )
    res = _render(path, tmp_path / "r", "1,4")
    assert res.exit_code == 0, res.output
    assert res.output.startswith(f"trial 0: {row['label_grasp']}; step 0.25 ms (the run at 0.5 ms blew up")
    assert not pd.isna(row["label_grasp"])


def test_snapshots_of_a_cell_without_a_dsr_are_named_null() -> None:
    from types import SimpleNamespace

    from somo_sweep.paper.grasp_render import _named

    params = SimpleNamespace(distal_segment_ratio=None, object_width_m=0.04, centering_position_m=0.1)
    names = set(_named("mine", params, {1.0: b"png"}).images)
    assert names == {"mine_dsrnull_w40mm_c100mm_t1.00s.png"}


def test_a_render_reads_the_chosen_step_from_the_folder_the_sweep_ran_into(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from somo_sweep.paper import grasp_render
    from somo_sweep.sweep.run import convergence

    path = tmp_path / "automatic.yaml"  # no simulation: block, so its step is chosen by its sweep
    shutil.copytree(MODELS, tmp_path / "models")
    path.write_text(
        "name: automatic\ntask: pinch_grasp\nmodel: models/pinch_gripper.yaml\n"
        "sweep:\n  task.distal_segment_ratio: [0.1]\n"
    )
    read: list[Path] = []
    monkeypatch.setattr(convergence, "read_manifest", lambda folder: read.append(Path(folder)) or {})
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    study = grasp_render._study_to_render(path, None, None, elsewhere)
    assert read == [elsewhere] and study.output == elsewhere
    read.clear()
    grasp_render._study_to_render(path, None, None)
    assert read and read[0] != elsewhere  # the study's own output folder


def test_a_render_refuses_a_results_folder_that_is_not_there(tmp_path: Path) -> None:
    path = _study(tmp_path, "duration_s: 1.0")
    missing = tmp_path / "not_here"
    result = CliRunner().invoke(
        app, ["render", str(path), "--trial", "0", "--results", str(missing), "--out", str(tmp_path / "r")]
    )
    assert result.exit_code == 2
    assert f"--results {missing}: no such results folder" in result.output
    assert not (tmp_path / "r").exists()
