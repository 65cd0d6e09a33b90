"""The MuJoCo step benchmark: both paths timed side by side, labels equal, switches restored."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from benchmarks.mujoco_step import build, code_path
from somo_sweep.sim.mujoco import blocks, scene


def test_the_before_path_switches_the_servos_and_the_blocks_off_and_back() -> None:
    saved = (scene.SERVOS, blocks.BLOCKS)
    assert saved == (False, True)  # the defaults: roots driven by their speeds, runs of steps in C
    with code_path(before=True):
        assert (scene.SERVOS, blocks.BLOCKS) == (False, False)
    assert saved == (scene.SERVOS, blocks.BLOCKS)


def test_one_cell_both_ways_gives_the_same_labels_and_the_share_inside_mj_step() -> None:
    out = build(columns_every=24, per_column=2)
    summary = out.json["mujoco_step_speed.json"]
    assert summary["cells"] == 2 and summary["cells_with_equal_labels"] == 2
    for path in ("before", "after"):
        assert 0.0 < summary[path]["share_inside_mj_step"] < 1.0
        assert summary[f"{path}_path"].startswith("root")  # what the path is, beside its numbers
    # both paths drive the root by its speeds: one scene, compiled once for the column
    assert summary["scene_cache"] == {"hits": 3, "misses": 1}
    # early stops checked every 10 ms before, every 40 ms after: the after path may step a little longer
    assert 0 < summary["before"]["steps"] <= summary["after"]["steps"] <= 1.05 * summary["before"]["steps"]
    assert any(line.lstrip().startswith("after/before") for line in out.lines)
