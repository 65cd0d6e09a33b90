"""Studies: which task to run on which model, and the axes to sweep (the public names).

A study file is described in :mod:`somo_sweep.sweep.study.file`; :func:`load_study` reads and
checks one (:mod:`somo_sweep.sweep.study.loading`) into a frozen :class:`Study`
(:mod:`somo_sweep.sweep.study.loaded`); :mod:`somo_sweep.sweep.study.derive` makes variants of it.
"""

from __future__ import annotations

from somo_sweep.sweep.study.derive import derive_study, with_auto_step, with_replicas, with_sampling
from somo_sweep.sweep.study.file import (
    MAX_REPLICAS,
    MAX_TRIALS,
    RESULTS_ROOT,
    Adaptive,
    Robustness,
    Simulation,
    StudyFile,
)
from somo_sweep.sweep.study.loaded import Study
from somo_sweep.sweep.study.loading import load_study
from somo_sweep.sweep.study.resolve import MODEL_CACHE, PARAMS_CACHE, RecentCache, load_model_dict

__all__ = [
    "MAX_REPLICAS",
    "MAX_TRIALS",
    "MODEL_CACHE",
    "PARAMS_CACHE",
    "RESULTS_ROOT",
    "Adaptive",
    "RecentCache",
    "Robustness",
    "Simulation",
    "Study",
    "StudyFile",
    "derive_study",
    "load_model_dict",
    "load_study",
    "with_auto_step",
    "with_replicas",
    "with_sampling",
]
