"""A grasp study to start from: finger, gripper, bench CSV template and study, as text.

``somo-sweep new grasp-study DIR`` writes these files (the command line alone writes);
here they are built from the bundled templates (``somo_sweep/data/starters/grasp_study``),
with a finger of the user's (``--finger``) or the template's 12-link, 70-mm finger. The
study's distal segment ratios are ones the finger's link count can express and its centering
positions follow the finger's reach; the bench template's ``# finger:`` line describes the
finger. Every file is checked before anything is written: the gripper against the task's
needs, the study's ratios against the finger.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from string import Template
from typing import Any

import yaml

from somo_sweep.errors import SomoError
from somo_sweep.model.load import Model, load_model, model_from_dict
from somo_sweep.model.manipulators import Manipulator
from somo_sweep.model.tables import bundled_path
from somo_sweep.tasks.pinch_grasp.params import BASE_DISTANCE_AT_ZERO_CENTERING_M, check_gripper

__all__ = ["STARTER_FILES", "grasp_study_files"]

#: The files a grasp-study starter holds, in the order they are written.
STARTER_FILES = ("finger.yaml", "gripper.yaml", "bench.csv", "study.yaml")
#: The centering positions put the box's centre between these multiples of the finger's reach
#: (base box plus chain) from the mounts, m/m; and never closer than this to the mounts, m.
FAR_REACHES, NEAR_REACHES, NEAREST_M = 1.1, 0.4, 0.025


@dataclass(frozen=True)
class _Finger:
    """What the templates need to know of the finger (SI)."""

    n_links: int
    length_m: float
    mass_kg: float
    width_m: float
    thickness_m: float
    base_m: float


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
    )


def _dsr_values(n_links: int) -> str:
    """0, about a quarter and about a half of the finger as whole links, as the study writes them."""
    counts = sorted({0, round(n_links / 4), round(n_links / 2)})
    return ", ".join(f"{k / n_links:.12g}" for k in counts)


def _centering(f: _Finger) -> tuple[float, float, float]:
    """Start, stop and step of the centering positions (m): 5 values over the finger's reach."""
    reach = f.base_m + f.length_m
    far = min(FAR_REACHES * reach, BASE_DISTANCE_AT_ZERO_CENTERING_M - 0.005)
    near = max(NEAR_REACHES * reach, NEAREST_M)
    step = round((far - near) / 4, 3)
    start = round(BASE_DISTANCE_AT_ZERO_CENTERING_M - near - 4 * step, 3)
    return start, round(start + 4 * step, 3), step


def _gripper_model(gripper_text: str, finger: Model) -> Model:
    """The starter's gripper with the finger in place of its ``file:`` references."""
    data = yaml.safe_load(gripper_text)
    finger_dict = finger.model_dump(mode="json", exclude_unset=True)["manipulator"]
    for mount in data["assembly"]["manipulators"]:
        del mount["file"]
        mount["manipulator"] = copy.deepcopy(finger_dict)
    return model_from_dict(data, "gripper.yaml")


def grasp_study_files(finger_path: Path | None = None) -> dict[str, str]:
    """The starter's files by name (:data:`STARTER_FILES`), built for a finger.

    Args:
        finger_path: A model file of one manipulator (a finger as designed or as calibrated);
            None: the template's 12-link, 70-mm finger.

    Raises:
        DescriptionError: The finger file does not load.
        SomoError: The file is not one finger, or a gripper of two of them is not one the
            grasp task can simulate (every reason at once).
    """
    if finger_path is None:
        finger_text = _template("finger.yaml")
        finger = model_from_dict(yaml.safe_load(finger_text), "finger.yaml")
    else:
        finger = load_model(finger_path, bundled=False)
        finger_text = Path(finger_path).read_text(encoding="utf-8")
        if finger.manipulator is None:
            raise SomoError(
                f"{finger_path}: a grasp study's finger is a model file of one manipulator; "
                "got an assembly; allowed: a file with a top-level 'manipulator:'"
            )
    gripper_text = _template("gripper.yaml")
    needs = check_gripper(_gripper_model(gripper_text, finger))
    if needs:
        where = finger_path or "finger.yaml"
        raise SomoError(f"{where}: a gripper of two of these fingers cannot grasp: " + "; ".join(needs))
    assert finger.manipulator is not None
    f = _described(finger.manipulator)
    start, stop, step = _centering(f)
    fields: dict[str, Any] = {
        "n_links": f.n_links,
        "dsr_values": _dsr_values(f.n_links),
        "c_start": f"{start:.3f}",
        "c_stop": f"{stop:.3f}",
        "c_step": f"{step:.3f}",
        "length_mm": f"{f.length_m * 1e3:.4g}",
        "mass_g": f"{f.mass_kg * 1e3:.4g}",
        "width_mm": f"{f.width_m * 1e3:.4g}",
        "thickness_mm": f"{f.thickness_m * 1e3:.4g}",
    }
    return {
        "finger.yaml": finger_text,
        "gripper.yaml": gripper_text,
        "bench.csv": Template(_template("bench.csv")).substitute(fields),
        "study.yaml": Template(_template("study.yaml")).substitute(fields),
    }
