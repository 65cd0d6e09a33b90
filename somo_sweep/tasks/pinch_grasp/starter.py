"""A grasp study to start from: finger, gripper, bench CSV template, study and design study, as text.

``somo-sweep new grasp-study DIR`` writes these files (the command line alone writes);
here they are built from the bundled templates (``somo_sweep/data/starters/grasp_study``),
with a finger of the user's (``--finger``) or the template's 12-link, 70-mm finger, on a
gripper of two or more of them (``--fingers``). The study's distal segment ratios are ones the
finger's link count can express and its centering positions follow the finger's reach; the
bench template's ``# finger:`` line describes the finger.

Layout (:mod:`somo_sweep.tasks.pinch_grasp.geometry`): two fingers sit as in the bundled
gripper; three or more sit evenly around the palm's axis on the smallest circle (from the
two-finger gripper's) that keeps their base boxes apart and lets the default 60-mm box pass
between the open fingertips with :data:`SPAN_CLEARANCE_M` to spare on each side; the palm is
a square as wide as that circle, and the study holds the palm's centre :data:`GROUND_CLEARANCE_M`
higher than the open hand's lowest point (or at the task's 35 mm).

Every file is checked before anything is written, with the checks ``somo-sweep run`` makes:
the gripper against the task's needs, each of the study's trials against the gripper (ratios,
pressure gain, the open hand's clearance of the ground and of the box), and the gripper as the
trial simulates it against MuJoCo's, the starter's engine.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from string import Template
from typing import Any

import yaml

from somo_sweep.errors import SomoError
from somo_sweep.model.load import Model, load_model, model_from_dict
from somo_sweep.model.manipulators import Manipulator
from somo_sweep.model.tables import bundled_if_missing, bundled_path
from somo_sweep.tasks.pinch_grasp.checks import check_gripper, check_trial
from somo_sweep.tasks.pinch_grasp.geometry import (
    BASE_DISTANCE_AT_ZERO_CENTERING_M,
    finger_mounts,
    lowest_point_m,
    mount_radius_m,
    palm_size_m,
    span_problem,
)
from somo_sweep.tasks.pinch_grasp.gripper import gripper
from somo_sweep.tasks.pinch_grasp.params import PAPER_OBJECT_SPAN_M, PinchGraspParams

__all__ = ["MAX_FINGERS", "STARTER_FILES", "grasp_study_files"]

#: The files a grasp-study starter holds, in the order they are written.
STARTER_FILES = ("finger.yaml", "gripper.yaml", "bench.csv", "study.yaml", "design.yaml")
#: Most fingers a starter's gripper may have.
MAX_FINGERS = 8
#: The centering positions put the box's centre between these multiples of the finger's reach
#: (base box plus chain) from the mounts, m/m; and never closer than this to the mounts, m.
FAR_REACHES, NEAR_REACHES, NEAREST_M = 1.1, 0.4, 0.025
#: The starter study's closing pressure, kPa.
PRESSURE_KPA = 150
#: Room the default box leaves to each open fingertip (three or more fingers), m; and the open
#: hand's lowest point above the ground, m.
SPAN_CLEARANCE_M = 0.005
GROUND_CLEARANCE_M = 0.005
#: The task's default hand height, m (the study sets it only when the hand needs more).
DEFAULT_HAND_HEIGHT_M = 0.035
#: The palm's mass, kg (the hand is driven along its path: it does not move the trial).
PALM_KG = 0.2
#: Steps of the mount circle's search, m, and its largest radius, m.
RADIUS_STEP_M, MAX_RADIUS_M = 0.0005, 0.100


@dataclass(frozen=True)
class _Finger:
    """What the templates need to know of the finger (SI)."""

    n_links: int
    length_m: float
    mass_kg: float
    width_m: float
    thickness_m: float
    base_m: float
    base_half_width_m: float


@dataclass(frozen=True)
class _Layout:
    """Where the fingers go: the mount circle's radius, m, the palm (x, y, z), m, and the palm's
    centre above the ground, m."""

    radius_m: float
    palm_m: tuple[float, float, float]
    hand_height_m: float


def _template(name: str) -> str:
    return bundled_path("starters", "grasp_study", name).read_text(encoding="utf-8")


def _described(finger: Manipulator) -> _Finger:
    links = [(a.segments, a.link) for a in finger.actuators]
    n_links = sum(n for n, _ in links)
    first = finger.actuators[0].link
    box = first.shape == "box" and len(first.size_m or ()) >= 2
    size = first.size_m or (0.020, 0.015)
    base = finger.base.link
    return _Finger(
        n_links=n_links,
        length_m=finger.length_m,
        mass_kg=sum(n * link.mass_kg for n, link in links),
        width_m=size[0] if box else 0.020,
        thickness_m=size[1] if box else 0.015,
        base_m=base.half_extent_m(2) * 2 if base is not None else 0.0,
        base_half_width_m=max(base.half_extent_m(0), base.half_extent_m(1)) if base is not None else 0.0,
    )


def _dsr_values(n_links: int) -> list[float]:
    """0, about a quarter and about a half of the finger, as whole links."""
    return [k / n_links for k in sorted({0, round(n_links / 4), round(n_links / 2)})]


def _centering(f: _Finger) -> tuple[float, float, float]:
    """Start, stop and step of the centering positions (m): 5 values over the finger's reach."""
    reach = f.base_m + f.length_m
    far = min(FAR_REACHES * reach, BASE_DISTANCE_AT_ZERO_CENTERING_M - 0.005)
    near = max(NEAR_REACHES * reach, NEAREST_M)
    step = round((far - near) / 4, 3)
    start = round(BASE_DISTANCE_AT_ZERO_CENTERING_M - near - 4 * step, 3)
    return start, round(start + 4 * step, 3), step


def _gripper_data(n_fingers: int, layout: _Layout) -> dict[str, Any]:
    """The starter's gripper as data: the fingers by reference (``file: finger.yaml``)."""
    mounts = finger_mounts(n_fingers, layout.radius_m)
    palm = {"shape": "box", "size_m": list(layout.palm_m), "mass_kg": PALM_KG}
    return {
        "assembly": {
            "name": "my_gripper",
            "base": {"mode": "driven", "link": palm},
            "manipulators": [
                {
                    "name": m.name,
                    "file": "finger.yaml",
                    "pose": {"position_m": list(m.position_m), "rpy_rad": list(m.rpy_rad)},
                }
                for m in mounts
            ],
        }
    }


def _gripper_model(data: dict[str, Any], finger: Model) -> Model:
    """The gripper with the finger in place of its ``file:`` references."""
    finger_dict = finger.model_dump(mode="json", exclude_unset=True)["manipulator"]
    assembly = dict(data["assembly"])
    assembly["manipulators"] = [
        {k: v for k, v in m.items() if k != "file"} | {"manipulator": finger_dict}
        for m in assembly["manipulators"]
    ]
    return model_from_dict({"assembly": assembly}, "gripper.yaml")


def _layout(n_fingers: int, finger: Model, f: _Finger) -> _Layout:
    """The two-finger gripper's frames, or for three or more the smallest mount circle that lets the
    default box pass the open fingertips with room to spare (see the module docstring)."""
    if n_fingers == 2:
        return _Layout(mount_radius_m(2, f.base_half_width_m), palm_size_m(2), DEFAULT_HAND_HEIGHT_M)
    least = mount_radius_m(n_fingers, f.base_half_width_m)
    steps = math.ceil((MAX_RADIUS_M - least) / RADIUS_STEP_M)
    first: _Layout | None = None
    above = [(math.floor(least / RADIUS_STEP_M) + i) * RADIUS_STEP_M for i in range(1, steps)]
    for radius in [least, *(round(r, 7) for r in above)]:
        side = 2 * math.ceil(radius * 1e3) / 1e3
        trial = _Layout(radius, (palm_size_m(2)[0], side, side), DEFAULT_HAND_HEIGHT_M)
        model = _gripper_model(_gripper_data(n_fingers, trial), finger)
        low = math.ceil((lowest_point_m(model) + GROUND_CLEARANCE_M) * 1e3) / 1e3
        trial = _Layout(radius, trial.palm_m, max(DEFAULT_HAND_HEIGHT_M, low))
        first = first or trial
        if span_problem(model, PAPER_OBJECT_SPAN_M + 2 * SPAN_CLEARANCE_M, trial.hand_height_m) is None:
            return trial
    assert first is not None
    return first  # no circle fits: the study's checks say why, and the starter is refused


def _finger_text(path: Path | None, given: str | None) -> str:
    """finger.yaml's text: marked as somo-sweep's (so ``calibrate -o finger.yaml`` may replace it in
    place), then the user's file as written (a finger refers to no other file: only an assembly's
    mounts do), or the template's."""
    mark = (
        f"# Written by somo-sweep new grasp-study{f' from {given}' if given else ''}. Calibrate it in place "
        "(stiffness and\n# pressure gain fitted, the rest kept): "
        "somo-sweep calibrate bench.csv --model finger.yaml -o finger.yaml\n"
    )
    return mark + (_template("finger.yaml") if path is None else path.read_text(encoding="utf-8"))


def _load_finger(finger_path: Path | None) -> tuple[Model, Path | None]:
    """The finger (the template's without a path; a bundled model's name works) and its file.

    Raises:
        DescriptionError: The file does not load.
        SomoError: It is not one manipulator.
    """
    if finger_path is None:
        return model_from_dict(yaml.safe_load(_template("finger.yaml")), "finger.yaml"), None
    finger = load_model(finger_path)  # a bundled model's name too, as the docs spell them
    if finger.manipulator is None:
        raise SomoError(
            f"{finger_path}: a grasp study's finger is a model file of one manipulator; "
            "got an assembly; allowed: a file with a top-level 'manipulator:'"
        )
    return finger, bundled_if_missing(finger_path, "models")


def _refusals(
    hand: Model, params: list[PinchGraspParams], engine_needs: Callable[[Model], list[str]] | None
) -> list[str]:
    """What ``somo-sweep run`` would refuse of the starter: the task's checks of the gripper and of
    each trial, and what the engine cannot express of the gripper as the trial simulates it."""
    needs = check_gripper(hand)
    for p in params if not needs else []:
        needs += [n for n in check_trial(hand, p) if n not in needs]
    if not needs and engine_needs is not None:  # the gripper as the trial re-splits it
        needs += engine_needs(gripper(hand, params[0]))
    return needs


def grasp_study_files(
    finger_path: Path | None = None,
    n_fingers: int = 2,
    engine_needs: Callable[[Model], list[str]] | None = None,
) -> dict[str, str]:
    """The starter's files by name (:data:`STARTER_FILES`), built for a finger.

    Args:
        finger_path: A model file of one manipulator (a finger as designed or as calibrated; a
            bundled model's name works too); None: the template's 12-link, 70-mm finger.
        n_fingers: Fingers of the gripper, 2 … :data:`MAX_FINGERS`.
        engine_needs: What the study's engine (MuJoCo) cannot express of a model, one sentence
            each (the check a MuJoCo study's loading makes; a task may not import an engine).

    Raises:
        DescriptionError: The finger file does not load.
        SomoError: A finger count out of range, a file that is not one finger, or a starter that
            ``somo-sweep run`` would refuse (every reason at once, as ``run`` words them).
    """
    if not 2 <= n_fingers <= MAX_FINGERS:
        raise SomoError(
            f"--fingers {n_fingers}: allowed: 2 to {MAX_FINGERS} (a gripper holds two fingers or more; the "
            f"starter lays out up to {MAX_FINGERS})"
        )
    finger, path = _load_finger(finger_path)
    assert finger.manipulator is not None
    f = _described(finger.manipulator)
    layout = _layout(n_fingers, finger, f)
    hand = _gripper_model(_gripper_data(n_fingers, layout), finger)
    dsr = _dsr_values(f.n_links)
    height = {} if n_fingers == 2 else {"hand_height_m": layout.hand_height_m}
    params = [PinchGraspParams(distal_segment_ratio=r, pressure_kpa=PRESSURE_KPA, **height) for r in dsr]
    needs = _refusals(hand, params, engine_needs)
    if needs:
        where = finger_path or "finger.yaml"
        raise SomoError(
            f"{where}: a gripper of {n_fingers} of these fingers would be refused by `somo-sweep run`: "
            + "; ".join(needs)
        )
    return {
        "finger.yaml": _finger_text(path, str(finger_path) if finger_path else None),
        "gripper.yaml": _gripper_text(n_fingers, layout),
        "bench.csv": Template(_template("bench.csv")).substitute(_fields(f, n_fingers, layout)),
        "study.yaml": Template(_template("study.yaml")).substitute(_fields(f, n_fingers, layout)),
        "design.yaml": Template(_template("design.yaml")).substitute(_fields(f, n_fingers, layout)),
    }


def _fields(f: _Finger, n_fingers: int, layout: _Layout) -> dict[str, Any]:
    """The templates' placeholders."""
    start, stop, step = _centering(f)
    height = ""
    if n_fingers > 2:
        height = (
            "  # The palm's centre this high above the ground, m: the open hand (palm, base boxes,\n"
            f"  # straight fingers) clears the ground by {GROUND_CLEARANCE_M * 1e3:g} mm.\n"
            f"  hand_height_m: {layout.hand_height_m:.3f}\n"
        )
    return {
        "n_links": f.n_links,
        "pressure_kpa": PRESSURE_KPA,
        "n_fingers": n_fingers,
        "dsr_values": ", ".join(f"{r:.12g}" for r in _dsr_values(f.n_links)),
        "hand_height": height,
        "c_start": f"{start:.3f}",
        "c_stop": f"{stop:.3f}",
        "c_step": f"{step:.3f}",
        "length_mm": f"{f.length_m * 1e3:.4g}",
        "mass_g": f"{f.mass_kg * 1e3:.4g}",
        "width_mm": f"{f.width_m * 1e3:.4g}",
        "thickness_mm": f"{f.thickness_m * 1e3:.4g}",
    }


def _gripper_text(n_fingers: int, layout: _Layout) -> str:
    """gripper.yaml: the template's comments, then the palm and each finger's mount."""
    data = _gripper_data(n_fingers, layout)["assembly"]
    mounts = "\n".join(
        f"    - name: {m['name']}\n      file: finger.yaml\n      pose: {{position_m: "
        f"{_list(m['pose']['position_m'])}, rpy_rad: {_list(m['pose']['rpy_rad'])}}}"
        for m in data["manipulators"]
    )
    first = finger_mounts(n_fingers, layout.radius_m)[0].angle_deg
    if n_fingers == 2:
        layout_note = (
            "The left pose below turns the finger's +z\n# to -x, splays it 15 degrees outward and "
            "turns its bending toward the centre line; the\n# right finger is the left one turned "
            "half a turn about the palm's x axis."
        )
    else:
        layout_note = (
            "Finger 1 below is the two-finger gripper's\n# left finger (its +z turned to -x, splayed "
            "15 degrees outward, bending toward the palm's\n# axis) turned "
            f"{first:g} degrees about the palm's x axis (from +y toward +z: 90 is on top); finger\n"
            f"# k is turned {first:g} + {360 / n_fingers:g} (k - 1) degrees, its base box centred "
            f"{layout.radius_m * 1e3:g} mm from the axis,\n# so every finger bends toward the palm's axis."
        )
    fields = {
        "n_fingers": n_fingers,
        "layout": layout_note,
        "palm": _list(data["base"]["link"]["size_m"]),
        "mounts": mounts,
    }
    return Template(_template("gripper.yaml")).substitute(fields)


def _list(values: list[float]) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"
