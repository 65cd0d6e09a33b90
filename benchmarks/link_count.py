"""What a finger's link count costs: one finger cut into N links, its explicit-spring step limit and a
MuJoCo pinch trial's CPU time (``python -m benchmarks.link_count``).

The finger is the grasp-study starter's 70-mm, 12-g finger (``somo_sweep/data/starters``) with its
bending stiffness EI and its mass kept as N changes: each joint gets k = EI·N/L, each link 12 g/N.
For each N it prints the chain's highest natural frequency ω_max (the modal estimate of
:mod:`somo_sweep.sim.modes`), the explicit springs' step limit 2/ω_max (PyBullet: a trial's
steps grow as 1/limit), and the CPU time of one two-finger pinch trial on MuJoCo at 4 ms (the
least of ``--repeats`` after one warm-up, this process's CPU time: it holds under load), with the
trial's labels. How far N links are from the continuous finger: docs/calibration.md,
"Convergence to a continuous finger".
"""

from __future__ import annotations

import argparse
import copy
import time
from typing import Any

import yaml

from benchmarks._cli import echo, int_in, user_errors
from somo_sweep.model.load import model_from_dict
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.modes import chain_matrices
from somo_sweep.sim.settings import MujocoSettings, WorldSettings
from somo_sweep.tasks.pinch_grasp.geometry import finger_mounts, palm_size_m
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams

__all__ = ["finger_of", "main"]

#: The starter finger's length, m, mass, kg, and stiffness: 12 joints of 0.5 N·m/rad.
LENGTH_M, MASS_KG = 0.070, 0.012
EI_N_M2 = 0.5 * LENGTH_M / 12
#: The trial: half the finger distal, a 40-mm box at c = 140 mm, 150 kPa at 1e-3 N·m/kPa.
TRIAL = {"distal_segment_ratio": 0.5, "object_width_m": 0.04, "centering_position_m": 0.140}


def finger_of(n_links: int) -> dict[str, Any]:
    """The starter's finger as data, cut into ``n_links`` links of the same EI and total mass."""
    data = yaml.safe_load(bundled_path("starters", "grasp_study", "finger.yaml").read_text())["manipulator"]
    finger = copy.deepcopy(data)
    act = finger["actuators"][0]
    act["n_segments"] = n_links
    act["link"]["mass_kg"] = MASS_KG / n_links
    act["joints"][0]["stiffness_n_m_per_rad"] = EI_N_M2 * n_links / LENGTH_M
    return finger


def _row(n_links: int, repeats: int) -> str:
    from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

    finger = finger_of(n_links)
    manip = model_from_dict({"manipulator": finger}).manipulator
    assert manip is not None
    omega = chain_matrices(manip).modes().highest_rad_s
    palm = {"shape": "box", "size_m": list(palm_size_m(2)), "mass_kg": 0.2}
    mounts = [
        {"name": m.name, "manipulator": finger, "pose": {"position_m": m.position_m, "rpy_rad": m.rpy_rad}}
        for m in finger_mounts(2)
    ]
    gripper = {"name": "g", "base": {"mode": "driven", "link": palm}, "manipulators": mounts}
    hand = model_from_dict({"assembly": gripper})
    params = PinchGraspParams(**TRIAL, pressure_kpa=150, early_stop=False)
    settings = WorldSettings(time_step_s=4e-3, engine_settings=MujocoSettings())
    cpu = []
    for _ in range(repeats + 1):
        t0 = time.process_time()
        result = run_pinch_grasp(hand, params, settings)
        cpu.append(time.process_time() - t0)
    labels = f"{result.labels.get('grasp')} / {result.labels.get('grasp_paper')}"
    return f"| {n_links} | {omega:,.0f} | {2 / omega * 1e3:.3f} | {min(cpu[1:]):.2f} | {labels} |"


def main(argv: list[str] | None = None) -> None:
    """Print the table for each link count."""
    summary = (__doc__ or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog="python -m benchmarks.link_count", description=summary)
    parser.add_argument("--links", type=int_in(2, 60), nargs="+", default=[6, 12, 24, 48])
    parser.add_argument("--repeats", type=int_in(1, 20), default=3)
    args = parser.parse_args(argv)
    with user_errors():
        head = "| links N | ω_max (rad/s) | 2/ω_max (ms) | MuJoCo trial CPU (s) | labels (contacts / paper) |"
        echo([head, "|---|---|---|---|---|"])
        echo(_row(n, args.repeats) for n in args.links)


if __name__ == "__main__":
    main()
