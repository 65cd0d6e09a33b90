"""The gripper's geometry, engine-free: where N fingers sit on the palm, how far they reach, how wide
the open fingertips are apart, and how low the open hand reaches.

Frames (the palm's, as in ``studies/models/pinch_gripper.yaml``): x points away from the object
(the fingers point along −x toward it), y across the fingers, z up. A finger's chain runs along
its own +z and bends about its grasp axis (+x in its file). The straight ("open") hand is the
model as written: every joint at rest.

**Layout of N fingers** (:func:`finger_mounts`): the mounts sit on a circle of radius
:data:`MOUNT_RADIUS_M` about the palm's x axis, evenly spaced, finger k at the angle
θ_k = θ_0 + k·360°/N measured about +x from +y toward +z, where θ_0 = 90° for an odd N (the first
finger on top) and 90° − 180°/N for an even N (two fingers level with the palm's centre for N = 2,
the first at +y; a pair on top for 4): no finger points at the ground, and the lowest fingers are as
high as an even spacing allows. Each finger is the first one (``left`` of
the two-finger gripper: chain turned to −x, splayed :data:`SPLAY_DEG` outward, bending toward the
centre line) turned by θ_k about the palm's x axis, so every finger bends toward the palm's axis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from somo_sweep.model.load import Model
from somo_sweep.sim.rotations import matrix_from_quat, quat_from_rpy, quat_multiply, rpy_from_quat

__all__ = [
    "BASE_DISTANCE_AT_ZERO_CENTERING_M",
    "MOUNT_RADIUS_M",
    "OBJECT_HEIGHT_M",
    "PAPER_OBJECT_SPAN_M",
    "SPAWN_GAP_M",
    "SPLAY_DEG",
    "Mount",
    "check_reach",
    "finger_mounts",
    "finger_reach_m",
    "ground_problem",
    "lowest_point_m",
    "mount_radius_m",
    "palm_size_m",
    "span_problem",
]

#: c + d in the original study, m: the centering position c is 200 mm minus the finger bases'
#: distance d from the object's centre (its hand offset h in scaled units gives d = 100 + 50·h
#: and c = 100 − 50·h, in mm).
BASE_DISTANCE_AT_ZERO_CENTERING_M = 0.200
#: The box's height (z), m, and its gap above the ground at spawn, m.
OBJECT_HEIGHT_M = 0.060
#: The paper's objects across the fingers, m (every object of its grid: 60 mm; its objects' hulls).
PAPER_OBJECT_SPAN_M = 0.060
SPAWN_GAP_M = 0.0005
#: Centre of a finger's base box from the palm's axis, m (the mount, its back face, 25 mm from
#: the axis; the box 10 mm thick, splayed), and the box centre's x, m.
MOUNT_RADIUS_M = 0.0262941
MOUNT_X_M = -0.015
#: How far each finger is turned outward from the palm's axis, degrees (15°, written as the
#: bundled gripper writes it, to its last digit).
SPLAY_DEG = 15.0
_SPLAY_RAD = 0.2617993877499604
#: Least gap between neighbouring base boxes on the mount circle, m.
MOUNT_GAP_M = 0.004
#: The palm of the two-finger gripper (x, y, z), m.
PALM_TWO_M = (0.020, 0.090, 0.032)
#: The two-finger gripper's mounts as the bundled gripper writes them (the rule at θ = 0 and 180°).
_TWO_FINGERS = (
    ("left", (MOUNT_X_M, MOUNT_RADIUS_M, 0.0), (0.0, -math.pi / 2, -_SPLAY_RAD)),
    ("right", (MOUNT_X_M, -MOUNT_RADIUS_M, 0.0), (math.pi, math.pi / 2, _SPLAY_RAD)),
)


Vec = tuple[float, float, float]


@dataclass(frozen=True)
class Mount:
    """Where one finger sits on the palm.

    Attributes:
        name: The finger's name in the gripper.
        angle_deg: θ, its angle about the palm's x axis from +y toward +z, degrees.
        position_m: Centre of its base box in the palm's frame, m.
        rpy_rad: Its roll, pitch, yaw in the palm's frame (extrinsic x, y, z), rad.
    """

    name: str
    angle_deg: float
    position_m: tuple[float, float, float]
    rpy_rad: tuple[float, float, float]


def mount_radius_m(n_fingers: int, base_half_width_m: float) -> float:
    """The mount circle's radius for ``n_fingers`` whose base boxes are ``base_half_width_m`` wide
    (half their larger side), m: :data:`MOUNT_RADIUS_M`, or more where neighbouring base boxes
    would come closer than :data:`MOUNT_GAP_M` (five fingers of 30-mm boxes and more)."""
    if n_fingers == 2:
        return MOUNT_RADIUS_M
    needed = (base_half_width_m + MOUNT_GAP_M / 2) / math.sin(math.pi / n_fingers)
    return max(MOUNT_RADIUS_M, math.ceil(needed * 1e4) / 1e4)


def finger_mounts(n_fingers: int, radius_m: float = MOUNT_RADIUS_M) -> list[Mount]:
    """The mounts of ``n_fingers`` (≥ 2) evenly around the palm's axis (see the module docstring).

    Two fingers are ``left`` and ``right`` (the bundled gripper's frames exactly); three or more
    are ``finger1`` … ``fingerN`` in the order of their angles, their base boxes' centres
    ``radius_m`` from the palm's axis.

    Raises:
        ValueError: Fewer than two fingers.
    """
    if n_fingers < 2:
        raise ValueError(f"a gripper needs two or more fingers, got {n_fingers}")
    first = math.pi / 2 - (math.pi / n_fingers if n_fingers % 2 == 0 else 0.0)
    angles = [first + 2 * math.pi * k / n_fingers for k in range(n_fingers)]
    if n_fingers == 2:
        return [Mount(n, math.degrees(a), p, r) for (n, p, r), a in zip(_TWO_FINGERS, angles, strict=True)]
    q0 = quat_from_rpy(_TWO_FINGERS[0][2])
    mounts = []
    for k, angle in enumerate(angles, start=1):
        about_x = (math.sin(angle / 2), 0.0, 0.0, math.cos(angle / 2))
        roll, pitch, yaw = (_clean(a) for a in rpy_from_quat(quat_multiply(about_x, q0)))
        y, z = _clean(radius_m * math.cos(angle)), _clean(radius_m * math.sin(angle))
        mounts.append(Mount(f"finger{k}", math.degrees(angle), (MOUNT_X_M, y, z), (roll, pitch, yaw)))
    return mounts


def _clean(value: float) -> float:
    """``value`` with float noise below 1e-12 taken to 0 (so a file reads 0.0, not 1.6e-18)."""
    return 0.0 if abs(value) < 1e-12 else float(value)


def palm_size_m(n_fingers: int, radius_m: float = MOUNT_RADIUS_M, base_half_width_m: float = 0.015) -> Vec:
    """The palm box of a gripper of ``n_fingers`` (x, y, z), m: the two-finger gripper's 90 × 32 mm,
    or for three or more a square that holds every base box (mounts ``radius_m`` from the axis,
    base boxes ``base_half_width_m`` wide, half their larger side), at least 90 mm."""
    if n_fingers == 2:
        return PALM_TWO_M
    side = max(PALM_TWO_M[1], 2 * math.ceil((radius_m + base_half_width_m * math.sqrt(2)) * 1e3) / 1e3)
    return (PALM_TWO_M[0], side, side)


def _fingers(model: Model) -> list[tuple[str, Any, Any]]:
    """(name, manipulator, pose) of each finger of the model's gripper."""
    return [(m.name, m.manipulator, m.pose) for m in model.as_assembly().manipulators]


class _Box(NamedTuple):
    """A piece of a straight finger along its own +z, m: half extents across, and where it spans."""

    half_x_m: float
    half_y_m: float
    z_from_m: float
    z_to_m: float


def _boxes(finger: Any) -> tuple[list[_Box], list[_Box]]:
    """The straight finger as boxes along its own +z: its base box (centred at the finger's origin)
    and each actuator's links, and its tip links."""
    chain, tips = [], []
    z = 0.0
    if finger.base.link is not None:
        link = finger.base.link
        z = link.half_extent_m(2)
        chain.append(_Box(link.half_extent_m(0), link.half_extent_m(1), -z, z))
    for act in finger.actuators:
        end = z + act.segments * act.segment_m
        chain.append(_Box(act.link.half_extent_m(0), act.link.half_extent_m(1), z, end))
        z = end
    for tip in finger.tip_links:
        end = z + 2 * tip.half_extent_m(2)
        tips.append(_Box(tip.half_extent_m(0), tip.half_extent_m(1), z, end))
        z = end
    return chain, tips


def _corners_m(finger: Any, pose: Any, tips_only: bool = False) -> np.ndarray:
    """Corners of the straight finger's boxes in the palm's frame (rows x, y, z), m; ``tips_only``:
    the fingertip, the chain's far face and the tip links."""
    rotation = matrix_from_quat(quat_from_rpy(pose.rpy_rad))
    chain, tips = _boxes(finger)
    last = chain[-1]
    boxes = [last._replace(z_from_m=last.z_to_m), *tips] if tips_only else [*chain, *tips]
    local = [
        (sx * box.half_x_m, sy * box.half_y_m, z)
        for box in boxes
        for z in (box.z_from_m, box.z_to_m)
        for sx in (-1, 1)
        for sy in (-1, 1)
    ]
    return np.asarray(local) @ rotation.T + np.asarray(pose.position_m)


def lowest_point_m(model: Model) -> float:
    """How far the open hand (palm, base boxes, straight fingers and tips) reaches below the palm's
    centre, m (positive: below it)."""
    hand = model.as_assembly()
    lows = [float(-_corners_m(f, pose)[:, 2].min()) for _, f, pose in _fingers(model)]
    if hand.base.link is not None:
        lows.append(hand.base.link.half_extent_m(2))
    return max(lows)


def ground_problem(model: Model, hand_height_m: float) -> str | None:
    """Why the open hand would be in the ground at ``hand_height_m`` (the palm's centre above it,
    m), or None when it clears the ground."""
    low = lowest_point_m(model)
    if low < hand_height_m:
        return None
    return (
        f"task.hand_height_m {hand_height_m:g} puts the open hand {(low - hand_height_m) * 1e3:.1f} mm into "
        f"the ground (its lowest point, palm, base boxes or straight fingers, is {low * 1e3:.1f} mm below "
        f"the palm's centre); allowed: hand_height_m above {low:.4f}"
    )


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted({(round(float(x), 12), round(float(y), 12)) for x, y in points})
    if len(pts) < 3:
        return np.asarray(pts)

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and _cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.asarray(half(pts) + half(pts[::-1]))


def _cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _overlap_m(polygon: np.ndarray, low: np.ndarray, high: np.ndarray) -> float:
    """How deep a convex polygon (y, z rows) and the rectangle [low, high] overlap, m (the least
    push apart along their edge normals; 0 or less: apart)."""
    rect = np.array([low, (high[0], low[1]), high, (low[0], high[1])])
    axes = [np.array([1.0, 0.0]), np.array([0.0, 1.0])]
    edges = np.roll(polygon, -1, axis=0) - polygon
    axes += [np.array([-e[1], e[0]]) / np.linalg.norm(e) for e in edges if np.linalg.norm(e) > 1e-12]
    depth = math.inf
    for axis in axes:
        a, b = polygon @ axis, rect @ axis
        depth = min(depth, min(a.max(), b.max()) - max(a.min(), b.min()))
    return depth


def _tips_yz(model: Model) -> list[tuple[str, np.ndarray]]:
    """Each finger's open fingertip (chain end and tip links) seen along x, as a convex polygon
    in the palm's (y, z), m."""
    return [(name, _hull(_corners_m(f, pose, tips_only=True)[:, 1:])) for name, f, pose in _fingers(model)]


def _blocking(tips: list[tuple[str, np.ndarray]], span_m: float, hand_height_m: float) -> tuple[str, float]:
    """The fingertip the box meets deepest (name, depth in m; depth ≤ 0: it passes every one)."""
    bottom = SPAWN_GAP_M - hand_height_m
    low, high = np.array([-span_m / 2, bottom]), np.array([span_m / 2, bottom + OBJECT_HEIGHT_M])
    return max(((name, _overlap_m(tip, low, high)) for name, tip in tips), key=lambda t: t[1])


def span_problem(model: Model, object_span_m: float, hand_height_m: float) -> str | None:
    """Why a box of ``object_span_m`` across the fingers (y; 60 mm tall, on the ground) cannot pass
    between the open fingertips of the gripper held with its palm's centre ``hand_height_m`` above
    the ground, or None when it can.

    The hand approaches along x, so the box passes the fingertips if, seen along x, its cross
    section and each open fingertip (the straight chain's far end and its tip links) are apart.
    A box that passes the fingertips but not the fingers' roots is a valid trial (pushed into the
    hand, as in the paper's deepest cells); one that cannot pass the fingertips never is.
    """
    tips = _tips_yz(model)
    name, depth = _blocking(tips, object_span_m, hand_height_m)
    if depth <= 0:
        return None
    if _blocking(tips, 1e-6, hand_height_m)[1] > 0:
        return (
            f"task.hand_height_m {hand_height_m:g}: the box ({OBJECT_HEIGHT_M * 1e3:g} mm tall) meets the "
            f"open fingertip of finger '{name}' whatever its object_span_m; allowed: a hand_height_m that "
            "puts the fingertips clear of the box's top"
        )
    fits, meets = 0.0, object_span_m
    for _ in range(40):  # the widest box that passes, to 0.1 µm
        mid = (fits + meets) / 2
        fits, meets = (mid, meets) if _blocking(tips, mid, hand_height_m)[1] <= 0 else (fits, mid)
    return (
        f"task.object_span_m {object_span_m:g}: the box (its size across the fingers) does not pass between "
        f"the open fingertips: it meets the fingertip of finger '{name}' {depth * 1e3:.1f} mm deep (at "
        f"hand_height_m {hand_height_m:g}); allowed: object_span_m below {fits:.4f} for this gripper"
    )


def finger_reach_m(finger: Any) -> float:
    """How far a finger can reach from its mount, m: base box, chain and tip links end to end (an
    upper bound: the straight finger, as if it pointed at the box)."""
    base = finger.base.link.half_extent_m(2) * 2 if finger.base.link is not None else 0.0
    return base + finger.length_m + sum(tip.half_extent_m(2) * 2 for tip in finger.tip_links)


def check_reach(model: Model, param_sets: Sequence[Any]) -> list[str]:
    """A gripper whose fingers reach the box in none of the study's cells: the straight fingers
    end short of the box's near face (d − width/2 from the mounts) everywhere. A cell out of reach
    is a valid result (no grasp, as in the paper's grid); a study of only such cells is not."""
    if not param_sets:
        return []
    reach = max(finger_reach_m(f) for _, f, _ in _fingers(model))
    gaps = [(p.base_distance_m - p.object_width_m / 2 - reach, p) for p in param_sets]
    gap, nearest = min(gaps, key=lambda g: g[0])
    if gap <= 0:
        return []
    least_c = BASE_DISTANCE_AT_ZERO_CENTERING_M - reach - nearest.object_width_m / 2
    return [
        f"the fingers reach at most {reach * 1e3:.1f} mm from their mounts (base box, chain and tips "
        f"straight), and no cell brings the box that close: the nearest, centering_position_m "
        f"{nearest.centering_position_m:g} with object_width_m {nearest.object_width_m:g}, leaves its near "
        f"face {gap * 1e3:.1f} mm beyond the fingertips; allowed: centering_position_m of at least "
        f"{least_c:.3f} for that width, or longer fingers"
    ]
