"""The original code's choices, kept to reproduce its study: the ``original:`` block of the
pinch-grasp parameters (``task.original.<name>``).

Each default is our physical model, so a study that leaves the block out simulates ours. The
original study's configuration (``studies/pinch_grasp_dsr_original.yaml``, docs/paper_figures.md)
sets them together; the Fig. 6 ablation (``studies/pinch_grasp_ablation.yaml``) toggles them one
at a time. The original's doubled springs are no setting of this block: they are the designer's
``spring_scale`` at 2.

These parameters were once top-level parameters of the task; a study giving one by its old name
(``task.restitution``, ``params: {object_shape: …}``) is read at its new place, with a notice
(:data:`MOVED`, :mod:`somo_sweep.sweep.study.moved`).
"""

from __future__ import annotations

from itertools import pairwise
from typing import ClassVar, Literal

from pydantic import Field, field_validator

from somo_sweep.tasks.pinch_grasp.geometry import PAPER_OBJECT_SPAN_M
from somo_sweep.tasks.registry import TaskParams

__all__ = ["MOVED", "ORIGINAL_HULL_SIZE_M", "Original", "hull_problem", "original_hull_size_m"]

#: The original study's object collision shapes (its cube_60mm set: a V-HACD convex hull of each
#: box mesh, 8-10 vertices), as boxes of the hulls' extents (x along the approach, y across the
#: fingers, z up), m, by nominal width. Each is 0.3-1.1 mm larger than the nominal box, and its
#: centre lies within 0.2 mm of the mass centre; the 40-mm hull's 0.5-mm bevel on one edge is left out.
ORIGINAL_HULL_SIZE_M: dict[float, tuple[float, float, float]] = {
    0.010: (0.010449, 0.060336, 0.060331),
    0.020: (0.020559, 0.060420, 0.060420),
    0.040: (0.040354, 0.060531, 0.060525),
    0.060: (0.060606, 0.060606, 0.060606),
    0.080: (0.080667, 0.060667, 0.060667),
    0.100: (0.100714, 0.060708, 0.060714),
    0.120: (0.120764, 0.061146, 0.061146),
}


def original_hull_size_m(width_m: float) -> tuple[float, float, float] | None:
    """The original's hull extents for a nominal object width (m), or None if it had no such object."""
    for nominal, size in ORIGINAL_HULL_SIZE_M.items():
        if abs(width_m - nominal) < 1e-9:
            return size
    return None


class Original(TaskParams):
    """The original code's choices (``task.original.<name>``); every default is our physical model.

    Attributes:
        finger_spinning_friction_m: Spinning (torsional) friction of every finger link and
            fingertip, m (Bullet's spinning friction as a length). ``None`` keeps the model
            file's (0.004 m in the bundled finger: a ~3-mm contact patch); 0 gives the
            original's point contacts. A designer sets a finger's own in its model file
            (``friction.spinning`` of its links).
        restitution: Restitution of the object, the finger links and the fingertips (Bullet
            multiplies a pair's values; the ground and the base boxes keep theirs). ``None``
            keeps the model file's on the fingers (0 in the bundled finger) and 0 on the object;
            the original's 1.0 throws the object out of most grasps.
        lift_profile: Breakpoints of the lift inside its phase, as (fraction of ``lift_s``,
            fraction of ``lift_m``) pairs, joined linearly from (0, 0) to (1, 1). Empty: one
            straight ramp (ours). The original's: ((0.2, 1/15), (0.8, 14/15)), 5 mm in the first
            and the last 0.2 s and 65 mm between (its hand_side_position trajectory).
        object_shape: ``box`` (the nominal box, ours) or ``original_hull``: a box of the extents
            of the original's convex-hull collision shape for that width
            (:data:`ORIGINAL_HULL_SIZE_M`, 0.3-1.1 mm larger), same mass.
        clamp_speed_cap: Let the trial go on at Bullet's speed cap, as the original code did
            (:attr:`~somo_sweep.sim.settings.WorldSettings.clamp_speed_cap`); False stops it
            as unstable. At 0.5 ms without inertia shaping a finger snapping shut after the
            object fell out reaches the cap.
    """

    listed_apart: ClassVar[bool] = True

    finger_spinning_friction_m: float | None = Field(None, ge=0)
    restitution: float | None = Field(None, ge=0, le=1)
    lift_profile: tuple[tuple[float, float], ...] = ()
    object_shape: Literal["box", "original_hull"] = "box"
    clamp_speed_cap: bool = False

    @field_validator("lift_profile")
    @classmethod
    def _lift_profile_rises(cls, v: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
        times = [0.0, *(t for t, _ in v), 1.0]
        if any(b <= a for a, b in pairwise(times)):
            raise ValueError(
                "lift_profile times (fractions of lift_s) must rise strictly inside (0, 1), "
                f"got {list(times[1:-1])}"
            )
        if any(not (0.0 <= h <= 1.0) for _, h in v):
            raise ValueError(
                f"lift_profile heights are fractions of lift_m in [0, 1], got {[h for _, h in v]}"
            )
        return v


#: Old parameter name → its place today (key paths under ``task.``).
MOVED: dict[str, str] = {name: f"original.{name}" for name in Original.model_fields}


def hull_problem(original: Original, object_width_m: float, object_span_m: float) -> str | None:
    """Why the original's hull cannot stand for a box of this width and span (m); None if it can
    (or the block asks for the nominal box)."""
    if original.object_shape != "original_hull":
        return None
    if object_span_m != PAPER_OBJECT_SPAN_M:
        return (
            "original.object_shape 'original_hull' is the original's objects, "
            f"{PAPER_OBJECT_SPAN_M:g} m across the fingers; got object_span_m {object_span_m:g}; "
            f"allowed: {PAPER_OBJECT_SPAN_M:g}, "
            "or original.object_shape 'box'"
        )
    if original_hull_size_m(object_width_m) is None:
        widths = ", ".join(f"{w:g}" for w in ORIGINAL_HULL_SIZE_M)
        return (
            f"original.object_shape 'original_hull' exists for the original's object widths only; got "
            f"object_width_m {object_width_m:g}; allowed: {widths}"
        )
    return None
