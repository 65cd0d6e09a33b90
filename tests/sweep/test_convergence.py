"""Automatic numerics by label convergence, on selftest tasks whose labels converge at a known step.

``selftest_sleep`` labels ``step`` ``coarse`` above ``coarse_above_s`` and ``fine`` below, and
``selftest_unstable`` blows up above ``unstable_above_step_s``: the right choice is known in
closed form. The bundled in-hand finger's ladder is 4, 2, 1.5 ms (its lowest modes allow the
largest validated step; it needs no shaping below 1.5 ms).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import signals_as_in_a_shell
from test_sweep import make_study
from test_sweep_processes import _descendants
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.numerics import numerics_for_step, step_ladder
from somo_sweep.sweep.jobs.job import JobMaker
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.convergence import choose_step, outcomes_of, stored_choice
from somo_sweep.sweep.run.execution import execute
from somo_sweep.sweep.run.options import RunOptions
from somo_sweep.sweep.store.result_store import read_manifest
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.study.loaded import Study


def _made(study: Study) -> tuple[Study, JobMaker]:
    """A study and its job maker, as a run hands them to the step's choice."""
    return study, JobMaker(study.trial_plan())


def _coded(study: Study) -> tuple[Study, str]:
    """A study and its code version, as a run compares a stored choice with."""
    return study, JobMaker(study.trial_plan()).code


LADDER = [4e-3, 2e-3, 1.5e-3]


def study_file(folder: Path, params: str, task: str = "selftest_sleep") -> Path:
    body = (
        f"name: conv\ntask: {task}\nmodel: models/ihm_finger.yaml\nparams: {{sleep_s: 0.0, {params}}}\n"
        "sweep:\n  task.x: [-3, -2, -1, 1, 2, 3]\n"
    )
    return make_study(folder, body)


def run_here(jobs: list) -> object:  # type: ignore[type-arg]
    return outcomes_of(execute(jobs, RunOptions(n_jobs=1)))


def test_the_ladder_starts_at_the_modal_guess_and_ends_where_no_shaping_is_needed() -> None:
    finger = load_model(bundled_path("models", "ihm_finger.yaml"))
    steps, why = step_ladder(finger)
    assert steps == LADDER and why == "the largest validated step"
    shaping = [max(numerics_for_step(finger, h).added_inertia_kg_m2.values()) for h in steps]
    assert shaping[0] > shaping[1] > 0 and shaping[-1] == 0.0


def test_the_largest_step_whose_labels_hold_at_half_of_it_is_chosen(tmp_path: Path) -> None:
    study = load_study(study_file(tmp_path, "coarse_above_s: 0.0025"), tmp_path / "out")
    choice = choose_step(*_made(study), run_here)  # type: ignore[arg-type]
    assert choice.step_s == 2e-3 and choice.guess_s == 4e-3
    first, second = choice.rungs
    assert not first.passed and first.robust == 6 and first.agree == 0 and len(first.differing) == 6
    assert second.passed and second.agree == 6
    assert "4 ms: not converged: 0 of 6 robust sample cells (of 6) agree with 2 ms" in choice.describe()[1]


def test_a_step_that_blows_up_is_not_chosen(tmp_path: Path) -> None:
    path = study_file(tmp_path, "unstable_x: [2], unstable_above_step_s: 0.003", "selftest_unstable")
    choice = choose_step(*_made(load_study(path, tmp_path / "out")), run_here)  # type: ignore[arg-type]
    assert [r.passed for r in choice.rungs] == [False, True] and choice.rungs[0].not_ok == 1
    assert choice.step_s == 2e-3


def test_cells_a_perturbation_flips_are_not_counted(tmp_path: Path) -> None:
    study = load_study(study_file(tmp_path, "jitter: 1"), tmp_path / "out")
    flippy = 0  # its perturbed run disagrees, and it changes with the step at every candidate

    def fake(jobs: list) -> object:  # type: ignore[type-arg]
        for job in jobs:
            step = job.settings.time_step_s
            if job.trial == flippy:
                label = "shaken" if job.replica else f"{step:g}"
            else:
                label = "coarse" if step > 2.5e-3 else "fine"
            yield job.job_id, "ok", {"grasp": label}

    choice = choose_step(*_made(study), fake)  # type: ignore[arg-type]
    assert [(r.robust, r.passed) for r in choice.rungs] == [(5, False), (5, True)]
    assert choice.step_s == 2e-3 and flippy not in choice.rungs[0].differing


def test_labels_that_never_converge_end_at_the_unshaped_step_and_say_so(tmp_path: Path) -> None:
    study = load_study(study_file(tmp_path, "label_the_step: true"), tmp_path / "out")
    choice = choose_step(*_made(study), run_here)  # type: ignore[arg-type]
    assert choice.step_s == 1.5e-3 and not any(r.passed for r in choice.rungs)
    assert choice.reason.startswith("no candidate converged")


def test_the_jobs_run_the_chosen_step_with_the_shaping_it_needs(tmp_path: Path) -> None:
    from dataclasses import replace

    study = load_study(study_file(tmp_path, "coarse_above_s: 0.0025"), tmp_path / "out")
    jobs = build_jobs(replace(study, auto_step_s=2e-3)).jobs
    assert {j.settings.time_step_s for j in jobs} == {2e-3}
    assert (
        jobs[0].numerics is not None and jobs[0].numerics.reason == "label convergence against half the step"
    )


def test_run_chooses_the_step_records_it_and_a_resume_reuses_it(tmp_path: Path) -> None:
    path = study_file(tmp_path, "coarse_above_s: 0.0025")
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1", "--no-plots"])
    assert res.exit_code == 0, res.output
    assert "chosen: 2 ms" in res.output and "trying 4 ms: 18 sample run(s)" in res.output
    record = read_manifest(out)["study"]["simulation"]["convergence"]
    assert record["step_s"] == 2e-3 and [r["passed"] for r in record["rungs"]] == [False, True]
    assert stored_choice(read_manifest(out), *_coded(load_study(path, out))) is not None
    again = CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1", "--no-plots"])
    assert again.exit_code == 0, again.output
    assert "automatic step 2 ms (chosen earlier" in again.output and "trying" not in again.output
    assert "0 trial(s) run" in again.output
    assert json.loads((out / "manifest.json").read_text())["study"]["simulation"]["convergence"] == record


@pytest.mark.parametrize("damage", ["rungs", "code_version", "sample"])
def test_a_stored_choice_of_other_code_or_damaged_is_not_reused(tmp_path: Path, damage: str) -> None:
    path = study_file(tmp_path, "coarse_above_s: 0.0025")
    out = tmp_path / "out"
    assert (
        CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1", "--no-plots"]).exit_code == 0
    )
    manifest = read_manifest(out)
    manifest["study"]["simulation"]["convergence"][damage] = "x" if damage != "sample" else [0]
    assert stored_choice(manifest, *_coded(load_study(path, out))) is None


def test_a_task_without_labels_takes_the_modal_step_after_one_sample_run(tmp_path: Path) -> None:
    body = (
        "name: b\ntask: bench\nmodel: models/ihm_finger.yaml\nparams: {test: free_bending}\n"
        "sweep:\n  task.pressure_kpa: [0, 50, 100]\n"
    )
    study = load_study(make_study(tmp_path, body), tmp_path / "out")
    runs: list[int] = []

    def counted(jobs: list) -> object:  # type: ignore[type-arg]
        runs.append(len(jobs))
        return run_here(jobs)

    choice = choose_step(*_made(study), counted)  # type: ignore[arg-type]
    assert runs == [3] and choice.rungs == [] and choice.step_s == 1.5e-3
    assert choice.reason.startswith("the task gives no labels to converge; the modal rule")


@pytest.mark.parametrize("signum", [2, 15], ids=["SIGINT", "SIGTERM"])
def test_a_signal_while_the_step_is_chosen_stops_cleanly(tmp_path: Path, signum: int) -> None:
    import os
    import subprocess
    import sys
    import time

    # 6 sample runs of 3 s: the signal lands while the step is chosen even on a loaded machine.
    body = "task: selftest_sleep\nmodel: models/ihm_finger.yaml\nparams: {sleep_s: 3.0}\n"
    body += "sweep: {task.x: [1, 2]}\n"
    path = make_study(tmp_path, body)
    proc = subprocess.Popen(
        [sys.executable, "-m", "somo_sweep", "run", str(path), "--out", str(tmp_path / "out"), "-j", "1"],
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=signals_as_in_a_shell,
    )
    assert proc.stderr is not None
    seen = ""
    while "trying" not in seen and proc.poll() is None:
        seen += proc.stderr.readline()
    # A sample trial is running (its forked child exists): the signal lands mid-choice.
    deadline = time.monotonic() + 60
    while not _descendants(proc.pid) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(0.5)
    assert proc.poll() is None, seen + proc.communicate()[1]
    os.kill(proc.pid, signum)
    rest = proc.communicate(timeout=60)[1]
    assert proc.returncode == 128 + signum, seen + rest
    assert "interrupted while choosing the time step" in rest and "Traceback" not in rest
    assert not (tmp_path / "out" / "trials").exists()


def test_check_of_a_study_prints_the_choice_and_why_and_writes_nothing(tmp_path: Path) -> None:
    path = study_file(tmp_path, "coarse_above_s: 0.0025")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    res = CliRunner().invoke(app, ["check", str(path), "-j", "1"], terminal_width=300)
    assert res.exit_code == 0, res.output
    assert "conv: task selftest_sleep, 6 trials" in res.output
    assert "trying 4 ms: 18 sample run(s)" in res.output
    assert "4 ms: not converged: 0 of 6 robust sample cells (of 6) agree with 2 ms" in res.output
    assert "chosen: 2 ms" in res.output
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before
    given = path.read_text() + "simulation: {time_step_s: 1.0e-3}\n"
    path.write_text(given)
    res = CliRunner().invoke(app, ["check", str(path)])
    assert res.exit_code == 0, res.output
    assert "simulation: time step 1 ms, from the study file" in res.output and "trying" not in res.output
