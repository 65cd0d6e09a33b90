"""Task ``ihm_gait``: its parameters and registration (light: no PyBullet import)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from somo_sweep.model.load import Model
from somo_sweep.tasks.registry import TaskParams, TaskSpec, register

__all__ = ["GaitParams"]

#: The bundled pressure table (a package data file).
DEFAULT_TABLE = "ihm_gait_setpoints_psi.csv"


class GaitParams(TaskParams):
    """Parameters of the gait task (SI unless named otherwise)."""

    #: Fields naming a table: resolved (and content-hashed) when a study is expanded.
    TABLE_FIELDS: ClassVar[tuple[str, ...]] = ("pressure_table",)

    pressure_table: str = DEFAULT_TABLE
    w_grasp_n_m_per_psi: float = 0.005
    w_side_n_m_per_psi: float = 0.01625
    duration_s: float | None = Field(None, gt=0)
    cube_size_m: float = Field(0.060, gt=0)
    cube_mass_kg: float = Field(0.020, gt=0)
    cube_friction: float = Field(1.2, ge=0)
    palm_height_m: float | None = Field(None, gt=0)
    palm_diameter_m: float | None = Field(None, gt=0)
    cube_offset_std_m: float = Field(0.0, ge=0)
    cube_yaw_std_deg: float = Field(0.0, ge=0)
    record_every_s: float = Field(0.04, gt=0)


#: Arrow type of every metric a trial returns (the results table's schema).
METRICS: dict[str, str] = {
    "final_rot_z_deg": "double",
    "rot_z_per_cycle_deg": "double",
    "max_offaxis_position_m": "double",
    "max_tilt_deg": "double",
    "dropped": "bool",
    "toppled": "bool",
}


#: Control inputs of the hand: four fingers, each a grasp and a side axis (the table's 8 pressures).
N_INPUTS = 8


def check_hand(model: Model) -> list[str]:
    """What the gait needs of its hand: a cylindrical rigid body named 'palm' for the cube to rest
    on, and 8 control inputs (four fingers' grasp and side axes, from the 8 pressure columns)."""
    hand = model.as_assembly()
    needs: list[str] = []
    palms = [b for b in hand.bodies if b.name == "palm"]
    if not palms:
        names = ", ".join(f"'{b.name}'" for b in hand.bodies) or "none"
        needs.append(
            "the ihm_gait task needs a rigid body named 'palm' for the cube to start on; the model's "
            f"bodies: {names}; allowed: an assembly whose bodies include "
            "{name: palm, link: {shape: cylinder, ...}}"
        )
    elif palms[0].link.shape != "cylinder":
        needs.append(
            "the palm must be a cylinder (its radius and height place the cube); "
            f"got shape '{palms[0].link.shape}'; allowed: cylinder"
        )
    if hand.n_inputs != N_INPUTS:
        needs.append(
            f"the ihm_gait task drives {N_INPUTS} inputs (four fingers' grasp and side axes, from the "
            f"pressure table's 8 columns); the model has {hand.n_inputs}"
        )
    return needs


register(
    TaskSpec(
        name="ihm_gait",
        run_path="somo_sweep.tasks.ihm_gait.task:run_ihm_gait",
        params_model=GaitParams,
        description="Four-finger hand turning a cube with a finger gait from a pressure table",
        tags=("paper", "fig5", "manipulation"),
        metrics=METRICS,
        check_model=check_hand,
        labels=("outcome",),
    )
)
