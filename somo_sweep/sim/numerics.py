"""Numerics that choose themselves: the time step and inertia shaping of a model, from its modes.

The springs are explicit torques (:mod:`somo_sweep.sim.pybullet.springs`: τ = −k·(q − q0) − c·q̇ from
the state at the start of the step) integrated by Bullet's semi-implicit Euler, which is
stable for a linear undamped mode of frequency ω iff ω·dt < 2. Measured on PyBullet 3.2.7
with the Coulomb motors off (:mod:`somo_sweep.sim.stability`): the blow-up step of one link
on a spring and of SoMo's 20-link finger (stiffness ×1 and ×10, link mass ×1 and ×0.2, added
inertia 0 to 3e-5 kg·m²) is 2/ω_max within the 3 % bisection tolerance. The motors add
dissipation (blow-up 1.6–4.7× later in that test) but that margin shrinks at large
deflections, so it is not counted on. Contacts are solved as constraints, which cannot raise
the highest frequency of a chain (Rayleigh's theorem of constraint).

The choice, per chain (:func:`choose_numerics`):

1. Inertia shaping: the largest added inertia J per segment link that moves each of the chain's
   lowest bending modes (one per bending plane: as many as joint definitions per actuator) by
   at most :data:`MAX_MODE_SHIFT`. It lowers ω_max, which lives in the light links.
2. The step: ``SAFETY`` · 2/ω_max of the shaped chain, at most :data:`MAX_STEP_S` and at most
   :data:`LOWEST_MODE_RAD` / ω_low, rounded down to a tidy value; the smallest over the
   model's chains is the model's step.
3. Each chain's shaping is then cut back to the least J for which that step is still within
   ``SAFETY`` · 2/ω_max (no more shaping than the step needs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from somo_sweep.model.description import MAX_ADDED_INERTIA_KG_M2
from somo_sweep.model.load import Model
from somo_sweep.sim.modes import ChainMatrices, ChainModes, chain_matrices, model_chains, shaped

__all__ = [
    "LOWEST_MODE_RAD",
    "MAX_MODE_SHIFT",
    "MAX_STEP_S",
    "SAFETY",
    "ChainChoice",
    "ChosenNumerics",
    "choose_numerics",
    "elastic",
    "numerics_for_step",
    "stability_limit_s",
    "step_ladder",
    "tidy_floor",
]

#: Fraction of the linear stability limit 2/ω_max used: covers the pose dependence of M (a
#: bent finger's ω_max differs from the straight one's by a few %) and cubic stiffening.
SAFETY = 0.8
#: Largest step, s: the largest the project has validated with contact (pinch grasp, 4 ms vs
#: 2 ms: 97.9 % label agreement, docs/pinch_grasp.md).
MAX_STEP_S = 4e-3
#: ω_low·dt at most this (rad): semi-implicit Euler's frequency error (ω·dt)²/24 stays below
#: 0.1 % on the lowest mode (≥ 40 steps per period), ten times under the shaping budget.
LOWEST_MODE_RAD = math.sqrt(24 * 1e-3)
#: Largest relative drop of the kept lowest modes that inertia shaping may cause.
MAX_MODE_SHIFT = 0.01
_TWO_PI = 2 * math.pi
#: Tidy mantissas a chosen step is rounded down to (loses at most 25 %).
TIDY = (1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)


def stability_limit_s(highest_rad_s: float) -> float:
    """The explicit springs' linear stability limit 2/ω_max, s (no limit without a spring)."""
    return 2.0 / highest_rad_s if highest_rad_s > 0 else math.inf


#: Modes below this fraction of a chain's highest are free (a joint without a spring): they
#: have no frequency to resolve, keep or shift. The eigensolver leaves a free mode at about
#: √ε ≈ 1.5e-8 of the highest, and a spring mode this far below the highest would need a
#: stiffness-to-inertia contrast of 1e12 within one chain.
FREE_MODE_FRACTION = 1e-6


def elastic(frequencies_rad_s: np.ndarray) -> np.ndarray:
    """The modes held by springs: ``frequencies_rad_s`` without the free ones (ascending)."""
    w = np.asarray(frequencies_rad_s, dtype=float)
    if w.size == 0 or not w[-1] > 0:
        return w[:0]
    return w[w > FREE_MODE_FRACTION * w[-1]]


def tidy_floor(value: float) -> float:
    """``value`` rounded down to m·10^k with m in :data:`TIDY` (0.00073 → 0.0006)."""
    exp = math.floor(math.log10(value))
    mant = value / 10**exp
    best = max(m for m in TIDY if m <= mant * (1 + 1e-9))
    return float(f"{best * 10**exp:.6g}")


@dataclass(frozen=True)
class ChainChoice:
    """What was chosen for one chain.

    Attributes:
        before: Modes as in the model file.
        after: Modes with the chosen shaping.
        added_inertia_kg_m2: Added to every principal moment of each segment link, kg·m².
        kept_modes: How many of the lowest modes the shaping budget protects.
        lowest_shift: Largest relative drop of a kept mode (0.004 = 0.4 %).
        best_step_s: Largest step this chain alone would allow, s.
    """

    before: ChainModes
    after: ChainModes
    added_inertia_kg_m2: float
    kept_modes: int
    lowest_shift: float
    best_step_s: float


@dataclass(frozen=True)
class ChosenNumerics:
    """The chosen step and shaping of a model; nothing is written anywhere.

    Attributes:
        time_step_s: The step, s.
        chains: Per chain, by manipulator (mount) name.
        reason: Which limit set the step, in words.
    """

    time_step_s: float
    chains: dict[str, ChainChoice]
    reason: str

    @property
    def added_inertia_kg_m2(self) -> dict[str, float]:
        """Added inertia per segment link of each chain, kg·m²."""
        return {name: c.added_inertia_kg_m2 for name, c in self.chains.items()}

    def apply(self, model: Model) -> Model:
        """``model`` with each chain's shaping added to its segment links."""
        if model.manipulator is not None:
            j = self.chains[model.manipulator.name].added_inertia_kg_m2
            return model.model_copy(update={"manipulator": shaped(model.manipulator, j)})
        assert model.assembly is not None
        mounts = [
            m.model_copy(
                update={"manipulator": shaped(m.manipulator, self.chains[m.name].added_inertia_kg_m2)}
            )
            for m in model.assembly.manipulators
        ]
        return model.model_copy(
            update={"assembly": model.assembly.model_copy(update={"manipulators": mounts})}
        )

    def describe(self) -> list[str]:
        """Lines for people: the step and why, then per chain its modes and shaping."""
        lines = [f"time step {self.time_step_s * 1e3:g} ms (set by {self.reason})"]
        for name, c in self.chains.items():
            b, a = c.before, c.after
            lines.append(
                f"  {name}: lowest mode {b.lowest_rad_s:.4g} rad/s ({b.lowest_rad_s / _TWO_PI:.4g} Hz), "
                f"highest {b.highest_rad_s:.4g} rad/s ({b.highest_rad_s / _TWO_PI:.4g} Hz), "
                f"{len(b.frequencies_rad_s)} modes; stability limit 2/ω_max "
                f"{stability_limit_s(b.highest_rad_s) * 1e3:.3g} ms"
            )
            lines.append(
                f"    added inertia {c.added_inertia_kg_m2:.3g} kg·m² per link: highest mode "
                f"{a.highest_rad_s:.4g} rad/s ({a.highest_rad_s / _TWO_PI:.4g} Hz), limit "
                f"{stability_limit_s(a.highest_rad_s) * 1e3:.3g} ms; lowest {c.kept_modes} mode(s) moved "
                f"{c.lowest_shift * 100:.2f} % (lowest {a.lowest_rad_s:.4g} rad/s); this chain alone "
                f"allows {c.best_step_s * 1e3:g} ms"
            )
        return lines

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-able summary (for manifests)."""
        return {
            "time_step_s": self.time_step_s,
            "reason": self.reason,
            "chains": {
                name: {
                    "added_inertia_kg_m2": c.added_inertia_kg_m2,
                    "lowest_rad_s_before": c.before.lowest_rad_s,
                    "lowest_rad_s_after": c.after.lowest_rad_s,
                    "highest_rad_s_before": c.before.highest_rad_s,
                    "highest_rad_s_after": c.after.highest_rad_s,
                    "lowest_shift": c.lowest_shift,
                }
                for name, c in self.chains.items()
            },
        }


def _shift(mats: ChainMatrices, base: np.ndarray, kept: int, j: float) -> float:
    """Largest relative drop of the ``kept`` lowest elastic modes from ``base`` (elastic) at J."""
    w = elastic(mats.frequencies_rad_s(j))[:kept]
    return float(np.max(1.0 - w / base[: len(w)])) if len(w) else 0.0


def _largest_inertia(mats: ChainMatrices, kept: int, max_shift: float) -> float:
    """Largest J (kg·m²) whose kept modes drop by at most ``max_shift`` (geometric bisection)."""
    base = elastic(mats.frequencies_rad_s(0.0))
    if kept == 0 or len(base) == 0:
        return 0.0
    scale = float(np.min(np.diag(mats.mass)))  # the lightest joint's own inertia
    # Never past what a link may be given (a chain heavy for its springs would grow J to overflow).
    lo, hi = 0.0, min(scale, MAX_ADDED_INERTIA_KG_M2)
    while _shift(mats, base, kept, hi) <= max_shift:
        if hi >= MAX_ADDED_INERTIA_KG_M2:
            return MAX_ADDED_INERTIA_KG_M2
        lo, hi = hi, min(hi * 10, MAX_ADDED_INERTIA_KG_M2)
    lo = lo or hi * 1e-6
    if _shift(mats, base, kept, lo) > max_shift:
        return 0.0
    while hi / lo > 1.01:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if _shift(mats, base, kept, mid) <= max_shift else (lo, mid)
    return lo


def _least_inertia_for(mats: ChainMatrices, step_s: float, upper: float) -> float:
    """Least J in [0, upper] with SAFETY·2/ω_max(J) ≥ step_s (``upper`` satisfies it)."""

    def ok(j: float) -> bool:
        return SAFETY * stability_limit_s(mats.frequencies_rad_s(j)[-1]) >= step_s

    if ok(0.0) or upper <= 0:
        return 0.0
    lo, hi = upper * 1e-6, upper
    if ok(lo):
        return lo
    while hi / lo > 1.01:
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi


def _step_limits(w: np.ndarray, max_step_s: float) -> dict[str, float]:
    w = elastic(w)
    return {
        f"stability ({SAFETY:g}·2/ω_max)": SAFETY * stability_limit_s(float(w[-1])) if len(w) else math.inf,
        f"lowest-mode resolution (ω_low·dt ≤ {LOWEST_MODE_RAD:.3f})": (
            LOWEST_MODE_RAD / float(w[0]) if len(w) else math.inf
        ),
        "largest validated step": max_step_s,
    }


def choose_numerics(
    model: Model, max_step_s: float = MAX_STEP_S, max_shift: float = MAX_MODE_SHIFT, engine: str = "pybullet"
) -> ChosenNumerics:
    """Choose the time step and inertia shaping of ``model`` from its chains' modes.

    Args:
        model: The model (as the trial will load it).
        max_step_s: Largest step allowed, s.
        max_shift: Largest relative drop of each chain's kept lowest modes.
        engine: The engine whose mass matrices give the modes (:func:`~somo_sweep.sim.modes.chain_matrices`).

    Returns:
        The step, the shaping per chain, the modes before and after, and which limit decided.
    """
    mats: dict[str, ChainMatrices] = {}
    upper: dict[str, float] = {}
    best: dict[str, tuple[float, str]] = {}
    for manip, floating in model_chains(model):
        m = chain_matrices(manip, floating, engine)
        if not m.joints or not len(elastic(m.frequencies_rad_s(0.0))):
            continue  # no spring to resolve: the chain sets no limit
        mats[manip.name] = m
        kept = min(m.axes_per_joint_cycle, len(m.stiffness) - m.rigid_modes)
        upper[manip.name] = _largest_inertia(m, kept, max_shift)
        limits = _step_limits(m.frequencies_rad_s(upper[manip.name]), max_step_s)
        why = min(limits, key=lambda k: limits[k])
        best[manip.name] = (tidy_floor(limits[why]), why)
    if not mats:
        return ChosenNumerics(max_step_s, {}, "no spring joints: the largest validated step")
    decider = min(best, key=lambda n: best[n][0])
    step = best[decider][0]
    chains: dict[str, ChainChoice] = {}
    for name, m in mats.items():
        kept = min(m.axes_per_joint_cycle, len(m.stiffness) - m.rigid_modes)
        j = _least_inertia_for(m, step, upper[name])
        before = m.modes(0.0)
        shift = _shift(m, elastic(np.asarray(before.frequencies_rad_s)), kept, j) if kept else 0.0
        chains[name] = ChainChoice(before, m.modes(j), j, kept, max(shift, 0.0), best[name][0])
    reason = f"{best[decider][1]} of chain '{decider}'"
    return ChosenNumerics(step, chains, reason)


def numerics_for_step(model: Model, step_s: float, engine: str = "pybullet") -> ChosenNumerics:
    """The least inertia shaping that makes ``step_s`` stable for every chain of ``model``.

    No lowest-mode budget: how much shaping a step may take is judged by the labels it gives,
    against half the step (:mod:`somo_sweep.sweep.run.convergence`), not by the modes. A chain that is
    stable at ``step_s`` as it is gets none. ``engine``: whose mass matrices give the modes.
    """
    chains: dict[str, ChainChoice] = {}
    for manip, floating in model_chains(model):
        m = chain_matrices(manip, floating, engine)
        if not m.joints or not len(elastic(m.frequencies_rad_s(0.0))):
            continue
        kept = min(m.axes_per_joint_cycle, len(m.stiffness) - m.rigid_modes)
        j = _least_inertia_for(m, step_s, _enough_inertia(m, step_s))
        before = m.modes(0.0)
        shift = _shift(m, elastic(np.asarray(before.frequencies_rad_s)), kept, j) if kept else 0.0
        chains[manip.name] = ChainChoice(before, m.modes(j), j, kept, max(shift, 0.0), step_s)
    return ChosenNumerics(step_s, chains, "label convergence against half the step")


def _enough_inertia(mats: ChainMatrices, step_s: float) -> float:
    """An added inertia that makes ``step_s`` stable (grown tenfold from the lightest joint's own)."""
    j = max(float(np.min(np.diag(mats.mass))) * 1e-3, 1e-15)
    while SAFETY * stability_limit_s(mats.frequencies_rad_s(j)[-1]) < step_s and j < MAX_ADDED_INERTIA_KG_M2:
        j = min(j * 10, MAX_ADDED_INERTIA_KG_M2)
    return j


def step_ladder(
    model: Model, max_step_s: float = MAX_STEP_S, engine: str = "pybullet"
) -> tuple[list[float], str]:
    """The steps an automatic choice tries, largest first, and what set the first one.

    The first is the model's largest step by its lowest modes (each chain's lowest mode resolved
    by ω_low·dt ≤ :data:`LOWEST_MODE_RAD`, at most ``max_step_s``): the modal starting guess. Each
    next one is half the last, down to the step at which every chain is stable with no shaping
    at all (:data:`SAFETY` · 2/ω_max), which ends the ladder. ``engine``: whose mass matrices
    give the modes.
    """
    guess, floor, why = max_step_s, max_step_s, "the largest validated step"
    for manip, floating in model_chains(model):
        m = chain_matrices(manip, floating, engine)
        w = elastic(m.frequencies_rad_s(0.0)) if m.joints else np.zeros(0)
        if not len(w):
            continue
        lowest = LOWEST_MODE_RAD / float(w[0])
        if lowest < guess:
            guess, why = lowest, f"lowest-mode resolution of chain '{manip.name}'"
        floor = min(floor, SAFETY * stability_limit_s(float(w[-1])))
    steps = [tidy_floor(guess)]
    while steps[-1] / 2 > floor * (1 + 1e-9):
        steps.append(steps[-1] / 2)
    if tidy_floor(floor) < steps[-1] * (1 - 1e-9):
        steps.append(tidy_floor(floor))
    return steps, why
