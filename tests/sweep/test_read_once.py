"""A results folder is read once, and a run's study made into jobs once.

A run that opens its folder reads the manifest and each journal once and decides from what it read
(quarantine, rebuild, recovery); ``show`` and ``plot`` open the folder once for every reader of it;
a run builds its study's trial plan (its job maker) once, for the step's sample trials and the job
table alike, and a dry run once for its first jobs and its estimate.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from test_sweep import selftest_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import ResultStore
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.study.loaded import Study


@pytest.fixture
def reads(monkeypatch: pytest.MonkeyPatch) -> Iterator[Counter[str]]:
    """How often each file of a results folder is opened for reading, by name (journals as ``journal``)."""
    seen: Counter[str] = Counter()
    read_text, open_file = Path.read_text, Path.open

    def counted_text(self: Path, *args: object, **kwargs: object) -> str:
        seen[self.name] += 1
        return read_text(self, *args, **kwargs)  # type: ignore[arg-type]

    def counted_open(self: Path, mode: str = "r", *args: object, **kwargs: object) -> object:
        if self.name.startswith(".journal-") and "r" in mode:
            seen["journal"] += 1
        return open_file(self, mode, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(Path, "read_text", counted_text)
    monkeypatch.setattr(Path, "open", counted_open)
    yield seen


def _finished(tmp_path: Path) -> tuple[Path, Path]:
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    run_sweep(load_study(path, out), RunOptions(n_jobs=1, chunk_rows=4))
    return path, out


def test_a_run_reads_its_folder_s_manifest_once_while_opening_it(tmp_path: Path, reads: Counter[str]) -> None:
    """Setting the folder in order read the manifest twice: to judge the parts, then to continue it."""
    path, out = _finished(tmp_path)
    study = load_study(path, out)
    table = build_jobs(study)
    reads.clear()
    store = ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    store.close()
    assert reads["manifest.json"] == 1


def test_a_killed_run_s_journal_is_read_once_by_the_run_that_recovers_it(
    tmp_path: Path, reads: Counter[str]
) -> None:
    """The journal was read twice: for the study hashes the folder holds, then for its rows."""
    path, out = _finished(tmp_path)
    part = sorted((out / "trials").glob("part-*.parquet"))[-1]
    rows = pq.read_table(part).to_pylist()
    part.unlink()  # its trials were finished, then the run was killed before storing them
    journal = out / "trials" / ".journal-20240101T000000-deadbeef.jsonl"
    journal.write_text("".join(json.dumps(r, default=str) + "\n" for r in rows))
    study = load_study(path, out)
    table = build_jobs(study)
    reads.clear()
    store = ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    store.close()
    assert reads["journal"] == 1
    assert any(f"recovered {len(rows)} finished trial(s)" in note for note in store.notes)
    assert not journal.exists()


@pytest.mark.parametrize(("command", "times"), [("show", 1), ("plot", 2)])
def test_show_and_plot_open_the_folder_once(
    tmp_path: Path, reads: Counter[str], command: str, times: int
) -> None:
    """``show`` read the manifest twice (the trials, then the manifest); ``plot`` three times (the
    trials, the manifest, then once more under the lock to list the plots: that one stays)."""
    _, out = _finished(tmp_path)
    reads.clear()
    result = CliRunner().invoke(app, [command, str(out)])
    assert result.exit_code == 0, result.output
    assert reads["manifest.json"] == times


@pytest.fixture
def plans(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Each trial plan a study makes (what its job maker is built from)."""
    made: list[int] = []
    real = Study.trial_plan

    def counted(self: Study) -> object:
        made.append(1)
        return real(self)

    monkeypatch.setattr(Study, "trial_plan", counted)
    return made


def test_a_run_choosing_its_step_makes_its_jobs_from_one_plan(tmp_path: Path, plans: list[int]) -> None:
    """The step's sample and the job table each made the study's plan again (one per candidate step)."""
    study = load_study(selftest_study(tmp_path, auto=True), tmp_path / "out")
    summary = run_sweep(study, RunOptions(n_jobs=1))
    assert summary.run == 8
    assert len(plans) == 1


def test_a_dry_run_makes_its_jobs_and_its_estimate_from_one_plan(tmp_path: Path, plans: list[int]) -> None:
    """The first rows and the trial timed for the estimate each made the study's plan."""
    path = selftest_study(tmp_path, auto=True)
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out"), "--dry-run"])
    assert result.exit_code == 0, result.output
    assert "automatic numerics" in result.output and "time: about" in result.output
    assert len(plans) == 1
