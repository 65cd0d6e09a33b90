"""The URDF cache: where it is (and the variables that move it), and its size bound."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from conftest import ROOT

from somo_sweep.sim import urdf_cache
from somo_sweep.sim.urdf_cache import MAX_CACHE_BYTES, cache_dir, prune_cache, write_urdf


def test_the_cache_is_in_the_users_cache_folder_unless_a_variable_moves_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("SOMO_SWEEP_CACHE", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "somo-sweep" / "urdf"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "somo-sweep" / "urdf"
    monkeypatch.setenv("SOMO_SWEEP_CACHE", str(tmp_path / "moved"))
    assert write_urdf("<robot name='a'/>").parent == tmp_path / "moved" / "urdf"


def _files(folder: Path, ages_s: list[float], size: int = 100) -> list[Path]:
    """One file of ``size`` bytes per age (s since its last use), oldest first."""
    folder.mkdir(parents=True, exist_ok=True)
    now = time.time()
    paths = []
    for i, age in enumerate(ages_s):
        path = folder / f"{i:04d}.urdf"
        path.write_bytes(b"x" * size)
        os.utime(path, (now - age, now - age))
        paths.append(path)
    return paths


def test_an_oversized_cache_loses_its_least_recently_used_files_down_to_the_share_kept(
    tmp_path: Path,
) -> None:
    paths = _files(tmp_path, [9000.0, 8000.0, 7000.0, 6000.0, 5000.0])  # 500 bytes in all
    assert prune_cache(tmp_path, max_bytes=600) == 0  # under the bound: nothing goes
    assert prune_cache(tmp_path, max_bytes=400, keep_recent_s=60.0) == 2  # down to 0.8 x 400
    assert [p.exists() for p in paths] == [False, False, True, True, True]


def test_files_used_recently_stay_whatever_the_size(tmp_path: Path) -> None:
    paths = _files(tmp_path, [7200.0, 10.0, 5.0])
    assert prune_cache(tmp_path, max_bytes=100, keep_recent_s=3600.0) == 1
    assert [p.exists() for p in paths] == [False, True, True]


def test_writing_a_new_file_keeps_the_cache_bounded_and_a_used_file_is_renewed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SOMO_SWEEP_CACHE", str(tmp_path))
    old = _files(cache_dir(), [9000.0] * 20, size=1000)
    kept = write_urdf("<robot name='kept'/>")
    os.utime(kept, (time.time() - 8000, time.time() - 8000))
    assert write_urdf("<robot name='kept'/>") == kept and time.time() - kept.stat().st_mtime < 60
    monkeypatch.setattr(urdf_cache, "MAX_CACHE_BYTES", 10_000)
    new = write_urdf("<robot name='new'/>")
    assert new.exists() and kept.exists()
    assert sum(p.exists() for p in old) <= 8  # at most 0.8 x 10 kB left of the old files


def test_the_docs_give_the_cache_its_place_bound_and_variable() -> None:
    text = (ROOT / "docs" / "outputs.md").read_text()
    assert "~/.cache/somo-sweep/urdf" in text and "SOMO_SWEEP_CACHE" in text
    assert f"at most {MAX_CACHE_BYTES // 1_000_000} MB" in text


def _unwritable(folder: str) -> str:
    return (
        f"SOMO_SWEEP_CACHE={folder}: the URDF cache folder {folder}/urdf cannot be created or written "
        "(Not a directory); PyBullet loads every body from a file there; needed: point SOMO_SWEEP_CACHE "
        "at a folder you can create and write, or unset it"
    )


def test_a_cache_variable_naming_a_file_is_one_error_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    monkeypatch.setenv("SOMO_SWEEP_CACHE", str(a_file))
    with pytest.raises(urdf_cache.CacheUnwritable) as checked:
        urdf_cache.check_cache()
    assert str(checked.value) == _unwritable(str(a_file))
    with pytest.raises(urdf_cache.CacheUnwritable) as written:
        write_urdf("<robot name='a'/>")
    assert str(written.value) == str(checked.value)


def test_a_bench_row_lets_an_unwritable_cache_through_instead_of_storing_a_failed_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from somo_sweep.model.load import load_model
    from somo_sweep.statics.solve import clear_cache, solve_row

    (tmp_path / "a_file").write_text("")
    monkeypatch.setenv("SOMO_SWEEP_CACHE", str(tmp_path / "a_file"))
    clear_cache()  # a body loaded before (another test) would not need the cache
    model = load_model(ROOT / "somo_sweep" / "data" / "models" / "ihm_finger.yaml")
    with pytest.raises(urdf_cache.CacheUnwritable, match="SOMO_SWEEP_CACHE="):
        solve_row(model, "free_bending", 50.0, 0.0)


def test_a_pybullet_study_with_an_unwritable_cache_stops_before_any_trial(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    (tmp_path / "a_file").write_text("")
    monkeypatch.setenv("SOMO_SWEEP_CACHE", str(tmp_path / "a_file"))
    study = tmp_path / "study.yaml"
    study.write_text(
        f"task: bench\nmodel: {ROOT / 'somo_sweep' / 'data' / 'models' / 'ihm_finger.yaml'}\n"
        "sweep:\n  task.pressure_kpa: [0, 50]\nsimulation: {time_step_s: 5.0e-4}\n"
    )
    result = CliRunner().invoke(app, ["run", str(study), "--out", str(tmp_path / "out"), "--jobs", "1"])
    assert result.exit_code == 2, result.output
    assert " ".join(result.output.split()) == f"error: {_unwritable(str(tmp_path / 'a_file'))}"
    assert not (tmp_path / "out").exists()
