"""The design benchmark's oracle: an exhaustive robust grid, looked up instead of simulated.

The grid (``results/reference/design_bench/grid.yaml``: every design of the benchmark's space on
every object, each cell with all its replicas) is stored as one row per run
(:func:`export_cells`). The oracle answers a trial by its design, object and replica number, so
three ways of looking for the best design can be replayed in seconds and compared by the
simulations each would have run:

* ``design``: :class:`~somo_sweep.design.search.DesignSearch` itself, its rounds answered by the
  oracle (the same code as ``somo-sweep design``, seeded);
* ``random``: designs drawn at random from the same space (moved onto what the task expresses, as
  the search does), each judged on every object;
* ``grid``: every design in the grid's order, each judged on every object.

A design judged on every object costs, per object, its trial and, where the trial gives the
objective's label, its replicas up to the first that disagrees: the search's own policy at its last
rung, so the baselines pay no replica the search would not.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.design.cells import CellState, cell_state
from somo_sweep.design.designs import Design, Designs
from somo_sweep.design.search import DesignSearch
from somo_sweep.design.study import DesignStudy
from somo_sweep.design.variables import as_asked
from somo_sweep.sweep.jobs.job import Job, param_column

__all__ = ["Curve", "Oracle", "design_curve", "export_cells", "grid_curve", "random_curve", "replay"]

#: Decimals a value keeps in the oracle's keys (the stored values are the simulated ones).
DIGITS = 9
#: (simulations spent, best robust share found so far) after each step of a method.
Curve = list[tuple[int, float]]


def _columns(study: DesignStudy) -> list[str]:
    return [param_column(k) for k in (*study.keys, *study.objects)]


def export_cells(table: pd.DataFrame, study: DesignStudy) -> pd.DataFrame:
    """The grid's runs as the oracle stores them: the design's and object's values, the replica,
    the status and the objective's label, sorted."""
    label = f"label_{study.objective.label}"
    keep = [*_columns(study), "replica", "status", label]
    cells = table[keep].copy()
    cells["replica"] = pd.to_numeric(cells["replica"]).fillna(0).astype(int)
    return cells.sort_values(keep[:-2], kind="stable").reset_index(drop=True)


@dataclass
class Oracle:
    """The stored grid, answering trials.

    Args:
        cells: :func:`export_cells`'s table.
        study: The benchmark's design study.
    """

    cells: pd.DataFrame
    study: DesignStudy

    def __post_init__(self) -> None:
        label = f"label_{self.study.objective.label}"
        self.columns = _columns(self.study)
        self.runs: dict[tuple[Any, ...], tuple[str, dict[str, str]]] = {}
        for values in self.cells.to_dict("records"):
            key = self._key(values, int(values["replica"]))
            labels = {} if pd.isna(values[label]) else {self.study.objective.label: str(values[label])}
            self.runs[key] = (str(values["status"]), labels)

    def _key(self, values: dict[str, Any], replica: int) -> tuple[Any, ...]:
        return (*(round(float(values[c]), DIGITS) for c in self.columns), replica)

    def outcome(self, job: Job) -> tuple[str, dict[str, str]]:
        """A trial's (status, labels), as the grid stored it.

        Raises:
            KeyError: The trial is not in the grid (the search left the benchmark's space).
        """
        return self.runs[self._key(job.columns, job.replica)]

    def judged(self, designs: Designs, design: Design) -> tuple[int, int]:
        """(objects robust, simulations) of a design judged on every object, replicas stopping at
        the first that disagrees."""
        k, label, value = self.study.replicas, self.study.objective.label, self.study.objective.value
        robust = cost = 0
        for obj in range(self.study.n_objects):
            plain = self.outcome(designs.plain(design, obj))
            cost += 1
            replicas: list[Any] = []
            if cell_state(plain, [], k, label, value) is not CellState.MISS:
                for number in range(1, k + 1):
                    replicas.append(self.outcome(designs.replica(design, obj, number)))
                    cost += 1
                    if cell_state(plain, replicas, k, label, value) is CellState.BROKEN:
                        break
            robust += cell_state(plain, replicas, k, label, value) is CellState.ROBUST
        return robust, cost


def replay(study: DesignStudy, oracle: Oracle) -> tuple[DesignSearch, Curve]:
    """The search answered by the oracle, and its curve: after each of its rounds, the simulations
    spent and the best robust share of a design judged on every object."""
    search = DesignSearch(study)
    known: dict[str, tuple[str, dict[str, str]]] = {}
    curve: Curve = []
    for batch in search.rounds(known, {}):
        for job in batch.jobs:
            known[job.job_id] = oracle.outcome(job)
        best = search.best()
        if best is not None:  # no design judged on every object yet: nothing found
            curve.append((search.spent, best[1].robust / study.n_objects))
    return search, curve


def design_curve(study: DesignStudy, oracle: Oracle) -> Curve:
    """The search's curve against the oracle (:func:`replay`)."""
    return replay(study, oracle)[1]


def _judge_all(study: DesignStudy, oracle: Oracle, asked: Iterator[dict[str, Any]], budget: int) -> Curve:
    """Designs judged on every object in the order asked, until ``budget`` simulations (a design
    asked again costs nothing)."""
    designs = Designs(study)
    seen: set[int] = set()
    spent, best, curve = 0, 0.0, []
    for values in asked:
        design = designs.get(values)
        if not design.feasible or design.number in seen:
            continue
        seen.add(design.number)
        robust, cost = oracle.judged(designs, design)
        if spent + cost > budget:
            break
        spent += cost
        best = max(best, robust / study.n_objects)
        curve.append((spent, best))
    return curve


def grid_curve(study: DesignStudy, oracle: Oracle) -> Curve:
    """Every design of the grid, in its order (the grid study's first axis slowest)."""
    keys = [param_column(k) for k in study.keys]
    order = oracle.cells[keys].drop_duplicates()
    asked = (
        {k: as_asked(study.variable(k), _plain(row[c])) for k, c in zip(study.keys, keys, strict=True)}
        for _, row in order.iterrows()
    )
    return _judge_all(study, oracle, asked, budget=10**9)


def random_curve(study: DesignStudy, oracle: Oracle, seed: int, budget: int) -> Curve:
    """Designs drawn uniformly from the space (a range uniformly, a choice with equal odds)."""
    rng = np.random.default_rng([seed, 0x52414E44])

    def draws() -> Iterator[dict[str, Any]]:
        while True:
            values: dict[str, Any] = {}
            for v in study.variables:
                if v.kind == "choices":
                    values[v.key] = v.choices[int(rng.integers(len(v.choices)))]
                elif v.kind == "int":
                    steps = round((v.high - v.low) / (v.step or 1))
                    values[v.key] = int(v.low + (v.step or 1) * int(rng.integers(steps + 1)))
                else:
                    values[v.key] = float(rng.uniform(v.low, v.high))
            yield values

    return _judge_all(study, oracle, draws(), budget)


def _plain(value: Any) -> Any:
    """A table's value as a plain Python one (NumPy scalars unwrapped)."""
    return value.item() if isinstance(value, np.generic) else value
