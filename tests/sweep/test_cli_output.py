"""Files the command line writes: atomically, with the permissions a plain write would give."""

from __future__ import annotations

import os
import stat
import time
from pathlib import Path

import pytest

from somo_sweep.cli.output import write_atomic
from somo_sweep.errors import SomoError


def test_a_new_file_gets_the_umask_permissions_not_the_temporary_files(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        path = write_atomic(tmp_path / "sub" / "table.csv", "a,b\n1,2\n")
    finally:
        os.umask(old)
    assert path.read_text() == "a,b\n1,2\n"
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    assert [p.name for p in path.parent.iterdir()] == ["table.csv"]  # no temporary left behind


def test_an_existing_file_keeps_its_mode(tmp_path: Path) -> None:
    path = tmp_path / "report.md"
    path.write_text("old")
    path.chmod(0o640)
    write_atomic(path, b"new")
    assert path.read_bytes() == b"new" and stat.S_IMODE(path.stat().st_mode) == 0o640


def test_a_fifo_where_an_output_goes_is_refused_not_waited_on(tmp_path: Path) -> None:
    """``plot``, ``classify`` and ``paper fig6`` opened it to see whether they wrote it, and hung."""
    from somo_sweep.cli.output import write_outputs

    for name in ("summary.png", "labels.csv", "fig6.json"):
        fifo = tmp_path / name
        os.mkfifo(fifo)
        with pytest.raises(SomoError, match=f"{name} is not a regular file"):
            write_outputs([(fifo, "data")])
        assert stat.S_ISFIFO(fifo.stat().st_mode)


def test_a_folder_we_cannot_write_in_is_found_before_the_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A read-only output folder was found only when writing, after the whole calibration."""
    from somo_sweep.cli.output import check_replaceable

    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == tmp_path else real(p, mode))
    with pytest.raises(SomoError) as info:
        check_replaceable(tmp_path / "sub" / "m.yaml")
    assert str(info.value) == (
        f"cannot write {tmp_path}/sub/m.yaml: {tmp_path} is read-only to us: permission denied (Permission "
        "denied); nothing was written: give yourself write access there, or give a folder of yours"
    )
    monkeypatch.setattr("somo_sweep.cli.replaceable._read_only_disk", lambda folder: folder == tmp_path)
    with pytest.raises(SomoError) as info:  # a read-only mount is no matter of permissions
        check_replaceable(tmp_path / "sub" / "m.yaml")
    assert ": the file system is read-only (Read-only file system); nothing was written: remount it" in str(
        info.value
    )


def test_a_failed_write_names_the_file_asked_for_not_the_temporary_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno

    def refuse(src: object, dst: object) -> None:
        raise OSError(errno.EROFS, "Read-only file system", str(src))

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OSError) as info:
        write_atomic(tmp_path / "model.yaml", "x")
    assert (
        info.value.filename == str(tmp_path / "model.yaml") and info.value.strerror == "Read-only file system"
    )
    assert list(tmp_path.iterdir()) == []


def test_a_killed_writers_temporary_file_is_cleared_by_the_next_write(tmp_path: Path) -> None:
    """A plot or figure killed between writing and renaming left .NAME.*.tmp forever."""
    old = tmp_path / ".summary.png.abc123.tmp"
    old.write_bytes(b"half a figure")
    os.utime(old, (time.time() - 3600, time.time() - 3600))
    fresh = tmp_path / ".summary.png.def456.tmp"  # another writer's, right now: kept
    fresh.write_bytes(b"in progress")
    other = tmp_path / ".notes.txt.abc123.tmp"  # not this output's
    other.write_bytes(b"x")
    os.utime(other, (time.time() - 3600, time.time() - 3600))
    write_atomic(tmp_path / "summary.png", b"png")
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        ".notes.txt.abc123.tmp",
        ".summary.png.def456.tmp",
        "summary.png",
    ]
