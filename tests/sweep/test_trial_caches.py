"""What a forked trial caches goes back to its worker, and the next trial there gives the same."""

from __future__ import annotations

import pytest

from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.trial import run_isolated
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.compare_engines import on_engine

pytest.importorskip("mujoco")
from somo_sweep.sim.mujoco.scene_cache import SCENES


def test_a_trials_compiled_scene_reaches_its_worker_and_changes_nothing() -> None:
    study = load_study(bundled_path("pinch_grasp_quick.yaml"))
    jobs = build_jobs(on_engine(study, "mujoco", study.output, 4e-3)).jobs
    first, second = jobs[0], jobs[1]  # one (DSR, width) column: one scene, the hand placed apart
    SCENES.clear()
    SCENES.enabled = False
    try:
        compiled = run_isolated(second)
    finally:
        SCENES.enabled = True
    run_isolated(first)
    assert len(SCENES) == 1  # the child's scene, adopted by this process
    served = run_isolated(second)
    assert served.status == compiled.status == "ok"
    assert served.labels == compiled.labels
    assert {k: repr(v) for k, v in served.metrics.items()} == {
        k: repr(v) for k, v in compiled.metrics.items()
    }
