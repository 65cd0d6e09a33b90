"""The bundled diagnosis example: bench data of a finger with one effect the plain model lacks.

``python -m benchmarks.bundled_data diagnosis-example OUT.csv`` (from the repository) writes
``studies/tables/planar_finger_bench_2.csv``: the 36-row plan of the calibration
example (:func:`somo_sweep.calibration.synthetic.example_plan`) simulated at the 0.5 ms
reference step with a hidden effect switched on, plus 1 % noise (seed 7). Which
effect it is stays out of the file; ``somo-sweep diagnose`` is meant to find it
(README, *Finding the missing effect*).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from somo_sweep.calibration.measurements import measurements_csv
from somo_sweep.calibration.synthetic import example_finger, example_plan, synthetic_rows
from somo_sweep.diagnosis.effects import add_effect

__all__ = ["example_csv", "example_rows"]

_HIDDEN = ("actuation_saturation", 250.0**-2)  # 1/kPa²: p_sat = 250 kPa, −23 % torque at 240 kPa
_SEED = 7


def example_rows() -> pd.DataFrame:
    """The example's rows (a DataFrame in the measurement schema)."""
    true = example_finger()
    assert true.manipulator is not None
    manip = add_effect(true.manipulator, *_HIDDEN)
    model = true.model_copy(update={"manipulator": manip})
    return synthetic_rows(model, example_plan(), 0.01, np.random.default_rng(_SEED), n_jobs=2)


def example_csv() -> str:
    """The example (``studies/tables/planar_finger_bench_2.csv``) as CSV text."""
    header = (
        "Synthetic bench data (somo-sweep: python -m benchmarks.bundled_data diagnosis-example): "
        "simulated, NOT measured.\n"
        "Planar finger 100 mm, 20 segments, 20 g; 1 % relative noise. Calibrate it, then run\n"
        "somo-sweep diagnose to see what the calibrated model is missing.\n"
        "finger: {length_mm: 100, segments: 20, mass_g: 20, width_mm: 20, thickness_mm: 15}"
    )
    return measurements_csv(example_rows(), header)
