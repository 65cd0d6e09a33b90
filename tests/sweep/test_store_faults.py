"""Damaged results folders and faults while writing: nothing written is ever lost or claimed falsely."""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_sweep import make_study, results_only, selftest_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError, StorageError
from somo_sweep.sweep.jobs import job as job_module
from somo_sweep.sweep.jobs import table as jobs_module
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.runner import RunEvents, RunOptions, run_sweep
from somo_sweep.sweep.store import result_store as store_module
from somo_sweep.sweep.store.result_store import ResultStore, read_manifest, read_results
from somo_sweep.sweep.study import load_study


def _finished(tmp_path: Path, n: int = 8, chunk_rows: int = 4) -> tuple[Path, Path]:
    """A study of ``n`` selftest trials run into ``out`` in parts of ``chunk_rows``."""
    path = selftest_study(tmp_path, n=n)
    out = tmp_path / "out"
    run_sweep(load_study(path, out), RunOptions(n_jobs=1, chunk_rows=chunk_rows))
    return path, out


def _parts(out: Path) -> list[Path]:
    return sorted((out / "trials").glob("part-*.parquet"))


def _run(path: Path, out: Path, *extra: str) -> object:
    return CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1", "--no-plots", *extra])


def test_one_retyped_part_is_set_aside_not_the_parts_that_agree(tmp_path: Path) -> None:
    """The first part's ``task_x`` rewritten as text: the three parts after it were called
    damaged (their types differ from the one before them), and the run moved them away."""
    path, out = _finished(tmp_path, n=16)
    parts = _parts(out)
    assert len(parts) == 4
    table = pq.read_table(parts[0])
    i = table.column_names.index("task_x")
    as_text = pa.array([str(v) for v in table.column(i).to_pylist()])
    pq.write_table(table.set_column(i, "task_x", as_text), parts[0])
    skipped: list[tuple[Path, str]] = []
    df = read_results(out, lambda part, why: skipped.append((part, why)))
    assert [p for p, _ in skipped] == [parts[0]] and len(df) == 12
    assert "its 'task_x' column holds string, where the results hold double" in skipped[0][1]
    res = _run(path, out)
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (out / "trials" / "quarantine").iterdir()) == [f"_{parts[0].name}"]
    assert all(p.exists() for p in parts[1:]) and len(read_results(out)) == 16


def test_a_part_with_more_rows_than_the_study_has_trials_is_not_read(tmp_path: Path) -> None:
    """One row repeated three million times in a 1.3 MB file took 9.6 GB to show."""
    _, out = _finished(tmp_path)
    first = _parts(out)[0]
    table = pq.read_table(first)
    pq.write_table(pa.concat_tables([table] * 5), first)  # 20 rows in a study of 8 trials
    skipped: list[str] = []
    df = read_results(out, lambda part, why: skipped.append(why))
    assert skipped == ["20 rows, more than the study's 8 trials"] and len(df) == 4


def test_a_truncated_part_is_quarantined_and_its_trials_run_again(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    first = _parts(out)[0]
    first.write_bytes(first.read_bytes()[:100])
    res = _run(path, out)
    assert res.exit_code == 0, res.output
    moved = out / "trials" / "quarantine" / f"_{first.name}"
    assert f"note: damaged part file {first.name}" in res.output and f"moved to {moved}" in res.output
    assert "4 trial(s) run (ok 4); 4 already done" in res.output and moved.is_file()
    df = pd.read_parquet(out / "trials")  # one pandas call still reads the whole table
    assert len(df) == 8 and df["job_id"].is_unique


def test_show_skips_a_zero_byte_part_and_says_so(tmp_path: Path) -> None:
    _, out = _finished(tmp_path)
    empty = _parts(out)[1]
    empty.write_bytes(b"")
    res = CliRunner().invoke(app, ["show", str(out)])
    assert res.exit_code == 0, res.output
    assert f"warning: skipped damaged part file {empty} (empty file)" in res.output
    assert "4 of 8 trials stored" in res.output and empty.exists()  # show changes nothing


def test_recheck_skips_a_damaged_part(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    _parts(out)[0].write_bytes(b"PAR1")
    res = CliRunner().invoke(app, ["recheck", str(path), "--out", str(out), "-n", "2"])
    assert res.exit_code == 0, res.output
    assert "skipped damaged part file" in res.output and "2 identical, 0 different" in res.output


def test_a_deleted_manifest_is_rebuilt_from_the_parts(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    (out / "manifest.json").unlink()
    res = _run(path, out)
    assert res.exit_code == 0, res.output
    assert "note: manifest.json was missing: rebuilt from the part files (earlier runs unknown)" in res.output
    assert "0 trial(s) run (none); 8 already done" in res.output
    assert read_manifest(out)["n_trials"] == 8 and len(read_results(out)) == 8


def test_a_truncated_manifest_is_a_clear_error_for_show_and_is_rebuilt_by_run(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    manifest = out / "manifest.json"
    truncated = manifest.read_text()[:50]
    manifest.write_text(truncated)
    res = CliRunner().invoke(app, ["show", str(out)])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert f"error: {manifest} is damaged (" in res.output and "to rebuild it from the trials" in res.output
    res = _run(path, out)
    assert res.exit_code == 0, res.output
    assert "manifest.json was damaged (kept as manifest.json.damaged)" in res.output
    assert (out / "manifest.json.damaged").read_text() == truncated
    assert len(read_results(out)) == 8


def test_an_oversized_manifest_is_damaged_not_read(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from somo_sweep.sweep.store import folder as folder_module

    _, out = _finished(tmp_path)
    manifest = out / "manifest.json"
    size = manifest.stat().st_size
    monkeypatch.setattr(folder_module, "MAX_MANIFEST_BYTES", size - 1)
    res = CliRunner().invoke(app, ["show", str(out)])
    assert res.exit_code == 2
    assert f"is damaged ({size} bytes, more than any manifest ({size - 1}))" in res.output
    monkeypatch.setattr(folder_module, "MAX_MANIFEST_BYTES", size)
    assert read_manifest(out)["study_hash"]


def test_a_study_hash_in_a_damaged_manifest_is_cut_in_the_message(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    manifest = out / "manifest.json"
    data = json.loads(manifest.read_text())
    data["study_hash"] = "x" * 1_000_000
    manifest.write_text(json.dumps(data))
    res = _run(path, out)
    assert res.exit_code == 2 and "holds results of a different study (hash xxx" in res.output
    assert "… (1000000 characters), this one is" in res.output and len(res.output) < 2000


def test_a_lost_manifest_of_another_study_is_refused_then_replaced_with_overwrite(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    (out / "manifest.json").unlink()
    path.write_text(path.read_text().replace("stop: 8", "stop: 9"))
    res = _run(path, out)
    assert res.exit_code == 2 and "holds results of a different study" in res.output
    assert "changed: unknown (no readable manifest)" in res.output and len(_parts(out)) == 2
    res = _run(path, out, "--overwrite")
    assert res.exit_code == 0, res.output
    assert "9 trial(s) run (ok 9); 0 already done" in res.output and len(read_results(out)) == 9


def test_overwrite_deletes_only_the_files_the_tool_wrote(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    assert CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1"]).exit_code == 0
    files = read_manifest(out)["files"]
    assert {"study.yaml", "plots/summary.png", "plots/summary.svg", "plots/label_map_sign.png"} <= set(files)
    assert all(f in files for f in (p.relative_to(out).as_posix() for p in _parts(out)))
    (out / "plots" / "important.png").write_bytes(b"mine")
    (out / "trials" / "notes.txt").write_text("mine too")
    path.write_text(path.read_text().replace("stop: 8", "stop: 3"))
    res = _run(path, out, "--overwrite")
    assert res.exit_code == 0, res.output
    # study.yaml, one part, the summary's two files and the label map
    assert "--overwrite: deleted 5 file(s) of the previous study" in res.output
    assert (out / "plots" / "important.png").read_bytes() == b"mine"
    assert (out / "trials" / "notes.txt").read_text() == "mine too"
    assert len(read_results(out)) == 3 and not (out / "plots" / "summary.png").exists()


def test_overwrite_never_deletes_through_a_linked_folder(tmp_path: Path) -> None:
    """A manifest listing ``evil/victim.txt``, ``evil`` a link to a folder elsewhere, made
    --overwrite delete the file outside the results folder."""
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    assert CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1"]).exit_code == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "victim.txt").write_text("precious")
    (out / "evil").symlink_to(elsewhere)
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["files"].append("evil/victim.txt")
    (out / "manifest.json").write_text(json.dumps(manifest))
    path.write_text(path.read_text().replace("stop: 8", "stop: 3"))
    res = _run(path, out, "--overwrite")
    assert res.exit_code == 0, res.output
    assert (elsewhere / "victim.txt").read_text() == "precious"


def test_a_linked_quarantine_is_refused_before_anything_moves(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    assert CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1"]).exit_code == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (out / "trials" / "quarantine").symlink_to(elsewhere)
    _parts(out)[0].write_bytes(b"damaged")  # would be moved to the quarantine
    res = _run(path, out)
    assert res.exit_code == 2 and "trials/quarantine is a symbolic link" in res.output, res.output
    assert list(elsewhere.iterdir()) == []


def test_a_folder_that_is_not_a_results_folder_is_refused_even_with_overwrite(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    mine = tmp_path / "mine"
    (mine / "plots").mkdir(parents=True)
    (mine / "plots" / "important.png").write_bytes(b"mine")
    res = _run(path, mine, "--overwrite")
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert f"error: {mine} is not empty (plots) and is not a somo-sweep results folder" in res.output
    assert sorted(p.name for p in mine.iterdir()) == ["plots"]


def test_out_pointing_at_a_file_is_a_clear_error(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    target = tmp_path / "taken.txt"
    target.write_text("keep me")
    res = _run(path, target)
    assert res.exit_code == 2 and f"error: --out {target} is a file, not a folder" in res.output
    assert target.read_text() == "keep me"
    with pytest.raises(SomoError, match="is a file, not a folder"):
        run_sweep(load_study(path, target), RunOptions(n_jobs=1))


class _DiskFull:
    """``pq.write_table`` that succeeds ``allowed`` times, then fails as a full disk does."""

    def __init__(self, allowed: int, code: int = errno.ENOSPC):
        self.allowed, self.code = allowed, code
        self.real = pq.write_table

    def __call__(self, table: pa.Table, where: Path, **kwargs: object) -> None:
        if self.allowed <= 0:
            Path(where).write_bytes(b"PAR1 half a file")  # a partial write, as the disk filled up
            raise OSError(self.code, os.strerror(self.code))
        self.allowed -= 1
        self.real(table, where, **kwargs)


def test_a_full_disk_stops_the_run_keeping_every_written_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    monkeypatch.setattr(store_module.pq, "write_table", _DiskFull(allowed=2))
    with pytest.raises(StorageError) as info:
        run_sweep(load_study(path, out), RunOptions(n_jobs=1, chunk_rows=2))
    text = str(info.value)
    assert text.startswith(f"stopped: cannot write {out / 'trials' / 'part-'}")  # the part, not a tmp
    assert ".parquet: the disk is full (No space left on device)." in text
    assert "and 4 of them are in the table, intact" in text
    assert "To go on: free space on that disk, then run the same command again" in text
    monkeypatch.undo()
    kept = read_results(out)
    run = read_manifest(out)["runs"][-1]
    assert len(kept) == 4 and run["status"] == "failed" and run["trials_written"] == 4
    assert not list((out / "trials").glob(".*.tmp"))
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=1))
    assert any("recovered" in note for note in summary.notes)
    df = read_results(out)
    assert len(df) == 8 and df["job_id"].is_unique


def test_a_full_disk_exits_1_with_a_message_not_a_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = selftest_study(tmp_path)
    monkeypatch.setattr(store_module.pq, "write_table", _DiskFull(allowed=1))
    res = _run(path, tmp_path / "out", "--chunk-rows", "2")
    assert res.exit_code == 1 and "Traceback" not in res.output
    assert "error: stopped: cannot write " in res.output and "the disk is full" in res.output


def _killed_after(path: Path, out: Path, finished: int) -> int:
    """Run the study in a child process killed after ``finished`` trials (no cleanup of any
    kind, as SIGKILL); returns the child's pid."""
    pid = os.fork()
    if pid == 0:
        try:

            def die(outcome: object, seen: list[int] = [0]) -> None:  # noqa: B006
                seen[0] += 1
                if seen[0] == finished:
                    os._exit(9)

            run_sweep(load_study(path, out), RunOptions(n_jobs=1, chunk_rows=100), RunEvents(outcome=die))
        finally:
            os._exit(1)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 9
    return pid


def test_finished_trials_of_a_killed_run_are_recovered_from_its_journal(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    pid = _killed_after(path, out, 5)
    assert f"pid {pid} on " in (out / ".lock").read_text()  # the killed run's lock file is left
    assert (
        not _parts(out)
        and len((out / "trials").glob(".journal-*.jsonl").__next__().read_text().splitlines()) == 5
    )
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=1))  # the stale lock does not stop it
    assert (summary.skipped, summary.run) == (5, 3)
    assert "recovered 5 finished trial(s) of a killed run from its journal" in summary.notes
    killed = "was killed (or its disk could not be written even to record its end): marked aborted"
    assert any(f"(pid {pid} on " in note and killed in note for note in summary.notes)
    assert read_manifest(out)["runs"][0]["status"] == "aborted"
    assert not (out / ".lock").exists()


def test_show_tells_a_killed_run_and_the_trials_its_journal_holds(tmp_path: Path) -> None:
    """``show`` said "→ None: aborted, 0 trial(s)" of a killed run whose 5 trials were recovered."""
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    _killed_after(path, out, 5)
    before = CliRunner().invoke(app, ["show", str(out)], env={"COLUMNS": "300"})
    assert before.exit_code == 0, before.output
    assert "0 of 8 trials stored (and 5 finished in a killed run's journal, stored by the next run)" in (
        before.output
    )
    assert "→ killed (no end recorded): 5 finished trial(s) in its journal" in before.output
    assert "running" not in before.output
    run_sweep(load_study(path, out), RunOptions(n_jobs=1))
    after = CliRunner().invoke(app, ["show", str(out)], env={"COLUMNS": "300"})
    assert "8 of 8 trials stored, study hash" in after.output
    assert "→ killed (found " in after.output
    assert "aborted, 5 trial(s) stored (5 recovered from its journal)" in after.output
    assert "None" not in after.output


def test_show_tells_a_run_in_progress_from_a_killed_one(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    study = load_study(path, tmp_path / "out")
    table = build_jobs(study)
    holder = ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    try:
        holder.start_run({"backend": "loky"})
        holder.journal({"job_id": table.jobs[0].job_id, "study_hash": table.study_hash})
        res = CliRunner().invoke(app, ["show", str(study.output)], env={"COLUMNS": "300"})
        assert f"→ still running (pid {os.getpid()} on " in res.output
        assert "(and 1 finished in the running run's journal)" in res.output
    finally:
        holder.close()
    assert not (study.output / ".lock").exists()


def test_the_lock_file_is_removed_after_a_clean_run_and_the_lock_still_excludes(tmp_path: Path) -> None:
    """A clean run left its .lock behind, which looked like a stale lock."""
    path, out = _finished(tmp_path)
    assert not (out / ".lock").exists() and "'.lock'" not in (out / "manifest.json").read_text()
    res = CliRunner().invoke(app, ["plot", str(out)])  # plot takes the lock too
    assert res.exit_code == 0 and not (out / ".lock").exists()
    study = load_study(path, out)
    table = build_jobs(study)
    holder = ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    try:
        with pytest.raises(SomoError, match="is in use by another somo-sweep run"):
            ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    finally:
        holder.close()


def test_a_run_that_opened_the_lock_file_as_it_was_removed_locks_the_new_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Removing the lock file when a run ends must not let two runs hold the folder: one that
    opened the old file, then locked it after the end, would hold a lock no one else sees."""
    from somo_sweep.sweep.store import lock as lock_module

    path = tmp_path / ".lock"
    first = lock_module.acquire(path)
    stale = os.open(path, os.O_RDWR)  # a second run opens the file ...
    first.release()  # ... the first run ends and removes it ...
    third = lock_module.acquire(path)  # ... and a third run creates and holds a new one
    real = lock_module._open
    given = iter([(stale, False)])
    monkeypatch.setattr(lock_module, "_open", lambda p: next(given, None) or real(p))
    try:
        with pytest.raises(SomoError, match="is in use by another somo-sweep run"):
            lock_module.acquire(path)  # the second run locks its old file, sees it gone, tries the new
    finally:
        third.release()
    assert not path.exists()


def _enospc(*args: object, **kwargs: object) -> None:
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.mark.parametrize(
    ("code", "cause", "advice"),
    [
        (errno.ENOSPC, "the disk is full (No space left on device)", "free space on that disk"),
        (
            errno.EROFS,
            "the file system is read-only (Read-only file system)",
            "remount it read-write, or give a folder on a writable disk",
        ),
        (errno.EACCES, "permission denied (Permission denied)", "give yourself write access there"),
    ],
    ids=["full", "read-only", "no-permission"],
)
def test_a_start_that_cannot_write_names_the_lock_the_cause_and_fitting_advice(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, code: int, cause: str, advice: str
) -> None:
    """A full disk at the start said "error: No space left on device" (no path) and left a 0-byte
    .lock; a read-only one was told to free space."""
    from somo_sweep.sweep.store import lock as lock_module

    path = selftest_study(tmp_path)
    out = tmp_path / "out"

    def refuse(fd: int, data: bytes, offset: int) -> int:
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(lock_module.os, "pwrite", refuse)
    res = _run(path, out)
    assert res.exit_code == 1, res.output
    assert (
        f"error: cannot take the lock {out / '.lock'}: {cause}; nothing was written: {advice}" in res.output
    )
    assert "then run the same command again" in res.output and "Traceback" not in res.output
    assert not out.exists()  # no empty lock file, nor the folder the run created for it
    (out / "trials").mkdir(parents=True)  # an existing results folder stays, without a lock file
    assert _run(path, out).exit_code == 1 and sorted(os.listdir(out)) == ["trials"]


def test_a_results_folder_on_a_read_only_disk_is_told_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    real = Path.mkdir

    def read_only(self: Path, *args: object, **kwargs: object) -> None:
        if self == out:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(self))
        real(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Path, "mkdir", read_only)
    res = _run(path, out)
    assert res.exit_code == 1
    assert (
        f"cannot create the results folder {out}: the file system is read-only (Read-only file system); "
        "nothing was written: remount it read-write, or give a folder on a writable disk"
    ) in res.output
    assert "free space" not in res.output


@pytest.mark.parametrize(
    ("code", "cause"),
    [
        (errno.ENOSPC, "the disk is full (No space left on device)"),
        (errno.EROFS, "the file system is read-only (Read-only file system)"),
    ],
    ids=["full", "read-only"],
)
def test_a_run_that_stopped_on_a_full_disk_is_not_reported_killed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, code: int, cause: str
) -> None:
    """After a disk-full (or read-only) stop whose end could not be written to the manifest
    either, the next run said the earlier one "was killed: marked aborted"."""
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    full, real_json, filled = _DiskFull(allowed=1, code=code), store_module.write_json, []

    def parts(table: pa.Table, where: Path, **kwargs: object) -> None:
        try:
            full(table, where, **kwargs)
        except OSError:
            filled.append(True)
            raise

    def manifest(where: Path, data: dict[str, object]) -> None:
        if filled:  # once full, the disk is full for the manifest too
            raise OSError(code, os.strerror(code))
        real_json(where, data)

    monkeypatch.setattr(store_module.pq, "write_table", parts)
    monkeypatch.setattr(store_module, "write_json", manifest)
    with pytest.raises(StorageError) as info:
        run_sweep(load_study(path, out), RunOptions(n_jobs=1, chunk_rows=2))
    assert cause in str(info.value)
    assert ("free space" in str(info.value)) == (code == errno.ENOSPC)
    monkeypatch.undo()
    assert read_manifest(out)["runs"][-1]["status"] == "running"  # the manifest could not say more
    assert '"stopped"' in (out / ".lock").read_text()  # the lock file says it instead
    monkeypatch.setattr(store_module.pq, "write_table", _DiskFull(allowed=0))
    with pytest.raises(StorageError) as info:  # still full when the next run recovers the journal
        run_sweep(load_study(path, out), RunOptions(n_jobs=1))
    assert str(info.value).startswith(f"cannot open the results folder {out}: cannot write {out / 'trials'}")
    assert "the disk is full (No space left on device); what it holds is intact" in str(info.value)
    monkeypatch.undo()
    assert '"stopped"' in (out / ".lock").read_text()  # kept for the run that gets through
    assert CliRunner().invoke(app, ["plot", str(out)]).exit_code == 0  # plot takes the lock too ...
    assert '"stopped"' in (out / ".lock").read_text()  # ... and leaves the record
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=1))
    note = next(n for n in summary.notes if "stopped itself" in n)
    assert "(cannot write " in note and f": {cause}): marked failed" in note
    assert not any("killed" in n for n in summary.notes), summary.notes
    assert "recovered 2 finished trial(s) of a run that stopped itself from its journal" in summary.notes
    first = read_manifest(out)["runs"][0]
    assert first["status"] == "failed" and cause in first["failure"]
    assert (first["trials_finished"], first["trials_written"], first["trials_recovered"]) == (4, 2 + 2, 2)
    assert len(read_results(out)) == 8 and not (out / ".lock").exists()


def test_a_run_stopped_by_a_full_disk_records_the_cause_and_the_next_run_does_not_say_killed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    monkeypatch.setattr(store_module.pq, "write_table", _DiskFull(allowed=1))
    with pytest.raises(StorageError):
        run_sweep(load_study(path, out), RunOptions(n_jobs=1, chunk_rows=2))
    monkeypatch.undo()
    run = read_manifest(out)["runs"][-1]
    assert run["status"] == "failed" and "the disk is full (No space left on device)" in run["failure"]
    assert not (out / ".lock").exists()  # the manifest says it all: no stop record needed
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=1))
    assert not any("killed" in n for n in summary.notes), summary.notes
    show = CliRunner().invoke(app, ["show", str(out)], env={"COLUMNS": "300"})
    assert ": failed (cannot write " in show.output and "the disk is full" in show.output


def test_trials_cut_short_by_a_stop_are_counted_in_our_words_not_joblibs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After a write failure joblib warned "UserWarning: 4 tasks which were still being processed
    by the workers have been cancelled"."""
    import warnings

    path = selftest_study(tmp_path, extra="set: {task.sleep_s: 0.3}", n=12)
    monkeypatch.setattr(store_module.pq, "write_table", _DiskFull(allowed=0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(StorageError) as info:
            run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=2, chunk_rows=1))
    assert not [w for w in caught if "tasks" in str(w.message)], [str(w.message) for w in caught]
    assert re.search(r"; the \d+ trial\(s\) still running were stopped\. To go on:", str(info.value))


def test_a_run_left_running_by_a_killed_process_is_marked_aborted(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    study = load_study(path, tmp_path / "out")
    table = build_jobs(study)
    killed = ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    killed.start_run({"backend": "loky"})
    killed.close()  # the process died: no end_run
    summary = run_sweep(study, RunOptions(n_jobs=1))
    runs = read_manifest(study.output)["runs"]
    assert [r["status"] for r in runs] == ["aborted", "completed"]
    killed = "was killed (or its disk could not be written even to record its end): marked aborted"
    assert any(killed in note for note in summary.notes)


def test_a_column_empty_in_the_first_part_takes_numbers_on_resume(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    study = load_study(path, tmp_path / "out")
    table = build_jobs(study)
    rows = [
        {"job_id": j.job_id, "trial": j.trial, "status": "ok", "study_hash": table.study_hash}
        for j in table.jobs
    ]
    args = (study.output, table.study_hash, table.resolved, table.axes, {})
    first = ResultStore(*args)
    first.write([{**rows[0], "gap_m": None}])
    first.close()
    second = ResultStore(*args)
    second.write([{**rows[1], "gap_m": 1.5}])
    second.close()
    df = read_results(study.output)
    assert df["gap_m"].dtype == "float64" and df["gap_m"].isna().tolist() == [True, False]


def test_declared_metric_types_fix_the_schema_from_the_first_part(tmp_path: Path) -> None:
    # Every trial fails: no row has a metric, yet the columns are there with the declared types.
    path = selftest_study(tmp_path, task="selftest_crash", extra="set: {task.crash_x: [1.0, 2.0]}", n=2)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    schema = pq.read_schema(_parts(tmp_path / "out")[0])
    assert schema.field("y").type == pa.float64() and schema.field("noise").type == pa.float64()


def test_a_metric_missing_in_early_trials_keeps_its_type(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, extra="set: {task.none_x: [1.0, 2.0]}", n=4)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1, chunk_rows=2))
    df = read_results(tmp_path / "out")
    assert df["y"].dtype == "float64" and df["y"].isna().tolist() == [True, True, False, False]


def test_every_run_keeps_its_versions(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    run_sweep(load_study(path, out), RunOptions(n_jobs=1))
    runs = read_manifest(out)["runs"]
    assert len(runs) == 2 and all({"python", "pybullet", "somo-sweep"} <= set(r["versions"]) for r in runs)


def test_job_ids_change_with_the_pybullet_version(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = selftest_study(tmp_path)
    before = build_jobs(load_study(path))
    monkeypatch.setattr(job_module, "pybullet_version", lambda: "0.0.1")
    monkeypatch.setattr(jobs_module, "pybullet_version", lambda: "0.0.1")
    after = build_jobs(load_study(path))
    assert not {j.job_id for j in before.jobs} & {j.job_id for j in after.jobs}
    assert after.resolved["pybullet"] == "0.0.1"


def test_resume_after_a_crash_mid_rewrite_heals_mixed_schemas(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    part = _parts(out)[0]
    table = pq.read_table(part)
    pq.write_table(table.append_column("extra_m", pa.array([1.0] * len(table))), part)
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=1))
    assert summary.run == 0
    schemas = {pq.read_schema(p).remove_metadata().to_string() for p in _parts(out)}
    assert len(schemas) == 1 and len(pd.read_parquet(out / "trials")) == 8
    assert results_only(read_results(out)).shape[0] == 8


def test_study_copy_and_manifest_name_what_was_written(tmp_path: Path) -> None:
    path = make_study(tmp_path, "task: selftest_sleep\nmodel: models/ihm_finger.yaml\n")
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert "study.yaml" in manifest["files"] and manifest["runs"][0]["trials_written"] == 1


@pytest.mark.parametrize("name", [".lock", ".manifest.json.tmp", ".study.yaml.tmp", "trials", "plots"])
def test_a_link_left_in_the_folder_never_carries_a_write_outside_it(tmp_path: Path, name: str) -> None:
    """A resumed run opened .lock and wrote .manifest.json.tmp / .study.yaml.tmp through links."""
    path, out = _finished(tmp_path)
    outside = tmp_path / "outside"
    outside.mkdir()
    victim = outside / "victim.txt"
    victim.write_text("my precious notes\n")
    link = out / name
    if link.is_dir():
        link.rename(tmp_path / f"moved-{name}")
    link.unlink(missing_ok=True)
    link.symlink_to(outside if name in ("trials", "plots") else victim)
    res = _run(path, out)
    assert "Traceback" not in res.output  # type: ignore[attr-defined]
    assert victim.read_text() == "my precious notes\n" and sorted(os.listdir(outside)) == ["victim.txt"]
    if name in (".lock", "trials", "plots"):
        assert res.exit_code == 2 and "is a symbolic link" in res.output, res.output  # type: ignore[attr-defined]
    else:
        assert res.exit_code == 0 and not (out / "study.yaml").is_symlink(), res.output  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("files", [1]),
        ("files", [None]),
        ("columns", {"a": 1}),
        ("columns", {"a": {"type": "?"}}),
        ("n_trials", True),
        ("n_trials", -5),
    ],
)
def test_a_manifest_with_wrong_inner_types_is_rebuilt_not_a_traceback(
    tmp_path: Path, key: str, value: object
) -> None:
    path, out = _finished(tmp_path)
    manifest = json.loads((out / "manifest.json").read_text())
    manifest[key] = value
    (out / "manifest.json").write_text(json.dumps(manifest))
    res = _run(path, out)
    assert res.exit_code == 0 and "rebuilt from the part files" in res.output, res.output  # type: ignore[attr-defined]
    assert len(read_results(out)) == 8


@pytest.mark.parametrize(
    ("value", "said"), [(True, "true"), (-5, "-5"), (0, "0"), (2.5, "2.5"), ("8", '"8"')]
)
def test_a_trial_count_no_study_has_is_refused_not_printed(tmp_path: Path, value: object, said: str) -> None:
    """``n_trials: true`` in a manifest showed "0 of True trials stored"; -5, "of -5 trials"."""
    _, out = _finished(tmp_path)
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["n_trials"] = value
    (out / "manifest.json").write_text(json.dumps(manifest))
    for command in ("show", "plot"):
        res = CliRunner().invoke(app, [command, str(out)])
        assert res.exit_code == 2 and "Traceback" not in res.output, res.output
        assert (
            f"manifest.json is damaged (its 'n_trials' is {said}, not a whole number of trials of at least "
            f"1); run the study again with --out {out} to rebuild it from the trials"
        ) in res.output


def test_a_part_of_another_study_copied_in_is_quarantined_by_the_next_run(tmp_path: Path) -> None:
    """`run` said all was well while `show` refused the folder."""
    path, out = _finished(tmp_path)
    other = pd.read_parquet(_parts(out)[0]).assign(study_hash="zz", job_id=lambda d: "x" + d["job_id"])
    other.to_parquet(out / "trials" / "part-from-elsewhere.parquet")
    assert CliRunner().invoke(app, ["show", str(out)]).exit_code == 2
    res = _run(path, out)
    assert (
        res.exit_code == 0
        and "part file part-from-elsewhere.parquet holds rows of another study" in res.output
    )  # type: ignore[attr-defined]
    assert (out / "trials" / "quarantine" / "_part-from-elsewhere.parquet").is_file()
    show = CliRunner().invoke(app, ["show", str(out)])
    assert show.exit_code == 0 and len(read_results(out)) == 8, show.output


def test_a_part_of_another_study_sharing_job_ids_is_one_foreign_study_error(tmp_path: Path) -> None:
    """A study sharing cells with this one has the same job ids: its part copied in was also
    reported as "repeats 4 row(s) … (a copy?)" beside the foreign-study error."""
    path, out = _finished(tmp_path)
    other = make_study(tmp_path / "b", (tmp_path / "study.yaml").read_text().replace("stop: 8", "stop: 4"))
    run_sweep(load_study(other, tmp_path / "b" / "out"), RunOptions(n_jobs=1))
    (copy,) = _parts(tmp_path / "b" / "out")
    assert set(pd.read_parquet(copy)["job_id"]) <= set(read_results(out)["job_id"])  # the same cells
    shutil.copy(copy, out / "trials" / "part-from-b.parquet")
    res = CliRunner().invoke(app, ["show", str(out)])
    assert res.exit_code == 2 and "4 row(s) belong to another study" in res.output, res.output
    assert "in part-from-b.parquet; move that file away" in res.output
    assert "repeats" not in res.output and "a copy?" not in res.output
    ran = _run(path, out)
    assert ran.exit_code == 0 and "part file part-from-b.parquet holds rows of another study" in ran.output
    assert "repeats" not in ran.output and len(read_results(out)) == 8


def test_a_scheduler_without_the_dask_backend_is_refused(tmp_path: Path) -> None:
    res = _run(selftest_study(tmp_path), tmp_path / "o", "--scheduler", "tcp://203.0.113.5:8786")
    assert res.exit_code == 2 and "--scheduler is for --backend dask" in res.output  # type: ignore[attr-defined]


def test_show_prints_stored_text_verbatim_and_terminal_controls_escaped(tmp_path: Path) -> None:
    """An error message quoting a path in brackets crashed ``show`` (rich markup); an escape
    sequence in a stored status retitled the terminal and cleared the screen."""
    _, out = _finished(tmp_path)
    first = _parts(out)[0]
    table = pq.read_table(first)
    n = table.num_rows
    table = table.set_column(table.column_names.index("status"), "status", pa.array(["error"] * n))
    message = "OSError: cannot read [/tmp/models/finger.yaml] [red]x\x1b]0;PWNED\x07\x1b[2J"
    table = table.set_column(table.column_names.index("message"), "message", pa.array([message] * n))
    pq.write_table(table, first)
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["study_name"] = "[/oops]"
    manifest["axes"] = {"task.x": ["not", "a", "column"]}
    (out / "manifest.json").write_text(json.dumps(manifest))
    res = CliRunner().invoke(app, ["show", str(out)], env={"COLUMNS": "400"})
    assert res.exit_code == 0, res.output
    assert "[/oops]" in res.output and "[/tmp/models/finger.yaml] [red]x" in res.output
    assert "\x1b" not in res.output and "\\x1b]0;PWNED\\x07\\x1b[2J" in res.output


@pytest.mark.parametrize("column", ["status", "__part_file__", "inferred"])
def test_a_part_with_a_repeated_or_reserved_column_is_set_aside(tmp_path: Path, column: str) -> None:
    """A second ``status`` column was a KeyError in every reader and in ``run`` (the folder was
    stuck); a ``__part_file__`` column an ArrowInvalid; an ``inferred`` one blamed inferred.parquet."""
    path, out = _finished(tmp_path)
    first = _parts(out)[0]
    table = pq.read_table(first)
    pq.write_table(table.append_column(column, pa.array(["x"] * table.num_rows)), first)
    skipped: list[str] = []
    assert len(read_results(out, lambda part, why: skipped.append(why))) == 4
    assert len(skipped) == 1 and f"'{column}'" in skipped[0]
    res = _run(path, out)
    assert res.exit_code == 0, res.output
    assert len(read_results(out)) == 8


def test_a_part_we_may_not_read_is_left_out_by_readers_and_never_moved(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A part without read permission was called damaged, and the next run moved it to the
    quarantine and ran its trials again; an unreadable trials/ read as an unfinished study."""
    path, out = _finished(tmp_path)
    first = _parts(out)[0]
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == first else real(p, mode))
    skipped: list[str] = []
    assert len(read_results(out, lambda part, why: skipped.append(why))) == 4
    assert skipped == ["cannot be read (permission denied)"]
    res = _run(path, out)
    assert res.exit_code == 2 and f"cannot read {first}: permission denied" in res.output, res.output
    assert first.exists() and not (out / "trials" / "quarantine").exists()
    trials = out / "trials"
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == trials else real(p, mode))
    with pytest.raises(SomoError, match=f"cannot read {trials}: permission denied"):
        read_results(out)


def test_trials_as_a_file_is_named_not_read_as_no_trials(tmp_path: Path) -> None:
    _, out = _finished(tmp_path)
    for part in _parts(out):
        part.unlink()
    (out / "trials").rmdir()
    (out / "trials").write_text("not a folder")
    with pytest.raises(SomoError, match="trials is not a folder"):
        read_results(out)


def test_plot_with_a_folder_where_the_lock_goes_draws_and_exits_0(tmp_path: Path) -> None:
    """It wrote the plots, then exited 2 with "Is a directory: .lock"."""
    _, out = _finished(tmp_path)
    (out / ".lock").unlink(missing_ok=True)
    (out / ".lock").mkdir()
    res = CliRunner().invoke(app, ["plot", str(out)])
    assert res.exit_code == 0, res.output
    assert (out / "plots" / "summary.png").is_file()


def test_a_fifo_among_the_parts_is_skipped_not_waited_on(tmp_path: Path) -> None:
    """Reading it hung show, plot, classify and paper fig6 until killed."""
    _, out = _finished(tmp_path)
    os.mkfifo(out / "trials" / "part-x.parquet")
    skipped: list[str] = []
    assert len(read_results(out, lambda part, why: skipped.append(why))) == 8
    assert skipped == ["not a regular file"]


def test_a_stop_record_with_a_long_cause_still_reads_back(tmp_path: Path) -> None:
    """A long file name in the cause must not cut the record's JSON (the next run would say killed)."""
    from somo_sweep.sweep.store.lock import LOCK_BYTES, acquire

    path = tmp_path / ".lock"
    lock = acquire(path)
    assert lock.record_stop({"stopped": "2026-01-01T00:00:00+00:00", "cause": "é" * 2000})
    lock.release(remove=False)
    assert path.stat().st_size == LOCK_BYTES
    again = acquire(path)
    try:
        record = again.stop_record
        assert record is not None and record["stopped"] == "2026-01-01T00:00:00+00:00"
        assert record["cause"].startswith("éé") and record["cause"].endswith("…")
    finally:
        again.release()
    assert not path.exists()


def test_a_fifo_where_the_lock_goes_is_named_and_never_waited_on(tmp_path: Path) -> None:
    path, out = _finished(tmp_path)
    os.mkfifo(out / ".lock")
    res = CliRunner().invoke(app, ["show", str(out)])
    assert res.exit_code == 0 and "8 of 8 trials stored" in res.output, res.output
    res = _run(path, out)
    assert res.exit_code == 2 and f"{out / '.lock'} is not a regular file (a FIFO" in res.output, res.output


def test_readers_of_a_folder_with_only_a_killed_run_s_journal_say_what_waits_there(tmp_path: Path) -> None:
    """``classify`` said "no finished trials yet" with 37 trials in the journal."""
    from somo_sweep.paper.grasp_trials import read_results as read_grasp_trials

    path = selftest_study(tmp_path)
    out = tmp_path / "out"
    _killed_after(path, out, 5)
    said = (
        f"{out}: no trials stored yet, but 5 finished trial(s) wait in the journal of a run that was "
        "killed before storing them; run the study into this folder again (somo-sweep run STUDY.yaml, "
        "with the same --out if it had one): it stores them before anything else runs"
    )
    with pytest.raises(SomoError) as grasp:
        read_grasp_trials(out)
    assert str(grasp.value) == said
    res = CliRunner().invoke(app, ["recheck", str(path), "--out", str(out)], env={"COLUMNS": "400"})
    assert res.exit_code == 2 and " ".join(res.output.split()) == f"error: {said}"


def test_readers_of_a_folder_with_nothing_finished_say_how_many_trials_the_study_has(tmp_path: Path) -> None:
    from somo_sweep.sweep.store.folder import nothing_stored

    study = load_study(selftest_study(tmp_path), tmp_path / "out")
    table = build_jobs(study)
    holder = ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    holder.start_run({"backend": "loky"})
    said = nothing_stored(study.output)
    assert said == f"{study.output}: no finished trials stored yet (of 8 in the study)"


def test_a_manifest_that_cannot_be_written_is_named_and_leaves_no_temporary_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk while the manifest's temporary file was written named that temporary file
    (``.manifest.json.….tmp``), not the manifest the user knows of."""
    from somo_sweep.sweep.store.manifest import write_json

    def full(self: Path, *args: object, **kwargs: object) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))

    monkeypatch.setattr(Path, "write_text", full)
    with pytest.raises(OSError) as info:
        write_json(tmp_path / "manifest.json", {"runs": []})
    assert info.value.errno == errno.ENOSPC
    assert info.value.filename == str(tmp_path / "manifest.json")
    assert list(tmp_path.iterdir()) == []
