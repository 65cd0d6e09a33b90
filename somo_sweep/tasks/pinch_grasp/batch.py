"""Many pinch-grasp trials run in one batch of worlds (:mod:`somo_sweep.sim.batch`).

Each trial is set up in its own world exactly as :func:`~.task.run_pinch_grasp` sets it up
(:class:`~.task.Trial`); then every world still running steps to the next stop in one call of
the batch, and each trial does its stop's work (samples, checks, the early stop) on its own
world. A trial that ends early, or blows up, leaves the batch and its slot idles. The trials of
a batch stop at the same steps (the same time step, phase durations and periods), and on engine
``mujoco_warp`` their scenes share one compiled structure (the same finger link count and DSR
split); a batch that mixes them is refused. On an engine that steps one world at a time the
results are those of :func:`~.task.run_pinch_grasp`, bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence

from somo_sweep.errors import UnstableSimulation
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.worlds import open_batch
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import Trial, trial_settings
from somo_sweep.tasks.registry import TaskResult

__all__ = ["run_pinch_grasp_batch"]


def run_pinch_grasp_batch(
    trials: Sequence[tuple[Model, PinchGraspParams]], settings: WorldSettings
) -> list[TaskResult]:
    """Run pinch-grasp trials together; their results in order.

    Args:
        trials: Each trial's gripper model and parameters.
        settings: The worlds' settings (the engine serving the batch).

    Raises:
        ValueError: The trials do not stop at the same steps.
    """
    if not trials:
        return []
    worlds_settings = [trial_settings(params, settings) for _, params in trials]
    results: list[TaskResult | None] = [None] * len(trials)
    with open_batch(worlds_settings) as batch:
        started = [Trial.start(w, m, p) for w, (m, p) in zip(batch.worlds, trials, strict=True)]
        stops = started[0].steps.stops
        if any(t.steps.stops != stops for t in started):
            raise ValueError("the trials of a batch must stop at the same steps (time step, phases, periods)")
        progress = [t.progress() for t in started]
        running, done = list(range(len(trials))), 0
        for i in stops:
            failed = batch.step(i - done, running)
            done = i
            for k, exc in failed.items():
                unstable = isinstance(exc, UnstableSimulation)
                results[k] = TaskResult(status="unstable" if unstable else "error", message=str(exc))
            running = [k for k in running if k not in failed and progress[k].at(i)]
            if not running:
                break
        for k, trial in enumerate(started):
            if results[k] is None:
                results[k] = trial.finish(progress[k].ending())
    return [r for r in results if r is not None]
