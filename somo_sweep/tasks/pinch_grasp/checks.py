"""What a pinch-grasp study needs of its gripper, checked when the study loads (the task's
``check_model``, ``check_params`` and ``check_grid``): each unmet need one sentence, saying what
the gripper or the parameters have and what is allowed."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.tasks.pinch_grasp.closing import closing_problems
from somo_sweep.tasks.pinch_grasp.geometry import check_reach, ground_problem, span_problem
from somo_sweep.tasks.pinch_grasp.links import MIN_FINGER_LINKS, distal_split_problem, finger_links, fingers

__all__ = ["TrialParams", "check_grid", "check_gripper", "check_trial"]


class TrialParams(Protocol):
    """What the checks read of a trial's parameters (a :class:`~.params.PinchGraspParams`)."""

    @property
    def distal_segment_ratio(self) -> float | None: ...
    @property
    def torque_n_m(self) -> float | None: ...
    @property
    def pressure_kpa(self) -> float | None: ...
    @property
    def hand_height_m(self) -> float: ...
    @property
    def object_span_m(self) -> float: ...


def check_gripper(model: Model) -> list[str]:
    """What the trial needs of its gripper, every unmet need at once: a driven base, two or more
    fingers of one link count, each finger a chain of links of one length with at least
    ``MIN_FINGER_LINKS`` links and a driven joint."""
    hand = model.as_assembly()
    needs: list[str] = []
    if hand.base.mode != "driven":
        needs.append(
            "the pinch_grasp task moves the hand along its path, so its base must be driven; "
            f"got base mode '{hand.base.mode}'; allowed: an assembly with base: {{mode: driven}}"
        )
    if len(hand.manipulators) < 2:
        names = ", ".join(f"'{m.name}'" for m in hand.manipulators)
        needs.append(
            f"the pinch_grasp task needs a gripper of two or more fingers; got {len(hand.manipulators)} "
            f"manipulator(s) ({names}); allowed: an assembly with 2 or more manipulators"
        )
    counts = {}
    for name, finger in fingers(model):
        n_links, _ = counts[name] = finger_links(finger)
        if n_links < MIN_FINGER_LINKS:
            needs.append(
                f"finger '{name}' has {n_links} link(s); allowed: {MIN_FINGER_LINKS} or more "
                "(contact positions along the finger are resolved to one link)"
            )
        lengths = sorted({round(a.segment_m, 9) for a in finger.actuators})
        if len(lengths) > 1:
            shown = ", ".join(f"{v * 1e3:g}" for v in lengths)
            needs.append(
                f"finger '{name}' has links of {shown} mm; allowed: links of one length (the distal "
                "segment ratio and the contact positions are measured in links)"
            )
        if not any(a.actuated_axes for a in finger.actuators):
            needs.append(
                f"finger '{name}' has no actuated joint; allowed: a finger whose first actuator has "
                "an actuated joint (the task closes the fingers through it)"
            )
    if len({n for n, _ in counts.values()}) > 1:
        shown = ", ".join(f"'{k}' {n}" for k, (n, _) in counts.items())
        needs.append(f"the fingers have different link counts ({shown}); allowed: one link count for all")
    return needs


def check_grid(model: Model, param_sets: Sequence[TrialParams]) -> list[str]:
    """Fingers that close on the box under some cell's drive (:mod:`.closing`) and reach it in some cell."""
    drives = {(p.torque_n_m if p.pressure_kpa is None else None, p.pressure_kpa) for p in param_sets}
    return closing_problems(model, drives) + check_reach(model, param_sets)


def check_trial(model: Model, params: TrialParams) -> list[str]:
    """What a trial's parameters need of the gripper: a DSR its fingers can express (one or two
    actuators each), under ``pressure_kpa`` a pressure gain in every finger, and an open hand clear
    of the ground whose fingertips the box passes between
    (:mod:`~somo_sweep.tasks.pinch_grasp.geometry`)."""
    needs: list[str] = []
    for name, finger in fingers(model):
        if params.distal_segment_ratio is not None:
            needs += _split_problems(name, finger, params.distal_segment_ratio)
        if params.pressure_kpa is not None and finger.actuation is None:
            needs.append(
                f"task.pressure_kpa drives each finger through its actuation.pressure_gain_n_m_per_kpa, "
                f"and finger '{name}' has none; allowed: a finger with an actuation block (what "
                "`somo-sweep calibrate` writes), or task.torque_n_m"
            )
    needs += [why for why in _open_hand_problems(model, params) if why is not None]
    return sorted(set(needs), key=needs.index)


def _split_problems(name: str, finger: Manipulator, dsr: float) -> list[str]:
    """Why finger ``name`` cannot be re-split at this DSR: too many actuators, an unactuated grasp
    axis, or a ratio off its link boundaries."""
    needs: list[str] = []
    actuators = finger.actuators
    if len(actuators) > 2:
        needs.append(
            f"finger '{name}' has {len(actuators)} actuators; allowed with a "
            "distal_segment_ratio: 1 or 2 (the ratio re-splits the finger into a driven "
            "proximal and a passive distal segment); or distal_segment_ratio: null to "
            "simulate the fingers as written"
        )
    if not actuators[0].joints[0].actuated:
        needs.append(
            f"finger '{name}': its first joint definition is not actuated; allowed with a "
            "distal_segment_ratio: a finger whose first actuator's first joint (the grasp "
            "axis, where pressure acts) is actuated"
        )
    n_links, link_m = finger_links(finger)
    why = distal_split_problem(dsr, n_links, link_m)
    if why is not None:
        needs.append(f"task.distal_segment_ratio: {why}, or null (the fingers as written)")
    return needs


def _open_hand_problems(model: Model, params: TrialParams) -> list[str | None]:
    """The open hand in the ground, or a box too wide to pass between its open fingertips."""
    if len(model.as_assembly().manipulators) < 2:
        return []  # the gripper check says what is missing
    ground = ground_problem(model, params.hand_height_m)
    return [ground] if ground else [span_problem(model, params.object_span_m, params.hand_height_m)]
