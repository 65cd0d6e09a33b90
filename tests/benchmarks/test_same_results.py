"""``python -m benchmarks.same_results``: two folders of one study compared trial by trial."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
from conftest import MODELS

from benchmarks.same_results import compare_folders, main
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.study import load_study

STUDY = (
    "name: st\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\nparams: {sleep_s: 0.0}\n"
    "sweep:\n  task.x: {start: 1, stop: 4, step: 1}\nsimulation: {time_step_s: 1.0e-3}\n"
)


def _two_runs(tmp_path: Path) -> tuple[Path, Path]:
    (tmp_path / "models").mkdir()
    shutil.copy(MODELS / "ihm_finger.yaml", tmp_path / "models")
    (tmp_path / "study.yaml").write_text(STUDY)
    for name in ("before", "after"):
        run_sweep(load_study(tmp_path / "study.yaml", tmp_path / name), RunOptions(n_jobs=1))
    return tmp_path / "before", tmp_path / "after"


def test_two_runs_of_one_study_are_the_same_and_one_changed_bit_is_found(tmp_path: Path) -> None:
    before, after = _two_runs(tmp_path)
    same = compare_folders(before, after)
    assert (same.matched, same.identical, same.same) == (4, 4, True)
    assert "job_id" not in same.columns and "wall_time_s" not in same.columns and "y" in same.columns
    assert main([str(before), str(after)]) == 0
    part = sorted((after / "trials").glob("*.parquet"))[0]
    table = pd.read_parquet(part)
    table.loc[0, "y"] = table.loc[0, "y"] + 1e-12  # one metric, one bit or so
    table.to_parquet(part)
    changed = compare_folders(before, after)
    assert (changed.identical, changed.differing, changed.moved, changed.same) == (3, {"y": 1}, [], False)
    assert changed.largest["y"][0] > 0
    assert main([str(before), str(after), "--detail"]) == 1
