"""The speed benchmark (``make bench``): grasp steps, one trial, bench statics, sweep scaling.

``python -m benchmarks.speed`` prints, in one run:

* ms per step of the two-finger grasp, Bullet vs our Python: the pinch-grasp gripper (20 links
  per finger) closing on and lifting a 40 mm box; the split is measured in the same run: time
  inside ``stepSimulation`` is Bullet's, everything else in the loop is ours;
* one pinch-grasp trial at the chosen numerics against the original's, in turn
  (:func:`benchmarks.numerics.trial_timing_lines`);
* the bench statics (:mod:`benchmarks.statics`);
* the sweep's scaling over workers and Dask against joblib (:mod:`benchmarks.scaling`;
  ``--no-scaling`` leaves it out).

``--convergence`` prints the time-step convergence table of a damped finger instead.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from time import perf_counter

import numpy as np

from benchmarks._cli import echo, int_in
from benchmarks.numerics import trial_timing_lines
from benchmarks.scaling import scaling_report
from benchmarks.statics import statics_lines
from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import load_model
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.planner import plan_rigid_body
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.worlds import open_world

__all__ = ["convergence_lines", "gripper_step_timing", "main", "speed_lines", "time_step_convergence"]

MODELS = bundled_path("models")


def gripper_step_timing(
    duration_s: float = 2.5, time_step_s: float = 5e-4, model_path: Path | None = None
) -> dict[str, float]:
    """Run the grasp scene once; returns ms per step (total, Bullet, Python) and the lift in m."""
    model = load_model(model_path or MODELS / "pinch_gripper.yaml")
    with open_world(WorldSettings(time_step_s=time_step_s)) as world:
        world.add_ground(friction=1.0)
        box = RigidBody(
            name="object",
            link=Link(shape="box", size_m=(0.04, 0.06, 0.06), mass_kg=0.02, friction={"lateral": 2.0}),
            pose=Pose(position_m=(0.0, 0.0, 0.0301)),
        )
        obj = world.load_plan(plan_rigid_body(box))
        hand = world.add_model(model, Pose(position_m=(0.10, 0.0, 0.035)))
        torque = SetpointTable([0.0, 0.3, 1.3], [[0.0, 0.0], [0.0, 0.0], [0.15, 0.15]])
        start_pose, lifted = [0.10, 0.0, 0.035, 0.0, 0.0, 0.0], [0.10, 0.0, 0.11, 0.0, 0.0, 0.0]
        world.follow(
            hand, inputs=torque, base=SetpointTable([0.0, 1.4, 2.4], [start_pose, start_pose, lifted])
        )
        steps = round(duration_s / time_step_s)
        start = perf_counter()
        world.step(steps)
        total = perf_counter() - start
        z_obj = float(world.base_pose(obj.id)[0][2])
    bullet = world.engine_time_s
    return {
        "steps": steps,
        "ms_per_step": 1e3 * total / steps,
        "bullet_ms_per_step": 1e3 * bullet / steps,
        "python_ms_per_step": 1e3 * (total - bullet) / steps,
        "python_over_bullet": (total - bullet) / bullet,
        "object_lift_m": z_obj - 0.0301,
    }


def time_step_convergence(
    steps_s: tuple[float, ...] = (1.25e-4, 2.5e-4, 5e-4, 1e-3, 2e-3), at_s: float = 0.25
) -> list[tuple[float, float | None]]:
    """Tip-position error of a step response against the finest step, per time step.

    The damped IHM finger (viscous damping 0.01 N·m·s/rad, 1e-5 kg·m² inertia
    shaping, no motor limit, no gravity) gets a 0.05 N·m grasp input; the tip
    position at ``at_s`` is compared. Returns ``(dt, error_m or None if unstable)``.
    """
    from somo_sweep.errors import UnstableSimulation
    from somo_sweep.model.load import model_from_dict

    data = load_model(MODELS / "ihm_finger.yaml").model_dump(mode="json", exclude_none=True)
    act = data["manipulator"]["actuators"][0]
    act["link"]["added_inertia_kg_m2"] = 1e-5
    for joint in act["joints"]:
        joint["motor_limit_n_m"], joint["damping_n_m_s_per_rad"] = 0.0, 0.01
    model = model_from_dict(data)
    tips: dict[float, np.ndarray | None] = {}
    for dt in steps_s:
        with open_world(WorldSettings(time_step_s=dt, gravity_m_s2=(0.0, 0.0, 0.0))) as world:
            handle = world.add_model(model)
            handle.set_inputs([0.05, 0.0])
            try:
                world.step(round(at_s / dt))
                tips[dt] = world.tip_position(handle.bodies[0])
            except UnstableSimulation:
                tips[dt] = None
    ref = tips[steps_s[0]]
    assert ref is not None
    return [(dt, None if tip is None else float(np.linalg.norm(tip - ref))) for dt, tip in tips.items()]


def speed_lines(repeats: int = 3) -> list[str]:
    """The step timing of the grasp scene and of one pinch-grasp trial, as printable lines."""
    runs = [gripper_step_timing() for _ in range(repeats)]
    best = min(runs, key=lambda r: r["ms_per_step"])
    med = {k: float(np.median([r[k] for r in runs])) for k in best}
    return [
        f"two-finger gripper (20 links/finger) grasping a box, {int(best['steps'])} steps at 0.5 ms, "
        f"median of {repeats} runs:",
        f"  total  {med['ms_per_step']:.4f} ms/step",
        f"  Bullet {med['bullet_ms_per_step']:.4f} ms/step (inside stepSimulation)",
        f"  Python {med['python_ms_per_step']:.4f} ms/step (springs, inputs, base drive, checks)",
        f"  Python / Bullet = {100 * med['python_over_bullet']:.1f} %",
        f"  object lifted {1e3 * med['object_lift_m']:.1f} mm",
        *trial_timing_lines(repeats),
    ]


def convergence_lines() -> list[str]:
    """The time-step convergence table of the grasp scene, as printable lines."""
    lines = ["time step (ms)  tip error vs 0.125 ms (mm)"]
    for dt, err in time_step_convergence():
        lines.append(f"{dt * 1e3:13.3f}  {'unstable' if err is None else f'{err * 1e3:.4f}'}")
    return lines


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.speed``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.speed",
        description="The speed benchmark: grasp steps (Bullet vs Python), one trial vs the original's "
        "numerics, bench statics, sweep scaling (parallel efficiency, Dask vs joblib).",
    )
    ap.add_argument(
        "--repeats", type=int_in(1, 100), default=3, help="timed runs per measurement (default 3)"
    )
    ap.add_argument(
        "--convergence", action="store_true", help="only the time-step convergence table of a damped finger"
    )
    ap.add_argument(
        "--scaling",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="time the 24-trial demo sweep (0.5 ms) at 1 and 2 workers, and at 2 workers joblib against "
        "a 2-worker Dask LocalCluster in turn (joblib, Dask, Dask, joblib) (default: on)",
    )
    ap.add_argument(
        "--quick-study",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="with --scaling, Dask against joblib on the quick study's 192 cells at 4 ms too (default: on)",
    )
    return ap


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and print its lines as they come."""
    args = parser().parse_args(argv)
    if args.convergence:
        echo(convergence_lines())
        return
    echo(speed_lines(args.repeats))
    echo(statics_lines())
    if args.scaling:
        scaling_report(quick_study=args.quick_study)


if __name__ == "__main__":
    main()
