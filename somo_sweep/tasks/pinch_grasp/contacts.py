"""Finger–object contacts of a gripper, sampled over a phase and reduced to position-based metrics.

Links are numbered along each finger as in SoMo: 1 at the base … N at the last
segment, N + 1 for the fingertip; palm and finger base boxes are ``palm``. Counts and
forces of all fingers are added per link number while sampling; a trial stores only
scalars of them (shares of force by zone, mean positions along the finger, see
:mod:`somo_sweep.tasks.pinch_grasp.classify`), so tables of fingers of any link count
have the same columns and relabel with the same code.

The final step's contacts are also counted per part for the paper rule: the finger
base boxes apart from the palm, because the original counts a base box as part of its
finger (its link −1, link number 0) and has no palm.
"""

from __future__ import annotations

import numpy as np

from somo_sweep.sim.world import Body, ModelHandle, World

__all__ = ["HoldProbe", "finger_link_count"]


def finger_link_count(hand: ModelHandle) -> int:
    """N, the segment links of each finger of ``hand`` (rigid pieces, as numbered along the chain).

    Raises:
        ValueError: The fingers differ in link count (the task's model check refuses them first).
    """
    fingers = {name for body in hand.bodies for name in body.plan.tip}
    counts: dict[str, int] = {}
    for body in hand.bodies:
        for info in body.plan.links:
            if info.role == "segment" and info.manipulator in fingers:
                counts[info.manipulator] = max(counts.get(info.manipulator, 0), info.number)
    values = set(counts.values())
    if len(values) != 1:
        raise ValueError(f"the fingers must have one link count each alike, got {counts}")
    return values.pop()


class HoldProbe:
    """Samples contacts between a gripper body and an object.

    Args:
        world: The world holding both.
        hand: The gripper (palm and fingers: one body, or one per finger and the palm).
        object_id: PyBullet id of the object.
        ground_id: PyBullet id of the ground (to tell a held object from one resting on it).
    """

    def __init__(self, world: World, hand: ModelHandle, object_id: int, ground_id: int | None = None):
        self.world = world
        self.hand = hand
        self.object_id = object_id
        self.ground_id = ground_id
        self.on_ground = 0
        self.fingers = [name for body in hand.bodies for name in body.plan.tip]
        self.n_links = n = finger_link_count(hand)
        # (PyBullet body id, link index) → (finger number, link number 1..N + 1) or palm (-1, 0).
        self._where: dict[tuple[int, int], tuple[int, int]] = {}
        # (PyBullet body id, link index) → slot of the final counts:
        # base 0, links 1..N, tip N + 1, palm N + 2.
        self._slot: dict[tuple[int, int], int] = {}
        self._link_body: dict[str, Body] = {}
        for body in hand.bodies:
            for info in body.plan.links:
                idx = body.link_index[info.name]
                self._link_body[info.name] = body
                if info.role in ("segment", "tip") and info.manipulator in self.fingers and info.number > 0:
                    self._where[body.id, idx] = (self.fingers.index(info.manipulator), info.number)
                    self._slot[body.id, idx] = info.number
                elif info.role == "segment" and info.manipulator in self.fingers:
                    # A midpoint layout's rigid half link before the first joint: part of the base,
                    # as in the original (merged into its base box, link number 0).
                    self._where[body.id, idx] = (-1, 0)
                    self._slot[body.id, idx] = 0
                else:
                    self._where[body.id, idx] = (-1, 0)
                    self._slot[body.id, idx] = (
                        0 if info.role == "base" and info.manipulator in self.fingers else n + 2
                    )
        self.counts = np.zeros(n + 1)
        self.force_sums_n = np.zeros(n + 1)
        self.palm_count = 0
        self.palm_force_sum_n = 0.0
        self.finger_force_sums_n = np.zeros(len(self.fingers))
        # Per finger and link number (rows: fingers in the gripper's order), N summed over samples.
        self.finger_link_force_sums_n = np.zeros((len(self.fingers), n + 1))
        self.samples = 0
        self.all_touching = 0
        self.last_links: list[int] = []
        self.last_counts = np.zeros(n + 3, int)

    def finger_mounts_m(self) -> np.ndarray:
        """World positions (m, one row per finger) of the finger mounts.

        A mount is the centre of the back face of the finger's base box, where the finger
        sits on the palm: SoMo's base frame, the point the original study places at its
        hand offset (the chain starts one base box length further along the finger).
        """
        rows = []
        for name in self.fingers:
            base = f"{name}__base"
            body = self._link_body[base]
            info = next(i for i in body.plan.links if i.name == base)
            assert info.link is not None
            rows.append(self.world.point_on_link(body, base, (0.0, 0.0, -info.link.half_extent_m(2))))
        return np.asarray(rows)

    def touching_now(self) -> bool:
        """Whether any part of the hand (fingers, palm, base boxes) touches the object now."""
        return any(self.world.contact_count(self.object_id, b.id) > 0 for b in self.hand.bodies)

    def on_ground_now(self) -> bool:
        """Whether the object touches the ground now (False without a ground)."""
        if self.ground_id is None:
            return False
        return self.world.contact_count(self.object_id, self.ground_id) > 0

    def sample(self) -> None:
        """Record the current contacts (one sample)."""
        touched = np.zeros(len(self.fingers), bool)
        links: list[int] = []
        palm = self.n_links + 2
        slots = np.zeros(self.n_links + 3, int)
        for body in self.hand.bodies:
            c = self.world.contacts(self.object_id, body.id)
            for link_b, force in zip(c["link_b"].tolist(), c["normal_force_n"].tolist(), strict=True):
                slots[self._slot.get((body.id, int(link_b)), palm)] += 1
                finger, number = self._where.get((body.id, int(link_b)), (-1, 0))
                if finger < 0:
                    self.palm_count += 1
                    self.palm_force_sum_n += force
                    continue
                touched[finger] = True
                links.append(number)
                self.counts[number - 1] += 1
                self.force_sums_n[number - 1] += force
                self.finger_force_sums_n[finger] += force
                self.finger_link_force_sums_n[finger, number - 1] += force
        self.samples += 1
        self.all_touching += int(touched.all())
        self.on_ground += int(self.on_ground_now())
        self.last_links = links
        self.last_counts = slots

    def hold_forces_n(self) -> np.ndarray:
        """Mean normal force per link number over the samples (links 1 … N, then the fingertip;
        all fingers added), N."""
        return self.force_sums_n / max(self.samples, 1)

    def finger_hold_forces_n(self) -> np.ndarray:
        """Mean normal force per finger (rows, the gripper's order) and link number (links 1 … N,
        then the fingertip) over the samples, N."""
        return self.finger_link_force_sums_n / max(self.samples, 1)

    def final_counts(self) -> np.ndarray:
        """The final step's contact points per part: base boxes, links 1 … N, fingertip (no palm)."""
        return self.last_counts[:-1]

    def metrics(self) -> dict[str, float | int]:
        """Summary metrics over the samples taken (means per sample)."""
        n = max(self.samples, 1)
        out: dict[str, float | int] = {"hold_samples": self.samples}
        out["hold_contact_fraction_all_fingers"] = self.all_touching / n
        out["hold_ground_contact_fraction"] = self.on_ground / n
        out["hold_contact_count_finger"] = int(self.counts.sum())
        out["hold_contact_count_palm"] = self.palm_count
        out["hold_normal_force_n_palm"] = self.palm_force_sum_n / n
        out["hold_normal_force_n"] = float(self.hold_forces_n().sum()) + self.palm_force_sum_n / n
        per_finger = self.finger_force_sums_n / n
        out["hold_normal_force_n_finger_min"] = float(per_finger.min())
        out["hold_normal_force_n_finger_max"] = float(per_finger.max())
        for k, force in enumerate(per_finger, start=1):
            out[f"hold_normal_force_finger{k}_n"] = float(force)
        last = np.asarray(self.last_links, float)
        out["final_contact_count"] = len(last)
        out["final_mean_contact_link"] = float(last.mean()) if len(last) else float("nan")
        out["final_contact_count_base"] = int(self.last_counts[0])
        out["final_contact_count_palm"] = int(self.last_counts[-1])
        return out
