"""How much of a blocked-force row the rigid model decides: the range of admissible plate forces.

A finger lying flat on the bench's plate touches it at more corners than it has joints, so the
contact forces that hold it in its solved shape are not unique. The plate's total force is
then only known to lie in an interval: every split of the weight between plate and clamp in
that interval is a rigid equilibrium of the same shape, and which one a simulation reports is
decided by its contact regularisation (Bullet's slop and solver order, MuJoCo's soft
constraints), not by the model. Once the finger curls onto its tip the interval closes to a
point. :func:`plate_force_range` solves the two linear programmes (least and most total plate
force over the non-negative contact forces that balance the solved equilibrium) with HiGHS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.statics.bench_rig import BenchSettings, bench_manipulator
from somo_sweep.statics.solve import static_chain

__all__ = ["PlateForceRange", "plate_force_range"]


@dataclass(frozen=True)
class PlateForceRange:
    """The plate forces rigid statics admits at a solved blocked-force equilibrium.

    Attributes:
        solved_n: The solved statics' value (what ``statics: solve`` reports), N.
        low_n, high_n: Least and most total plate force that holds the same shape, N
            (``high_n`` is ``inf`` when a corner can push without bound against the clamp).
        corners: Corners touching the plate at the equilibrium.
    """

    solved_n: float
    low_n: float
    high_n: float
    corners: int

    @property
    def width_n(self) -> float:
        """How much of the value the model leaves open, N (0: the row is determined)."""
        return self.high_n - self.low_n


def plate_force_range(
    model: Model | Manipulator,
    pressure_kpa: float = 0.0,
    settings: BenchSettings | None = None,
    direction: str | None = None,
) -> PlateForceRange:
    """Solve a blocked-force row and bound the total plate force over every rigid equilibrium of
    the solved shape.

    Args:
        model: A manipulator model (clamped on the bench).
        pressure_kpa: Actuation pressure, kPa.
        settings: Bench numerics (scale, gravity, stop height, engine kinematics).
        direction: ``loading`` / ``unloading`` (hysteresis), or None.

    Raises:
        SimulationError: The row has no solved equilibrium, or the programmes fail.
    """
    st = settings or BenchSettings()
    if not math.isfinite(pressure_kpa):
        raise SimulationError(f"pressure_kpa must be finite, got {pressure_kpa}")
    chain = static_chain(
        bench_manipulator(model), st.scale, st.added_inertia_kg_m2, st.stop_z_m, st.engine, st.stop
    )
    approach = {"loading": 1.0, "unloading": -1.0}.get(direction or "", 0.0)
    u = chain.joint_torques(pressure_kpa) - approach * chain.hysteresis
    eq = chain.equilibrium(u, 0.0, st.gravity_m_s2, plate=True)
    if not eq.converged:
        raise SimulationError(f"blocked_force at {pressure_kpa:g} kPa: no solved equilibrium ({eq.cause})")
    net, rows, corners = chain.holding_terms(eq.q, u, 0.0, st.gravity_m_s2)
    if corners == 0:
        return PlateForceRange(eq.force_n, 0.0, 0.0, 0)
    objective = np.zeros(len(rows))
    objective[:corners] = 1.0
    # Without HiGHS's presolve: it called feasible flat fingers infeasible (a 10-link planar finger at
    # 2 kPa, whose balance NNLS meets to 1e-13), the programmes are small.
    bounds = []
    for sign in (1.0, -1.0):
        res = linprog(
            sign * objective,
            A_eq=rows.T,
            b_eq=-net,
            bounds=(0, None),
            method="highs",
            options={"presolve": False},
        )
        if res.status == 3 and sign < 0:  # unbounded: a corner pushing against the clamp
            bounds.append(math.inf)
        elif res.status != 0:
            raise SimulationError(
                f"blocked_force at {pressure_kpa:g} kPa: the plate-force programme failed ({res.message})"
            )
        else:
            bounds.append(float(sign * res.fun))
    return PlateForceRange(eq.force_n, bounds[0], bounds[1], corners)
