"""The designs of a search: each asked once, moved onto what the task can express, checked, numbered.

A design is one value per design variable. Before it runs, the task moves the values it cannot
express to the nearest it can (:mod:`~somo_sweep.tasks.snapping`: a distal segment
ratio onto the fingers' link boundaries), and the design is checked as a study of its objects
would be at load (:func:`~somo_sweep.sweep.study.checks.check_points`): one that fails is
*infeasible*, with the reason, and never runs. Designs that come out the same after the move are
one design.

Each feasible design gets the next number, and its trials are those of a grid study of the same
file with the design's values as one-value sweep axes and the objects as the others: the same
ids and seeds (a job is a pure function of its parameters and seed), so a grid of these
designs, run on its own, holds the very trials the search ran. Design n's trial on object o is
numbered ``n × objects + o`` in the results folder.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from typing import Any

from somo_sweep.design.study import DesignStudy
from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.sweep.jobs.job import Job, JobMaker, replica_jobs
from somo_sweep.sweep.study import Study
from somo_sweep.sweep.study.axes import Axis
from somo_sweep.sweep.study.checks import check_points
from somo_sweep.tasks.snapping import snap_of

__all__ = ["Design", "Designs", "design_key", "design_study"]


def design_key(values: dict[str, Any]) -> str:
    """What makes two designs the same: their values, numbers by value (1 == 1.0)."""

    def same(v: Any) -> Any:
        return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else v

    return json.dumps({k: same(v) for k, v in values.items()}, sort_keys=True, default=repr)


def design_study(base: Study, values: dict[str, Any]) -> Study:
    """The grid study of one design: its values as one-value axes (first), then the objects."""
    axes = tuple(Axis(k, (v,)) for k, v in values.items())
    return replace(base, axes=axes + base.axes, groups=(tuple(values), *base.groups))


@dataclass
class Design:
    """One design of a search.

    Attributes:
        number: Its number (the order designs were first asked), or -1 when infeasible.
        values: The values it runs (as the task can express them), by key path.
        asked: The values first asked for it.
        why: Why it is infeasible ("" when feasible).
    """

    number: int
    values: dict[str, Any]
    asked: dict[str, Any]
    why: str = ""
    _maker: JobMaker | None = field(default=None, repr=False)
    _jobs: dict[int, Job] = field(default_factory=dict, repr=False)
    _replicas: dict[int, list[Job]] = field(default_factory=dict, repr=False)

    @property
    def feasible(self) -> bool:
        """Whether it can run."""
        return not self.why


class Designs:
    """Every design a search asked for, by its values (each checked and numbered once).

    Args:
        study: The design study.
    """

    def __init__(self, study: DesignStudy):
        self.study = study
        self.by_key: dict[str, Design] = {}
        self.numbered: list[Design] = []
        self.infeasible: list[Design] = []

    def get(self, asked: dict[str, Any]) -> Design:
        """The design of values asked by the optimiser (moved, checked and numbered at first ask)."""
        key = design_key(asked)
        if key in self.by_key:
            return self.by_key[key]
        values, why = self._expressed(asked)
        moved = design_key(values)
        design = self.by_key.get(moved)
        if design is None:
            design = Design(-1 if why else len(self.numbered), values, dict(asked), why)
            if why:
                self.infeasible.append(design)
            else:
                design._maker = JobMaker(design_study(self.study.base, values).trial_plan())
                self.numbered.append(design)
            self.by_key[moved] = design
        self.by_key[key] = design
        return design

    def _expressed(self, asked: dict[str, Any]) -> tuple[dict[str, Any], str]:
        """The values the task can express nearest those asked, and why they cannot run ("" if
        they can)."""
        study = self.study
        values = dict(asked)
        grid = design_study(study.base, values)
        task = grid.task
        try:
            resolver = grid.resolver()
            point = grid.point_at(0)
            _, model = resolver.model(point)
            params = resolver.params(point)
        except DescriptionError as exc:
            return values, _reason(exc.problems)
        snap = snap_of(task)
        moves = snap(model, params) if snap is not None else {}
        for name, value in moves.items():
            key = f"task.{name}"
            if key not in values:
                continue  # a fixed value the model cannot express: the checks below say why
            variable = study.variable(key)
            if not variable.contains(value):
                span = variable.bounds()
                return values, (
                    f"{key} {values[key]!r} is expressed as {value!r}, outside the variable's "
                    f"{'range' if span is None else f'{span[0]:g} … {span[1]:g}'}"
                )
            values[key] = value
        if moves:
            grid = design_study(study.base, values)
        problems: list[Problem] = []
        check_points(grid, {}, problems)
        return values, _reason(problems) if problems else ""

    def plain(self, design: Design, obj: int) -> Job:
        """The trial of a feasible design on object ``obj`` (grid order of the objects)."""
        if obj not in design._jobs:
            assert design._maker is not None, "an infeasible design has no trials"
            job = design._maker.job(obj)
            design._jobs[obj] = replace(job, trial=design.number * self.study.n_objects + obj)
        return design._jobs[obj]

    def replica(self, design: Design, obj: int, number: int) -> Job:
        """Replica ``number`` (1 … K) of a design's trial on object ``obj``."""
        if obj not in design._replicas:
            perturb = self.study.base.task.perturb
            assert perturb is not None  # refused when the study loads
            design._replicas[obj] = replica_jobs(self.plain(design, obj), self.study.replicas, perturb)
        return design._replicas[obj][number - 1]


def _reason(problems: list[Problem]) -> str:
    """Problems as one line (the first three)."""
    shown = "; ".join(p.message if not p.path else f"{p.path}: {p.message}" for p in problems[:3])
    more = f" (and {len(problems) - 3} more)" if len(problems) > 3 else ""
    return shown + more
