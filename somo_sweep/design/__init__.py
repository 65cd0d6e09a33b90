"""Design search: which design to build, searched against robust labels (``somo-sweep design``).

A design study (:mod:`somo_sweep.design.study`) names design variables, the objects a design is
judged on and an objective (the robust share of a label over the objects, optionally against a
trade-off); :func:`load_design` reads and checks one; :func:`run_design` searches it into a results
folder (Optuna, successive halving over the objects, replicas only where they can change a rank;
:mod:`somo_sweep.design.search`), every simulation a row of the folder's trials table;
:func:`rank_designs` ranks the designs the folder holds.
"""

from __future__ import annotations

from somo_sweep.design.loading import load_design
from somo_sweep.design.ranking import rank_designs, wilson
from somo_sweep.design.run import DesignRun, design_table, run_design
from somo_sweep.design.search import DesignSearch, Progress
from somo_sweep.design.study import DesignStudy

__all__ = [
    "DesignRun",
    "DesignSearch",
    "DesignStudy",
    "Progress",
    "design_table",
    "load_design",
    "rank_designs",
    "run_design",
    "wilson",
]
