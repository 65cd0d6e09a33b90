"""Grasp labels — ``pinch``, ``power`` or ``no_grasp`` — from stored per-trial metrics.

Two rules, both pure functions of a trial's stored metrics (so a finished sweep
can be relabelled without rerunning it):

``paper`` (the original study's rule, exactly as its code applies it)
    Grasped if, at the end, the object's centre has z > 40 mm (its ``height_check``),
    and −50 mm ≤ x, y ≤ 50 mm and 40 mm ≤ z ≤ 200 mm (its ``bounding_box``); the
    bounds are absolute world coordinates, and the object starts at x = y = 0 in both
    codes, so they are also relative to the start. Then the finger–object contact points
    of the *final step* are averaged by link number (its ``mean_link``, stored as
    ``final_mean_link_paper``): links 1 … N, the fingertip counts as N (the original merges
    the fingertip into the last link), a finger's base box as 0 (it is link −1 of the
    original's finger body); the palm, which the original does not have, is left out.
    Pinch if mean / N > 1 − DSR (the mean position along the finger,
    ``final_mean_position_paper``, beyond the distal segment's start), with DSR the grid's
    decimal value as the original's notebook compares it, power otherwise. A grasped
    trial with no finger contact at the final step is power: the notebook compares NaN,
    which is never above the threshold. So at DSR 0 nothing is a pinch. Rows stored
    before the final step's per-part counts (no ``final_contact_count_base``) are
    relabelled from ``final_mean_contact_link`` (fingertip N + 1, base boxes left out)
    where every split of it gives the same label, else ``unknown``.

``contacts`` (default)
    Uses where the contact *force* sits over the whole hold phase, not one step.
    Grasped if the object was held: off the ground in at least 90 % of the hold
    samples, touched by every finger in at least 90 % of them, and higher at the
    end than at the start by at least ``MIN_LIFT_M`` (10 mm). An object that swings
    in the fingertips but stays off the ground is held; one left on the ground is not.
    The finger's distal zone is the links past the driven segment (its last
    DSR·N links, whether the distal segment is a separate actuator or not) plus the
    fingertip; the rest of the finger and the palm form the proximal zone. The trial
    stores the zones' shares of the hold-phase normal force
    (``hold_force_fraction_distal``, ``_tip``, ``_proximal``, ``_palm``).
    Pinch if the proximal zone carries less than ``max_proximal_fraction`` (25 %)
    of the hold-phase normal force, power otherwise: a power grasp is one where
    the object is pressed into the proximal finger or the palm, while a light
    touch of a proximal link during a fingertip grasp does not make it one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from somo_sweep.errors import SomoError, did_you_mean
from somo_sweep.tasks.pinch_grasp.legacy import upgrade_table
from somo_sweep.tasks.pinch_grasp.positions import contact_position, paper_mean_link, zone_force_fractions

__all__ = [
    "LABELS",
    "RULES",
    "GraspEvidence",
    "classify",
    "contact_position",
    "distal_ratio",
    "find_column",
    "is_held",
    "paper_mean_link",
    "reclassify",
    "zone_force_fractions",
]

Label = Literal["pinch", "power", "no_grasp", "unknown"]
LABELS: tuple[str, ...] = ("pinch", "power", "no_grasp")
RULES: tuple[str, ...] = ("contacts", "paper")

#: Links per finger of rows stored without ``n_finger_links`` (the bundled finger).
BUNDLED_FINGER_LINKS = 20
#: Paper rule bounds on the final object position, m.
PAPER_MIN_Z_M = 0.040
PAPER_MAX_Z_M = 0.200
PAPER_MAX_XY_M = 0.050
#: Contacts rule: least rise of the object (m), least share of hold samples held, proximal share.
MIN_LIFT_M = 0.010
MIN_HELD_FRACTION = 0.9
MAX_PROXIMAL_FRACTION = 0.25


@dataclass(frozen=True)
class GraspEvidence:
    """What the rules look at, for one trial (scalars only: any finger's rows alike).

    Attributes:
        distal_segment_ratio: DSR of the fingers.
        object_position_m: Final object centre (x, y, z) relative to the world, m; it starts at x = y = 0.
        lift_height_m: Final object height above its start, m.
        commanded_lift_m: How far the hand lifted, m.
        hold_force_fraction_proximal: Share of the hold-phase normal force on the proximal zone
            (proximal links, base boxes and palm; NaN: no contact force at all).
        hold_contact_fraction_all_fingers: Share of hold samples with every finger touching.
        final_mean_contact_link: Mean link number of the final step's contacts (fingertip N + 1,
            base boxes and palm left out; NaN: none).
        hold_ground_contact_fraction: Share of hold samples with the object on the ground.
        final_mean_link_paper: The original's mean link of the final step's contacts (base boxes
            0, fingertip N; NaN: no contact), or None for a row stored before it.
        n_finger_links: N, segment links per finger.
        hold_contact_count_palm: Palm and base-box contact points over the hold samples (the
            final step is one of them; -1 unknown); used only when ``final_mean_link_paper`` is None.
    """

    distal_segment_ratio: float
    object_position_m: tuple[float, float, float]
    lift_height_m: float
    commanded_lift_m: float
    hold_force_fraction_proximal: float
    hold_contact_fraction_all_fingers: float
    final_mean_contact_link: float
    hold_ground_contact_fraction: float = 0.0
    final_mean_link_paper: float | None = None
    n_finger_links: int = BUNDLED_FINGER_LINKS
    hold_contact_count_palm: int = -1

    @classmethod
    def from_metrics(
        cls, metrics: Mapping[str, Any], distal_segment_ratio: float, commanded_lift_m: float = 0.075
    ) -> GraspEvidence:
        """Evidence from a trial's metrics (a task result or one row of a results table)."""
        mean_paper = None
        if _finite(metrics.get("final_contact_count_base")):
            mean_paper = float(metrics["final_mean_link_paper"])
        palm = metrics.get("hold_contact_count_palm")
        n_links = metrics.get("n_finger_links")
        return cls(
            distal_segment_ratio=float(distal_segment_ratio),
            object_position_m=(
                float(metrics["object_x_m"]),
                float(metrics["object_y_m"]),
                float(metrics["object_z_m"]),
            ),
            lift_height_m=float(metrics["lift_height_m"]),
            commanded_lift_m=float(commanded_lift_m),
            hold_force_fraction_proximal=float(metrics["hold_force_fraction_proximal"]),
            hold_contact_fraction_all_fingers=float(metrics["hold_contact_fraction_all_fingers"]),
            final_mean_contact_link=float(metrics["final_mean_contact_link"]),
            hold_ground_contact_fraction=float(metrics["hold_ground_contact_fraction"]),
            final_mean_link_paper=mean_paper,
            n_finger_links=int(n_links) if n_links is not None and _finite(n_links) else BUNDLED_FINGER_LINKS,
            hold_contact_count_palm=int(palm) if palm is not None and _finite(palm) else -1,
        )


def distal_ratio(distal_segment_ratio: Any, metrics: Mapping[str, Any]) -> float:
    """The DSR the rules compare with: the trial's ratio, or for fingers simulated as written
    (no ratio) their distal zone's share of the links, ``n_distal_links / n_finger_links``."""
    if distal_segment_ratio is not None and _finite(distal_segment_ratio):
        return float(distal_segment_ratio)
    n_distal, n_links = metrics.get("n_distal_links", "nan"), metrics.get("n_finger_links", "nan")
    if _finite(n_distal) and _finite(n_links) and float(n_links) > 0:
        return float(n_distal) / float(n_links)
    return float("nan")


def _finite(value: Any) -> bool:
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def _paper_threshold(dsr: float) -> float:
    # The notebook compares with the grid's decimal DSR (0.55, not 0.5499999999999999); at an
    # exact tie (all contacts on link 9 at DSR 0.55) the float result decides, as it did there.
    return 1.0 - round(dsr, 6)


def _paper(ev: GraspEvidence) -> Label:
    x, y, z = ev.object_position_m
    grasped = (
        z > PAPER_MIN_Z_M
        and PAPER_MIN_Z_M <= z <= PAPER_MAX_Z_M
        and -PAPER_MAX_XY_M <= x <= PAPER_MAX_XY_M
        and -PAPER_MAX_XY_M <= y <= PAPER_MAX_XY_M
    )
    if not grasped:
        return "no_grasp"
    threshold = _paper_threshold(ev.distal_segment_ratio)
    n_links = ev.n_finger_links
    if ev.final_mean_link_paper is not None:
        mean = ev.final_mean_link_paper
        return "pinch" if mean / n_links > threshold else "power"  # NaN (no contact): power
    # A row stored before the per-part counts: its mean numbers the fingertip 21 and leaves the
    # base boxes out. With a tip share f of the contacts the paper's mean is m − f, and
    # max(0, m − N) ≤ f ≤ (m − 1) / N; base-box contacts (possible only if the palm or a base
    # box was touched during the hold) can pull it down to 0.
    m = ev.final_mean_contact_link
    if not math.isfinite(m):
        return "power"  # no finger contact: with or without base-box contacts, power
    high = min(m, float(n_links))
    low = m - (m - 1) / n_links if ev.hold_contact_count_palm == 0 else 0.0
    if low / n_links > threshold:
        return "pinch"
    if high / n_links <= threshold:
        return "power"
    return "unknown"


def is_held(ev: GraspEvidence) -> bool:
    """Held through the hold phase: off the ground, in every finger, and lifted (see the module doc)."""
    return (
        ev.lift_height_m >= MIN_LIFT_M
        and ev.hold_contact_fraction_all_fingers >= MIN_HELD_FRACTION
        and 1.0 - ev.hold_ground_contact_fraction >= MIN_HELD_FRACTION
    )


def _contacts(ev: GraspEvidence, max_proximal_fraction: float = MAX_PROXIMAL_FRACTION) -> Label:
    if not is_held(ev):
        return "no_grasp"
    proximal = ev.hold_force_fraction_proximal
    if not math.isfinite(proximal):
        return "no_grasp"
    return "pinch" if proximal < max_proximal_fraction else "power"


def classify(evidence: GraspEvidence, rule: str = "contacts", **options: float) -> Label:
    """Label one trial with a rule (``contacts`` or ``paper``); options tune the ``contacts`` rule.

    Raises:
        SomoError: Unknown rule (lists the valid ones).
    """
    allowed = {"paper": (), "contacts": ("max_proximal_fraction",)}
    if rule in allowed:
        bad = sorted(set(options) - set(allowed[rule]))
        if bad:
            raise SomoError(
                f"grasp rule '{rule}' takes no option {', '.join(bad)}; "
                f"allowed: {', '.join(allowed[rule]) or 'none'}"
            )
        fraction = options.get("max_proximal_fraction", MAX_PROXIMAL_FRACTION)
        if not (math.isfinite(fraction) and 0.0 < fraction <= 1.0):
            raise SomoError(f"max_proximal_fraction must be above 0 and at most 1, got {fraction:g}")
    if rule == "paper":
        return _paper(evidence)
    if rule == "contacts":
        return _contacts(evidence, **options)
    raise SomoError(f"unknown grasp rule '{rule}'{did_you_mean(rule, RULES)}; allowed: {', '.join(RULES)}")


def find_column(columns: list[str], name: str) -> str | None:
    """The column holding ``name`` in a results table, or None.

    Tried in order: ``name`` itself, the sweep engine's ``task_<name>`` (task parameters)
    and ``label_<name>``, then the one column ending in ``.name``, ``/name`` or ``:name``.
    """
    for candidate in (name, f"task_{name}", f"label_{name}"):
        if candidate in columns:
            return candidate
    hits = [c for c in columns if any(c.endswith(sep + name) for sep in (".", "/", ":"))]
    return hits[0] if len(hits) == 1 else None


def reclassify(table: Any, rule: str = "contacts", **options: float) -> Any:
    """Labels for every row of a results table (a pandas DataFrame) from its stored metrics.

    Columns are found by metric or parameter name, bare or behind a prefix
    (``metrics.lift_height_m``, ``task.distal_segment_ratio``...). Rows whose status is
    not ``ok`` keep no label (``None``). Under the paper rule, rows without the final step's
    per-part counts (stored before them) get ``unknown`` where their stored mean does not
    decide the label (see the module docstring). A table stored with per-link columns is
    converted first (:func:`~somo_sweep.tasks.pinch_grasp.legacy.upgrade_table`).

    Returns:
        A pandas Series of labels aligned with ``table``.

    Raises:
        SomoError: A needed column is missing (lists which) or the rule is unknown.
    """
    import pandas as pd

    classify(_DUMMY, rule, **options)  # fail early on a bad rule or option
    table = upgrade_table(table)
    cols = [str(c) for c in table.columns]
    needed = [
        "distal_segment_ratio",
        "object_x_m",
        "object_y_m",
        "object_z_m",
        "lift_height_m",
        "hold_force_fraction_proximal",
        "hold_contact_fraction_all_fingers",
        "hold_ground_contact_fraction",
        "final_mean_contact_link",
    ]
    found = {n: find_column(cols, n) for n in needed}
    missing = [n for n, c in found.items() if c is None]
    if missing:
        raise SomoError(
            f"results table lacks the columns needed to classify grasps: {', '.join(missing)} "
            "(was it made by the pinch_grasp task?)"
        )
    optional_names = (
        "final_contact_count_base",
        "final_mean_link_paper",
        "n_finger_links",
        "n_distal_links",
        "hold_contact_count_palm",
    )
    optional = {n: find_column(cols, n) for n in optional_names}
    found.update({n: c for n, c in optional.items() if c is not None})
    lift_col = find_column(cols, "lift_m")
    status_col = find_column(cols, "status")
    labels: list[str | None] = []
    for _, row in table.iterrows():
        if status_col is not None and row[status_col] != "ok":
            labels.append(None)
            continue
        metrics = {n: row[c] for n, c in found.items()}
        lift = float(row[lift_col]) if lift_col is not None else 0.075
        ev = GraspEvidence.from_metrics(metrics, distal_ratio(metrics["distal_segment_ratio"], metrics), lift)
        labels.append(classify(ev, rule, **options))
    return pd.Series(labels, index=table.index, name=f"grasp_{rule}", dtype=object)


_DUMMY = GraspEvidence(0.2, (0.0, 0.0, 0.0), 0.0, 0.075, float("nan"), 0.0, float("nan"))
