"""Task ``whole_arm``: its parameters and registration (light: no PyBullet import)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from somo_sweep.model.load import Model
from somo_sweep.tasks.registry import TaskParams, TaskSpec, register

__all__ = ["WholeArmParams", "check_torque_table", "torque_columns"]

#: The bundled torque table (a package data file).
DEFAULT_TABLE = "whole_arm_torques_n_m.csv"


class WholeArmParams(TaskParams):
    """Parameters of the whole-arm task (SI).

    The default ball is a scaled, light basketball: radius 45 mm, 50 g, a thin shell
    (I = 2/3·m·r²). A real one (120 mm, 600 g) would need a much larger arm.
    """

    #: Fields naming a table: resolved (and content-hashed) when a study is expanded.
    TABLE_FIELDS: ClassVar[tuple[str, ...]] = ("torque_table",)

    torque_table: str = DEFAULT_TABLE
    torque_scale: float = Field(1.0, ge=0)  # 0 runs the control: the arm never moves
    duration_s: float | None = Field(None, gt=0)  # default: the table's end
    mount_height_m: float = Field(1.0, gt=0)
    ball_position_m: tuple[float, float, float] = (0.065, 0.0, 0.54)
    ball_radius_m: float = Field(0.045, gt=0)
    ball_mass_kg: float = Field(0.05, gt=0)
    ball_friction: float = Field(1.0, ge=0)
    hoop_centre_m: tuple[float, float, float] = (-0.38, 0.0, 0.55)
    hoop_inner_radius_m: float = Field(0.09, gt=0)
    record_every_s: float = Field(0.01, gt=0)


#: Arrow type of every metric a trial returns (the results table's schema).
METRICS: dict[str, str] = {
    "ball_passed_hoop": "bool",
    "ball_max_lift_m": "double",
    "hoop_crossing_offset_m": "double",
    "hoop_crossing_time_s": "double",
    "hoop_allowed_offset_m": "double",
    "ball_touched_rim": "bool",
    "ball_final_height_m": "double",
}


def check_manipulator(model: Model) -> list[str]:
    """The task runs a single manipulator (the arm is one manipulator), not an assembly."""
    if model.manipulator is not None:
        return []
    return [
        "the whole_arm task needs a model with a 'manipulator' section; got an assembly "
        f"('{model.as_assembly().name}'); allowed: a manipulator model"
    ]


def torque_columns(input_names: list[str]) -> list[str]:
    """The torque table's columns for a loaded arm's inputs (``<arm>/<actuator>/<axis>``).

    ``time_s``, then ``<actuator>_<axis>_n_m`` for each input.
    """
    return ["time_s"] + ["_".join(n.split("/")[1:]) + "_n_m" for n in input_names]


def check_torque_table(model: Model, params: WholeArmParams) -> list[str]:
    """The torque table has one column per input of the model, in input order (read: its header)."""
    if model.manipulator is None:
        return []  # check_manipulator says so
    import io

    import pandas as pd

    from somo_sweep.errors import SomoError
    from somo_sweep.model.tables import read_table_text

    arm = model.manipulator
    want = torque_columns([f"{arm.name}/{name}" for name in arm.input_names])
    try:
        name, text = read_table_text(params.torque_table)
        got = [str(c) for c in pd.read_csv(io.StringIO(text), comment="#", nrows=0).columns]
    except SomoError as exc:
        return [str(exc)]
    except (ValueError, pd.errors.ParserError) as exc:
        return [f"torque_table: cannot read its header ({str(exc).splitlines()[0]})"]
    if got == want:
        return []
    return [
        f"torque_table {name} does not fit the model's {len(want) - 1} inputs: columns must be "
        f"{', '.join(want)}; got {', '.join(got) or 'none'}"
    ]


register(
    TaskSpec(
        name="whole_arm",
        run_path="somo_sweep.tasks.whole_arm.task:run_whole_arm",
        params_model=WholeArmParams,
        description="Continuum arm wraps a ball, lifts it and drops it through a hoop (scripted torques)",
        tags=("paper", "fig7", "manipulation"),
        metrics=METRICS,
        check_model=check_manipulator,
        check_params=check_torque_table,
        labels=("outcome",),
    )
)
