"""The MuJoCo step benchmark: both paths timed side by side, labels equal, switches restored."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from benchmarks.mujoco_step import build, code_path
from somo_sweep.sim import follow
from somo_sweep.sim.mujoco import scene
from somo_sweep.sim.mujoco.scene_cache import SCENES


def test_the_before_path_switches_every_cut_off_and_back() -> None:
    with code_path(before=True):
        assert (scene.JACOBIAN, follow.PLAN_RUNS, SCENES.enabled) == ("sparse", False, False)
    assert (scene.JACOBIAN, follow.PLAN_RUNS, SCENES.enabled) == ("dense", True, True)


def test_one_cell_both_ways_gives_the_same_labels_and_the_share_inside_mj_step() -> None:
    out = build(columns_every=24, per_column=2)
    summary = out.json["mujoco_step_speed.json"]
    assert summary["cells"] == 2 and summary["cells_with_equal_labels"] == 2
    for path in ("before", "after"):
        assert 0.0 < summary[path]["share_inside_mj_step"] < 1.0
    assert summary["scene_cache"] == {"hits": 1, "misses": 1}  # the column's second cell
    assert any(line.lstrip().startswith("after/before") for line in out.lines)
