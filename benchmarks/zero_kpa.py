"""Why the 0-kPa blocked-force row differs between engines: a step ladder, with the bench's plate and
with the plate starting further from the clamp.

At 0 kPa the bench's blocked-force protocol lays the unpressurised finger on a frictionless plate.
The pinch finger's side joints pair its links into rigid bodies that rest on three corner lines
each, so rigid statics leaves the split of the weight between clamp and plate open over an interval
(printed with the solved value; :mod:`somo_sweep.statics.plate_force_range`), and each engine's
contact regularisation picks a point in or near it. This script prints
``run_bench(..., "blocked_force", p)`` on PyBullet and MuJoCo at 1, 0.5, 0.25 and 0.125 ms, and the
solved statics, at 0 and 25 kPa: once with the bench's plate, then with the plate starting
``--plate-starts`` segments past the clamp (an experiment: the bench itself keeps its plate). A gap
that stays as the step shrinks is not a step error.

Run from the repository root: ``python -m benchmarks.zero_kpa`` (``make bench-zero-kpa``, 2-3 min;
``--plate-starts 0.25,0.5,1 --steps 5e-4`` for the plate at several starts, one step; MuJoCo needs
the ``[mujoco]`` extra).

The package has no setting for where the plate starts along the finger (only for its height,
``BenchSettings.stop_z_m``), so the experiment swaps the bench's plate geometry
(``stop_geometry``) in this process while it runs, and restores it after.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

import somo_sweep.statics.chain_kinematics as chain_kinematics
import somo_sweep.statics.relaxation as relaxation
import somo_sweep.statics.solve as statics
from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.statics.bench import BenchSettings, run_bench
from somo_sweep.statics.plate_force_range import plate_force_range

GRAVITY_M_S2 = 9.81


def _segment_m(manip: Manipulator) -> float:
    """Length of the first actuator's segments, m."""
    first = manip.actuators[0]
    if first.n_segments is None:
        raise SystemExit("this script needs actuators with n_segments")
    return first.length_m / first.n_segments


@contextmanager
def plate_past_first_segment(segments: float = 1.0) -> Iterator[None]:
    """The bench's plate, starting ``segments`` segments of the first actuator past the clamp."""
    original = relaxation.stop_geometry

    def shifted(
        manip: Manipulator, origin_m: np.ndarray, tip_x_m: float, stop_z_m: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        centre, half = original(manip, origin_m, tip_x_m, stop_z_m)
        start_m = float(origin_m[0]) + segments * _segment_m(manip)
        end_m = float(centre[0] + half[0])
        centre, half = centre.copy(), half.copy()
        centre[0], half[0] = (start_m + end_m) / 2, (end_m - start_m) / 2
        return centre, half

    # The solved statics caches each finger's chain with its plate: start and end without it.
    statics.clear_cache()
    relaxation.stop_geometry = chain_kinematics.stop_geometry = shifted
    try:
        yield
    finally:
        relaxation.stop_geometry = chain_kinematics.stop_geometry = original
        statics.clear_cache()


def _ladder(model_path: str, steps_s: tuple[float, ...] = (1e-3, 5e-4, 2.5e-4, 1.25e-4)) -> None:
    model = load_model(model_path)
    for pressure_kpa in (0.0, 25.0):
        solved = run_bench(model, "blocked_force", pressure_kpa, 0.0, BenchSettings(), statics="solve").value
        held = plate_force_range(model, pressure_kpa)
        print(
            f"  {pressure_kpa:g} kPa, solved statics: {solved:.5f} N; rigid statics admits "
            f"{held.low_n:.5f} .. {held.high_n:.5f} N ({held.corners} corners on the plate)"
        )
        for engine in ("pybullet", "mujoco"):
            values = []
            for step_s in steps_s:
                settings = BenchSettings(time_step_s=step_s, scale=20.0, engine=engine)
                values.append(
                    run_bench(model, "blocked_force", pressure_kpa, 0.0, settings, statics="dynamic").value
                )
            print(
                f"    {engine:8s} at {' / '.join(f'{s * 1e3:g}' for s in steps_s)} ms: "
                + " / ".join(f"{v:.5f}" for v in values)
                + " N"
            )


def main(argv: list[str] | None = None) -> None:
    """Print the finger's weight, then the ladder with the bench's plate and with each plate start."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.zero_kpa", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--model", default=str(bundled_path("models", "pinch_finger.yaml")))
    parser.add_argument(
        "--plate-starts",
        default="1",
        help="comma-separated plate starts past the clamp for the experiment, in segments (default 1)",
    )
    parser.add_argument(
        "--steps",
        default="1e-3,5e-4,2.5e-4,1.25e-4",
        help="comma-separated time steps, s (default: the ladder)",
    )
    args = parser.parse_args(argv)
    steps_s = tuple(float(v) for v in args.steps.split(","))
    manip = load_model(args.model).manipulator
    if manip is None:
        raise SystemExit(f"{args.model} has no manipulator")
    _segment_m(manip)
    masses_kg = [a.link.mass_kg * (a.n_segments or 0) for a in manip.actuators]
    weight_n = (sum(masses_kg) + sum(t.mass_kg for t in manip.tip_links)) * GRAVITY_M_S2
    segment_n = manip.actuators[0].link.mass_kg * GRAVITY_M_S2
    print(f"finger weight {weight_n:.4f} N; one proximal segment {segment_n:.4f} N")
    print("plate from the clamp (the bench):")
    _ladder(args.model, steps_s)
    for start in (float(v) for v in args.plate_starts.split(",")):
        print(f"plate from {start:g} segment(s) past the clamp (experiment):")
        with plate_past_first_segment(start):
            _ladder(args.model, steps_s)


if __name__ == "__main__":
    main()
