"""When a pinch-grasp trial's outcome is settled before its end: the early-stop rule.

A trial may stop as soon as no later phase can change its label under either rule
(:mod:`somo_sweep.tasks.pinch_grasp.classify`). The rule is checked every
``check_period_s`` (40 ms) from the end of the squeeze to the end of the lift: the outcome is
settled when the object

* touches no part of the hand (fingers, palm, base boxes),
* rests on the ground: touches it, moves slower than ``REST_SPEED_M_S`` and turns
  slower than ``REST_SPIN_RAD_S``,
* has its centre at most ``PAPER_MIN_Z_M`` (40 mm) above the ground,

and every finger joint turns slower than ``FINGER_REST_RAD_S`` (the fingers have
stopped closing: at the end of the torque ramp they still close at ~0.2 rad/s).
The reason recorded is ``no_contact_after_squeeze`` when the hand did not touch the
object at the end of the squeeze, ``dropped`` when it did and has let it go.

Why that settles *no grasp* under both rules: after the squeeze the torque stays
constant and the hand only moves straight up (lift) or stays put (hold), so a finger
at rest beside a box at rest on the ground keeps its horizontal gap; a box resting
on the ground is a vertical prism, so a finger rising beside it does not meet it.
Nothing touches the box again, let alone lifts it: ``contacts`` then finds no
finger on it in the hold samples, and ``paper`` finds its centre below 40 mm and no
contact at the last step. Each condition closes one way the outcome could still
change: a finger still closing can reach the box after the squeeze; a box still
toppling (pushed over in the approach) can fall into the fingers; a box standing on
its end (the 80–120 mm wide ones, centre 40–60 mm up) passes the paper rule's height
test, and a finger touching it at the last step would make it a paper grasp.
"""

from __future__ import annotations

from dataclasses import dataclass

from somo_sweep.tasks.pinch_grasp.classify import PAPER_MIN_Z_M

__all__ = [
    "FINGER_REST_RAD_S",
    "REASONS",
    "REST_SPEED_M_S",
    "REST_SPIN_RAD_S",
    "Snapshot",
    "settled_reason",
]

#: Largest object speed (m/s) and turning rate (rad/s) of an object at rest.
REST_SPEED_M_S = 0.005
REST_SPIN_RAD_S = 0.05
#: Largest finger joint speed of fingers that have stopped closing, rad/s.
FINGER_REST_RAD_S = 0.05
#: The reasons recorded in ``ended_early_reason``.
REASONS = ("no_contact_after_squeeze", "dropped")


@dataclass(frozen=True)
class Snapshot:
    """What the rule looks at, at one moment of a trial.

    Attributes:
        hand_touches_object: Any contact between the hand and the object.
        object_on_ground: Any contact between the object and the ground.
        object_speed_m_s: Speed of the object's centre, m/s.
        object_spin_rad_s: Magnitude of the object's angular velocity, rad/s.
        object_z_m: Height of the object's centre above the ground, m.
        finger_speed_rad_s: Largest finger joint speed, rad/s.
    """

    hand_touches_object: bool
    object_on_ground: bool
    object_speed_m_s: float
    object_spin_rad_s: float
    object_z_m: float
    finger_speed_rad_s: float

    @property
    def settled(self) -> bool:
        """True when no later phase can make this trial a grasp (see the module docstring)."""
        return (
            not self.hand_touches_object
            and self.object_on_ground
            and self.object_speed_m_s < REST_SPEED_M_S
            and self.object_spin_rad_s < REST_SPIN_RAD_S
            and self.object_z_m <= PAPER_MIN_Z_M
            and self.finger_speed_rad_s < FINGER_REST_RAD_S
        )


def settled_reason(snapshot: Snapshot, touched_at_squeeze_end: bool) -> str:
    """The reason to end the trial now (one of ``REASONS``), or ``""`` to go on.

    Args:
        snapshot: The current state.
        touched_at_squeeze_end: Whether the hand touched the object at the end of the squeeze.
    """
    if not snapshot.settled:
        return ""
    return REASONS[1] if touched_at_squeeze_end else REASONS[0]
