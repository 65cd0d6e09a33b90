"""One pinch-grasp trial rerun exactly as its sweep ran it, with snapshots of it on the way.

The trial is the study's job (model, parameters, settings with the study's chosen step and
inertia shaping, seed) run through the sweep's own :func:`~somo_sweep.sweep.run.trial.run_job`:
a run that blows up is run again at half the step, as every stored trial was, and the snapshots
are those of the run whose outcome is reported. Snapshots read the world and change nothing in it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from somo_sweep.errors import SomoError
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.paper.grasp_trials import find_trial

if TYPE_CHECKING:
    from somo_sweep.sim.render import Camera
    from somo_sweep.sweep.run.trial import Outcome
    from somo_sweep.sweep.study import Study

__all__ = ["MAX_SNAPSHOTS", "TrialRender", "render_trial"]

#: Most snapshots one ``render`` call takes (each is a PNG of the scene).
MAX_SNAPSHOTS = 100
#: Size of a rendered snapshot (width, height), px: twice the camera's default, so that the
#: fingers and their links read (TinyRenderer takes about 0.3 s more per snapshot).
RENDER_SIZE_PX = (960, 800)
#: The camera's distance from the point between the object and the finger mounts it looks at, m
#: (its view is 0.29 m tall there: the fingers and the lifted object fill the frame).
RENDER_DISTANCE_M = 0.40


@dataclass(frozen=True)
class TrialRender:
    """One trial rerun with its snapshots.

    Attributes:
        images: The snapshots it reached (one PNG each); empty when it reached none.
        status: The trial's status (``ok``, ``unstable``, ``error``), as its sweep stores it.
        label: Its label (its status if not ``ok``, with why), the snapshots it did not reach and
            why, its step and how that was reached, in one line.
    """

    images: Artifacts
    status: str
    label: str


def _check_times(times_s: list[float], duration_s: float) -> None:
    """Refuse no snapshot, too many, or one outside the trial's ``duration_s``."""
    if not 1 <= len(times_s) <= MAX_SNAPSHOTS:
        raise SomoError(f"--at-s: give 1 to {MAX_SNAPSHOTS} snapshot times, got {len(times_s)}")
    outside = [t for t in times_s if not (math.isfinite(t) and 0.0 <= t <= duration_s)]
    if outside:
        raise SomoError(
            f"--at-s {outside[0]:g}: a snapshot time must be from 0 to {duration_s:g} s (the trial's length)"
        )


def _trial_label(outcome: Outcome, missed_s: list[float], study_step_s: float, step_chosen: bool) -> str:
    """The trial's label, the snapshots it missed (``missed_s``) and why, and its step."""
    result = outcome.result
    if outcome.status != "ok":
        label = f"{outcome.status} ({outcome.message})"
        if missed_s:
            label += f"; no snapshot at {', '.join(f'{t:g}' for t in missed_s)} s: the run ended before"
    else:
        label = str(result.labels.get("grasp", result.status))
        ended = result.metrics.get("ended_early_s")
        if isinstance(ended, float) and math.isfinite(ended) and missed_s:
            why = result.metrics.get("ended_early_reason", "")
            label += f" (ended early at {ended:.2f} s: {why}; no snapshot after it)"
    label += f"; step {outcome.time_step_used_s * 1e3:g} ms"
    if outcome.retried_half_step:
        label += f" (the run at {study_step_s * 1e3:g} ms blew up; rerun at half the step, as the sweep does)"
    if not step_chosen:
        # No step chosen yet: the jobs carry the modal starting guess, which a sweep may reject.
        label += (
            " (the automatic step's starting guess: this study has not chosen its step yet; "
            "`somo-sweep check STUDY.yaml` or a run chooses it, then render uses that)"
        )
    return label


def _study_to_render(
    study_path: str | Path,
    engine: str | None,
    notes: Callable[[Sequence[str]], None] | None,
    results: str | Path | None = None,
) -> Study:
    """The pinch_grasp study a render reruns a trial of: loaded with the step its results folder
    (``results``, else the study's own output) stored, its notices given to ``notes``, moved to
    ``engine`` with that engine's numerics when one is named.

    Raises:
        SomoError: The study runs another task, or ``results`` is not a folder.
    """
    from somo_sweep.sweep.run.convergence import with_stored_step
    from somo_sweep.sweep.study import load_study

    if results is not None and not Path(results).is_dir():
        raise SomoError(f"--results {results}: no such results folder (give the folder the sweep ran into)")
    study = with_stored_step(load_study(study_path, results))
    if notes is not None:
        notes(study.notices)
    if study.task.name != "pinch_grasp":
        raise SomoError(f"{study_path}: render needs a pinch_grasp study, this one runs '{study.task.name}'")
    if engine is not None:
        from somo_sweep.sweep.views.compare_engines import on_engine

        study = on_engine(study, engine, study.output)
    return study


def render_trial(
    study_path: str | Path,
    trial: str,
    times_s: list[float],
    engine: str | None = None,
    notes: Callable[[Sequence[str]], None] | None = None,
    results: str | Path | None = None,
) -> TrialRender:
    """Rerun one trial of a pinch_grasp study as its sweep runs it, with a snapshot at each time.

    Args:
        study_path: The study file.
        trial: Its job id, or its 0-based index in the study's grid.
        times_s: Snapshot times, s.
        engine: Run the trial on this engine (``pybullet`` or ``mujoco``) with its numerics
            (:func:`~somo_sweep.sweep.views.compare_engines.on_engine`); None: the study's own.
        notes: Given the study's notices once it loads (before the trial runs).
        results: The results folder its sweep ran into, for the step it chose (None: the study's
            own output folder).

    Returns:
        The snapshots the trial reached, its status and its label.

    Raises:
        SomoError: A bad study, trial or time, or a snapshot that could not be taken.
    """
    from somo_sweep.sim.render import snapshot
    from somo_sweep.sim.world import World
    from somo_sweep.sweep.jobs.table import build_jobs
    from somo_sweep.sweep.run.trial import run_job
    from somo_sweep.tasks.pinch_grasp.gripper import fingers_colored
    from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams
    from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

    study = _study_to_render(study_path, engine, notes, results)
    job = find_trial(build_jobs(study).jobs, trial)
    params = job.params
    assert isinstance(params, PinchGraspParams)
    _check_times(times_s, params.duration_s)
    camera = _camera(params)
    images: dict[float, Any] = {}
    broken: list[Exception] = []

    def observe(world: World, time_s: float) -> None:
        try:
            images[time_s] = snapshot(world, camera)
        except Exception as exc:  # the renderer's failure, not the trial's: raised below
            broken.append(exc)
            raise

    def run(model: Any, p: Any, settings: Any, seed: int) -> Any:
        images.clear()  # a run that blew up leaves no snapshot: only its retry's are shown
        # Each finger in its own colour (no physics changes: the outcome is the trial's).
        painted = fingers_colored(model)
        return run_pinch_grasp(painted, p, settings, seed, observe=observe, observe_at_s=times_s)

    outcome = run_job(job, run)
    if broken:
        raise broken[0]
    return _rendered(study, job, outcome, images, times_s)


def _rendered(
    study: Study, job: Any, outcome: Any, images: dict[float, Any], times_s: list[float]
) -> TrialRender:
    """The render of a trial that ran: its snapshots named, its status, and its line (the step it
    ran at, the snapshots it missed)."""
    missed = _missed(times_s, images, outcome.time_step_used_s)
    step_chosen = not (study.simulation is None and study.auto_step_s is None)
    label = _trial_label(outcome, missed, job.settings.time_step_s, step_chosen)
    return TrialRender(_named(study.name, job.params, images), outcome.status, label)


def _camera(params: Any) -> Camera:
    """The camera of a trial's snapshots: above the point between the object and the finger mounts."""
    from somo_sweep.sim.render import Camera

    return Camera(
        target_m=(params.base_distance_m * 0.5, 0.0, params.hand_height_m),
        distance_m=RENDER_DISTANCE_M,
        width_px=RENDER_SIZE_PX[0],
        height_px=RENDER_SIZE_PX[1],
    )


def _missed(times_s: list[float], images: dict[float, Any], step_s: float) -> list[float]:
    """The times asked for (s) that no snapshot was taken at: the trial ended (or blew up) first.

    A snapshot is taken before the step nearest its time (``step_s``, s), so within a step of it.
    """
    return sorted({t for t in times_s if not any(abs(t - taken) <= step_s for taken in images)})


def _named(study_name: str, params: Any, images: dict[float, Any]) -> Artifacts:
    """The snapshots (time, s → image) as PNG files named by the study, the cell and the time."""
    dsr = params.distal_segment_ratio  # null: the finger's own split (no re-split)
    name = (
        f"{study_name}_dsr{'null' if dsr is None else f'{dsr:.2f}'}_w{params.object_width_m * 1e3:g}mm"
        f"_c{params.centering_position_m * 1e3:g}mm"
    )
    # Two decimals, or as many more as keep snapshots a step apart from sharing a file name.
    digits = next(d for d in range(2, 10) if len({f"{t:.{d}f}" for t in images}) == len(images))
    return Artifacts(images={f"{name}_t{t:.{digits}f}s.png": img for t, img in sorted(images.items())})
