"""Active sampling in real runs: ``selftest_sleep`` over a disc, whose labels are known in closed form.

The ``region`` label is ``inside`` a disc of radius 5.5 in (x, u), ``sign`` the sign of x; a
robustness replica moves x by up to ``jitter``, so the cells near x = 0 and near the circle are
not robust. The tests check what a user sees: the map agrees with the exhaustive one, the cells
never simulated are inferred with a confidence and never robust, a run is the same whatever the
worker count, and a killed run resumes without simulating anything twice.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from test_sweep import make_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.run.replica_state import fold_cells, replica_state
from somo_sweep.sweep.run.runner import RunEvents, RunOptions, RunSummary, run_sweep
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.answers import Question, ask
from somo_sweep.sweep.views.results import open_results

DISC = """\
name: disc
task: selftest_sleep
model: models/ihm_finger.yaml
params: {{region_radius_m: 5.5, jitter: 0.3}}
sweep:
  task.x: {{start: -8, stop: 8, step: 1}}
  task.u: {{start: -8, stop: 8, step: 1}}
simulation: {{time_step_s: 1.0e-3}}
sampling: active
active: {{batch: 10, initial: 20, target_agreement: 0.97{active}}}
robustness: {{replicas: 2{robustness}}}
"""


def disc_study(folder: Path, active: str = "", robustness: str = "") -> Path:
    return make_study(folder, DISC.format(active=active, robustness=robustness))


def run(path: Path, out: Path, jobs: int = 1) -> None:
    run_sweep(load_study(path, out), RunOptions(n_jobs=jobs))


def exhaustive(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    return np.where(x**2 + u**2 < 5.5**2, "inside", "outside")


def simulated(folder: Path) -> pd.DataFrame:
    """Every stored run (trials and replicas): job id, trial, replica, labels."""
    trials = read_results(folder)
    keep = trials[~trials["inferred"]]
    return keep[["job_id", "trial", "replica", "label_region", "label_sign"]].sort_values("job_id")


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RunSummary]:
    """The disc study run once, uninterrupted, on one worker: (its results folder, its summary)."""
    folder = tmp_path_factory.mktemp("whole")
    summary = run_sweep(load_study(disc_study(folder), folder / "out"), RunOptions(n_jobs=1))
    return folder / "out", summary


def test_an_active_run_simulates_a_part_and_infers_the_rest_with_its_confidence(
    whole: tuple[Path, RunSummary],
) -> None:
    folder, summary = whole
    assert summary.sampling == "active" and summary.active is not None
    trials = read_results(folder)
    state = replica_state(trials)
    cells = fold_cells(trials, state=state)
    inferred = cells[cells["inferred"]]
    assert state.settled and summary.inferred == len(inferred) > 0.4 * len(cells)
    assert summary.run < 0.6 * len(cells)
    assert (
        inferred["confidence"].between(0.0, 1.0).all()
        and cells.loc[~cells["inferred"], "confidence"].isna().all()
    )
    assert inferred["robust"].isna().all()  # a cell never simulated is never called robust
    assert (inferred["message"].str.startswith("inferred, not simulated")).all()
    label = cells["label_region_majority"].astype(str).to_numpy()
    assert (label == exhaustive(cells["task_x"].to_numpy(), cells["task_u"].to_numpy())).mean() >= 0.95
    shown = CliRunner().invoke(app, ["show", str(folder)], terminal_width=300)
    assert (
        f"{len(cells) - len(inferred)} simulated and {len(inferred)} inferred (active sampling)"
        in shown.output
    )
    runs = read_manifest(folder)["runs"][-1]
    assert runs["replica_plan"]["kind"] == "active" and runs["active"]["estimated_agreement"] >= 0.97


def test_replicas_stop_at_the_first_disagreement_and_such_a_cell_awaits_none(tmp_path: Path) -> None:
    path = disc_study(tmp_path, active=", labels: [sign]")
    run(path, tmp_path / "out")
    trials = read_results(tmp_path / "out")
    state = replica_state(trials)
    cells = fold_cells(trials, state=state)
    broken = cells[cells["robust"].eq(False).fillna(False).astype(bool)]
    assert len(broken) and (broken["replicas"] < 2).any()  # stopped after a replica that disagreed
    assert set(broken.loc[broken["replicas"] < 2, "trial"]) <= state.stopped
    assert (cells["replicas_awaited"] == 0).all()
    answer = ask(
        open_results(tmp_path / "out"), Question("task_x", "label_sign", "positive", every=("task_u",))
    )
    assert bool(answer.table["complete"].iloc[0]) and answer.note is None


def test_the_same_runs_and_labels_with_one_worker_and_with_two(
    tmp_path: Path, whole: tuple[Path, RunSummary]
) -> None:
    run(disc_study(tmp_path), tmp_path / "two", jobs=2)
    one, two = simulated(whole[0]), simulated(tmp_path / "two")
    assert one.to_numpy().tolist() == two.to_numpy().tolist()
    a, b = (
        pd.read_parquet(f / "inferred.parquet").sort_values("trial") for f in (whole[0], tmp_path / "two")
    )
    assert a[["trial", "label_region", "label_sign", "confidence"]].equals(
        b[["trial", "label_region", "label_sign", "confidence"]]
    )


KILL = (
    "import os, signal, sys\n"
    "from somo_sweep.sweep.run.runner import RunEvents, RunOptions, RunSummary, run_sweep\n"
    "from somo_sweep.sweep.study import load_study\n"
    "seen = []\n"
    "def stop(outcome):\n"
    "    seen.append(outcome)\n"
    "    if len(seen) == int(sys.argv[3]):\n"
    "        os.kill(os.getpid(), signal.SIGKILL)\n"
    "run_sweep(load_study(sys.argv[1], sys.argv[2]), RunOptions(n_jobs=1, chunk_rows=1),"
    " RunEvents(outcome=stop))\n"
)


@pytest.mark.parametrize("after", [25, 57], ids=["in batch 1", "among replicas"])
def test_a_killed_run_resumes_its_batches_and_simulates_nothing_twice(
    tmp_path: Path, after: int, whole: tuple[Path, RunSummary]
) -> None:
    path = disc_study(tmp_path)
    done = subprocess.run(
        [sys.executable, "-c", KILL, str(path), str(tmp_path / "out"), str(after)], check=False
    )
    assert done.returncode == -9
    stored = simulated(tmp_path / "out")
    assert len(stored) == after - 1 or len(stored) == after  # the trial in flight may be lost
    trials = read_results(tmp_path / "out")
    assert not replica_state(trials).settled and not trials["inferred"].any()
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    resumed = simulated(tmp_path / "out")
    # Every run stored before (and the one its journal kept, if any) is not run again.
    assert len(resumed) - (summary.run + summary.replicas_run) in (len(stored), len(stored) + 1)
    assert resumed["job_id"].is_unique
    assert resumed.to_numpy().tolist() == simulated(whole[0]).to_numpy().tolist()
    written = [
        job_id
        for part in (tmp_path / "out" / "trials").glob("*.parquet")
        for job_id in pq.read_table(part).column("job_id").to_pylist()
    ]
    assert len(written) == len(set(written))  # no run written twice


def test_an_interrupted_run_is_provisional_for_the_readers(tmp_path: Path) -> None:
    path = disc_study(tmp_path)
    seen: list[object] = []

    def stop(outcome: object) -> None:
        seen.append(outcome)
        if len(seen) == 40:
            raise KeyboardInterrupt

    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1), RunEvents(outcome=stop))
    answer = ask(
        open_results(tmp_path / "out"), Question("task_x", "label_region", "inside", every=("task_u",))
    )
    assert not answer.table["complete"].any()
    assert "trials are stored (the last run was interrupted)" in (answer.note or "")


@pytest.mark.parametrize(
    ("active", "robustness", "says"),
    [
        (", model: forest", "", "active.model"),
        (", target_agreement: 0", "", "active.target_agreement"),
        (", batch: 0", "", "active.batch"),
        (", labels: [colour]", "", "active.labels"),
        ("", ", audit_fraction: 0.2", "robustness.audit_fraction: sampling: active audits no cell"),
    ],
)
def test_bad_active_settings_get_one_line_naming_the_key(
    tmp_path: Path, active: str, robustness: str, says: str
) -> None:
    path = disc_study(tmp_path, active, robustness)
    with pytest.raises(DescriptionError, match=says.replace(".", r"\.")):
        load_study(path, tmp_path / "out")
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()


def test_dry_run_says_how_the_study_is_sampled(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["run", str(disc_study(tmp_path)), "--dry-run", "--no-estimate"])
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "active sampling of a 17 x 17 grid (289 trials)" in text
    assert "stops when the estimated agreement reaches 0.97" in text
    runs = "runs: 289 trial(s) at most (active sampling simulates fewer) + 0 to 578 robustness replica"
    assert runs in text


@pytest.mark.slow
def test_the_sampler_replayed_on_an_exhaustive_run_asks_for_what_the_real_run_ran(tmp_path: Path) -> None:
    """What the benchmark relies on (benchmarks/active_sampling.py): the sampler answered from a
    stored exhaustive run (every cell, every replica) asks for exactly the runs a real run runs."""
    from somo_sweep.sweep.run.active import Sampler
    from somo_sweep.sweep.run.active_plan import run_value, sampler_settings

    path = disc_study(tmp_path)
    run(path, tmp_path / "active")
    study = load_study(path, tmp_path / "all")
    exhaustive = replace(
        study, sampling="grid", robustness=study.robustness.model_copy(update={"where": "all"})
    )
    run_sweep(exhaustive, RunOptions(n_jobs=2))
    every = read_results(tmp_path / "all")
    names = ["region", "sign"]
    outcome = {
        (int(r["trial"]), int(r["replica"])): run_value(
            r["status"], {n: r[f"label_{n}"] for n in names}, names
        )
        for r in every.to_dict("records")
    }
    sampler = Sampler((17, 17, 1), sampler_settings(study))
    asked = {a for batch in sampler.batches(lambda c, n: outcome[(c, n)]) for a in batch}
    ran = simulated(tmp_path / "active")
    assert asked == {(int(t), int(r)) for t, r in zip(ran["trial"], ran["replica"], strict=True)}
