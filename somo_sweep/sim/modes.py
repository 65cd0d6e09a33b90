"""Modal estimate of a manipulator's chain: K v = ω² M v about the straight (neutral) pose.

M is the joint-space mass matrix of the chain's plan (:mod:`somo_sweep.sim.planner`) as the
study's engine loads it, at the spring joints' neutral positions, in SI (kg·m² for revolute, kg
for prismatic joints): PyBullet's ``calculateMassMatrix``
(:mod:`somo_sweep.sim.pybullet.mass_matrix`) or MuJoCo's ``mj_fullM``
(:mod:`somo_sweep.sim.mujoco.mass_matrix`). K is the diagonal of the spring joints' stiffness
(N·m/rad or N/m). Gravity's geometric stiffness,
the Coulomb motors, damping and contacts are left out: the estimate is the linear,
undamped chain, which is what an explicit spring update has to resolve.

Inertia shaping adds ``J`` (kg·m²) to every principal moment of every segment link; the mass
matrix is linear in it, so two evaluations give M(J) = M₀ + J·D for every J (on MuJoCo, whose
implicit springs need no shaping and whose scenes leave it out, D = 0).
A mount clamped to a palm or a driven base is analysed with its base clamped; a free
manipulator (no base link, ``base.mode: free``) with a floating base, whose six rigid-body
modes are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.planner import plan_manipulator

__all__ = ["ChainMatrices", "ChainModes", "chain_matrices", "model_chains", "neutral_mass_matrix", "shaped"]

#: Inertia (kg·m²) used to measure dM/dJ; the matrix is linear in J, so any value works.
_PROBE_KG_M2 = 1e-4
#: Rigid-body modes of a floating base.
_BASE_DOFS = 6


@dataclass(frozen=True)
class ChainModes:
    """Natural frequencies of one chain.

    Attributes:
        chain: Manipulator (mount) name.
        added_inertia_kg_m2: Inertia shaping added to each segment link, kg·m².
        frequencies_rad_s: Every natural frequency, ascending, rad/s.
    """

    chain: str
    added_inertia_kg_m2: float
    frequencies_rad_s: tuple[float, ...]

    @property
    def lowest_rad_s(self) -> float:
        """Lowest natural frequency, rad/s."""
        return self.frequencies_rad_s[0]

    @property
    def highest_rad_s(self) -> float:
        """Highest natural frequency, rad/s (what an explicit step must resolve)."""
        return self.frequencies_rad_s[-1]


@dataclass(frozen=True)
class ChainMatrices:
    """The linearised chain: M(J) = ``mass`` + J·``inertia_gain``, and K = diag(``stiffness``).

    Attributes:
        chain: Manipulator (mount) name.
        joints: Spring joint names, in matrix order (after the base DoFs of a floating base).
        mass: Mass matrix without added inertia, SI (kg·m² / kg).
        inertia_gain: dM/dJ, dimensionless (J in kg·m²).
        stiffness: Diagonal of K, SI (N·m/rad / N/m); zeros for floating-base DoFs.
        rigid_modes: Zero-frequency modes to drop (6 for a floating base, else 0).
        axes_per_joint_cycle: Joint definitions an actuator cycles through (at most over the
            actuators): the number of bending planes, hence of "lowest" modes worth keeping.
    """

    chain: str
    joints: tuple[str, ...]
    mass: np.ndarray
    inertia_gain: np.ndarray
    stiffness: np.ndarray
    rigid_modes: int
    axes_per_joint_cycle: int

    def frequencies_rad_s(self, added_inertia_kg_m2: float = 0.0) -> np.ndarray:
        """Natural frequencies (ascending, rad/s) with ``added_inertia_kg_m2`` on each segment link."""
        m = self.mass + added_inertia_kg_m2 * self.inertia_gain
        w2 = scipy.linalg.eigh(np.diag(self.stiffness), m, eigvals_only=True)
        return np.sqrt(np.clip(np.sort(w2)[self.rigid_modes :], 0.0, None))

    def modes(self, added_inertia_kg_m2: float = 0.0) -> ChainModes:
        """The chain's :class:`ChainModes` with ``added_inertia_kg_m2`` on each segment link."""
        w = self.frequencies_rad_s(added_inertia_kg_m2)
        return ChainModes(self.chain, added_inertia_kg_m2, tuple(float(v) for v in w))


def shaped(manip: Manipulator, added_inertia_kg_m2: float) -> Manipulator:
    """``manip`` with ``added_inertia_kg_m2`` added to every actuator link (on top of its own)."""
    acts = [
        a.model_copy(
            update={
                "link": a.link.model_copy(
                    update={"added_inertia_kg_m2": a.link.added_inertia_kg_m2 + added_inertia_kg_m2}
                )
            }
        )
        for a in manip.actuators
    ]
    return manip.model_copy(update={"actuators": acts})


def model_chains(model: Model) -> list[tuple[Manipulator, bool]]:
    """Every manipulator of a model (named as mounted) and whether its base floats."""
    assembly = model.as_assembly()
    floating = assembly.base.link is None and assembly.base.mode == "free"
    return [
        (mount.manipulator.model_copy(update={"name": mount.name}), floating)
        for mount in assembly.manipulators
    ]


def neutral_mass_matrix(plan: BodyPlan, engine: str = "pybullet") -> np.ndarray:
    """The mass matrix of ``plan`` at its neutral pose on ``engine`` (SI; a free base's six DoFs
    first, then the spring joints in plan order). Imports that engine, and only that one."""
    if engine in ("mujoco", "mujoco_warp"):  # MuJoCo Warp's model is MuJoCo's
        from somo_sweep.sim.mujoco.mass_matrix import neutral_mass_matrix as mujoco_matrix

        return mujoco_matrix(plan)
    from somo_sweep.sim.pybullet.mass_matrix import neutral_mass_matrix as pybullet_matrix

    return pybullet_matrix(plan)


def chain_matrices(manip: Manipulator, floating: bool = False, engine: str = "pybullet") -> ChainMatrices:
    """Linearise one manipulator's chain about its neutral pose (two mass matrices on ``engine``).

    Args:
        manip: The manipulator (its own ``added_inertia_kg_m2`` is part of the baseline).
        floating: Analyse with a floating base (six rigid-body modes dropped) instead of clamped.
        engine: The engine whose mass matrix is read: ``pybullet`` or ``mujoco``.
    """
    mode = "free" if floating else "fixed"
    # Both plans first (the chain as it is, and probed with added inertia), then their matrices.
    plan = plan_manipulator(manip, mode=mode)
    probe = plan_manipulator(shaped(manip, _PROBE_KG_M2), mode=mode)
    m0, m1 = neutral_mass_matrix(plan, engine), neutral_mass_matrix(probe, engine)
    k = [sj.stiffness for sj in plan.joints]
    rigid = _BASE_DOFS if floating else 0
    stiffness = np.concatenate([np.zeros(m0.shape[0] - len(k)), np.asarray(k, dtype=float)])
    return ChainMatrices(
        chain=manip.name,
        joints=tuple(sj.name for sj in plan.joints),
        mass=m0,
        inertia_gain=(m1 - m0) / _PROBE_KG_M2,
        stiffness=stiffness,
        rigid_modes=rigid if m0.shape[0] > len(k) else 0,
        axes_per_joint_cycle=max(len(a.joints) for a in manip.actuators),
    )
