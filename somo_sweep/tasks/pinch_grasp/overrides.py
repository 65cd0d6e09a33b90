"""The model fields a pinch-grasp trial's parameters overwrite in every finger when they are not
null (:func:`~somo_sweep.tasks.pinch_grasp.gripper.split_finger` does it): a study that gives such a
field too is refused, since its column would not be what was simulated
(:attr:`~somo_sweep.tasks.registry.TaskSpec.replaces`)."""

from __future__ import annotations

__all__ = ["REPLACED"]

_FINGER = "model.assembly.manipulators[*].manipulator"
_LINKS = f"{_FINGER}.actuators[*].link"
_JOINTS = f"{_FINGER}.actuators[*].joints[*]"
_TIPS = f"{_FINGER}.tip_links[*]"

#: Task parameter → the model fields it replaces (key-path patterns, ``[*]``: every item).
REPLACED: dict[str, tuple[str, ...]] = {
    "numerics.added_inertia_kg_m2": (f"{_LINKS}.added_inertia_kg_m2",),
    "numerics.damping_n_m_s_per_rad": (f"{_JOINTS}.damping_n_m_s_per_rad",),
    "numerics.motor_limit_n_m": (f"{_JOINTS}.motor_limit_n_m",),
    "original.finger_spinning_friction_m": (f"{_LINKS}.friction.spinning", f"{_TIPS}.friction.spinning"),
    "original.restitution": (f"{_LINKS}.restitution", f"{_TIPS}.restitution"),
}
