"""The design search: Optuna asks designs in batches, successive halving judges them, cheaply first.

Each batch: the optimiser (Optuna's TPE for one objective, NSGA-II with a trade-off; seeded, in
memory) asks ``batch`` designs (:mod:`somo_sweep.design.designs`: moved onto what the task can
express, checked; an infeasible one is told as such through Optuna's constraints and never runs).
The feasible ones are halved over the rungs of objects (:mod:`somo_sweep.design.halving`): each
rung runs their trials on its objects, then replicas, one replica number per round, only of the
cells whose own trial gives the objective's label and whose replicas agree so far, and only for
the designs whose place at the cut is still open; at the last rung every design runs them all.
Then each asked design is told to the optimiser: its robust share over every object when it
reached the last rung, else (one objective) its shares at the rungs it reached, as a pruned trial.

Every decision is a function of the outcomes of the trials the search asked for: the rounds are
batch-synchronous, so the same seed gives the same designs, trials and ranking whatever the worker
count, and a search resumed from its results folder replays them from the stored trials (no
trial repeated) until it reaches the first one not stored. ``budget`` counts every trial the
search asks for (replicas included), stored or not, so a replay spends as the first run did.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from somo_sweep.design.cells import CellState, Outcome, Tally, cell_state, hits, next_replica, reduced
from somo_sweep.design.designs import Design, Designs
from somo_sweep.design.halving import promoted, slots, undecided
from somo_sweep.design.optimiser import Optimiser, Verdict
from somo_sweep.design.study import DesignStudy
from somo_sweep.sweep.jobs.job import Job, JobMaker, param_column
from somo_sweep.sweep.run.sampling import Batch, Known
from somo_sweep.sweep.store.schema import FIXED

__all__ = ["MAX_STALE", "DesignSearch", "Progress", "metric_column"]

#: Batches in a row that ask only designs already judged before the search stops.
MAX_STALE = 3
#: Infeasible designs the record lists (the others are counted).
MAX_LISTED = 100
Values = dict[str, dict[str, Any]]


@dataclass(frozen=True)
class Progress:
    """Where a search is, for a progress line.

    Attributes:
        batch: The optimiser's batch (0 first).
        rung: The rung (0 first) and how many objects it holds.
        kind: ``trials`` or ``replicas``.
        designs: Designs judged at this rung.
        jobs: Simulations in this round.
        spent: Simulations asked so far (this round's included), of ``budget``.
        budget: The budget.
        best: The best complete design so far (its values and tally), or None.
    """

    batch: int
    rung: tuple[int, int]
    kind: str
    designs: int
    jobs: int
    spent: int
    budget: int
    best: tuple[dict[str, Any], Tally] | None


def metric_column(name: str, columns: Sequence[str]) -> str:
    """The results column of a metric (``metric_NAME`` where NAME is also a fixed or parameter column)."""
    return f"metric_{name}" if name in FIXED or name in columns else name


class DesignSearch:
    """The batches of one design search (a :class:`~somo_sweep.sweep.run.session.BatchSource`).

    Args:
        study: The design study.
        progress: Called before each round with where the search is.
    """

    def __init__(self, study: DesignStudy, progress: Callable[[Progress], None] | None = None):
        self.study = study
        self.designs = Designs(study)
        self.progress = progress
        trade = study.trade_off
        self.columns: tuple[str, ...] = ()
        if trade is not None and trade.metric is not None:
            self.columns = (metric_column(trade.metric, _parameter_columns(study)),)
        self.run_info: dict[str, Any] = {
            "sampling": "design",
            "replicas": study.replicas,
            "budget": study.budget,
        }
        self.requested: set[str] = set()
        self.spent = 0
        self.exhausted = False
        self.batch_number = 0
        self.asked = 0
        self.notes: list[str] = []
        self.known: Known = {}
        self.values: Values = {}

    # -- reading outcomes ------------------------------------------------------------------

    def _outcome(self, job: Job) -> Outcome:
        """A trial's outcome once the search has asked for it: a trial stored by an earlier run is
        read only when the replay asks for it again, so the replay spends as that run did."""
        return self.known.get(job.job_id) if job.job_id in self.requested else None

    def state(self, design: Design, obj: int) -> tuple[CellState, list[Outcome]]:
        """A cell's state and its replicas' outcomes (from what is known now)."""
        study, designs = self.study, self.designs
        objective = study.objective
        plain = self._outcome(designs.plain(design, obj))
        replicas: list[Outcome] = []
        if hits(plain, objective.label, objective.value):  # replicas of other cells are never built
            replicas = [self._outcome(designs.replica(design, obj, r)) for r in range(1, study.replicas + 1)]
        return cell_state(plain, replicas, study.replicas, objective.label, objective.value), replicas

    def tally(self, design: Design, objects: Sequence[int]) -> Tally:
        """A design's tally on some objects."""
        return Tally.of(self.state(design, o)[0] for o in objects)

    def trade_value(self, design: Design, objects: Sequence[int]) -> float | None:
        """The trade-off's value of a design on some objects (None: no cell counts yet)."""
        trade = self.study.trade_off
        if trade is None:
            return None
        if trade.variable is not None:
            return float(design.values[trade.variable])
        found = []
        for o in objects:
            if self.state(design, o)[0] is CellState.ROBUST:
                value = self.values.get(self.designs.plain(design, o).job_id, {}).get(self.columns[0])
                if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
                    found.append(float(value))
        return reduced(trade.reduce, found)

    def verdict(self, design: Design, reached: dict[int, int]) -> Verdict:
        """What a feasible design of a batch did (``reached``: each design's last rung)."""
        last = reached.get(design.number, 0)
        sizes = self.study.rungs[: last + 1]
        shares = tuple(self.tally(design, self.study.order[:size]).share for size in sizes)
        trade = self.trade_value(design, self.study.order[: sizes[-1]])
        return Verdict(shares, tuple(sizes), last == len(self.study.rungs) - 1, trade)

    def best(self) -> tuple[Design, Tally] | None:
        """The best design judged on every object with every replica (first registered on a tie)."""
        every = range(self.study.n_objects)
        done = [(d, t) for d in self.designs.numbered if (t := self.tally(d, every)).resolved]
        return max(done, key=lambda dt: (dt[1].robust, -dt[0].number), default=None)

    # -- the rounds ------------------------------------------------------------------------

    def rounds(self, known: Known, values: Values) -> Iterator[Batch]:
        """The rounds still to run (see the module docstring); stored trials are not rerun."""
        self.known, self.values = known, values
        optimiser = Optimiser(self.study)
        stale = 0
        while not self.exhausted:
            before = self.spent
            asked = optimiser.ask(self.study.batch, self.designs.get)
            self.asked += len(asked)
            reached = yield from self._halve([d for _, d in asked])
            if self.exhausted:
                self.notes.append(f"the budget of {self.study.budget} simulations is spent")
                break
            for trial, design in asked:
                optimiser.tell(trial, self.verdict(design, reached) if design.feasible else None)
            self.batch_number += 1
            stale = stale + 1 if self.spent == before else 0
            if stale >= MAX_STALE:
                self.notes.append(
                    f"the search stopped with {self.study.budget - self.spent} simulations of its budget "
                    f"left: {MAX_STALE} batches in a row asked only designs already judged (or infeasible)"
                )
                break

    def _halve(self, asked: Sequence[Design]) -> Generator[Batch, None, dict[int, int]]:
        """Successive halving of one batch's feasible designs; returns each one's last rung."""
        alive = list({d.number: d for d in asked if d.feasible}.values())
        reached: dict[int, int] = {}
        rungs = self.study.rungs
        for r, size in enumerate(rungs):
            objects = self.study.order[:size]
            reached.update((d.number, r) for d in alive)
            where = (r, size)
            plain = [self.designs.plain(d, o) for d in alive for o in objects]
            yield from self._run(plain, "trials", where, len(alive))
            last = r == len(rungs) - 1
            cut = len(alive) if last else slots(len(alive), self.study.reduction)
            while not self.exhausted:
                tallies = {d.number: self.tally(d, objects) for d in alive}
                racing = [d for d in alive if d.number in set(undecided(tallies, cut))] if not last else alive
                jobs = self._open_replicas(racing, objects)
                if not jobs:
                    break
                yield from self._run(jobs, "replicas", where, len(racing))
            if self.exhausted:
                break
            if not last:
                tallies = {d.number: self.tally(d, objects) for d in alive}
                keep = set(promoted(tallies, self.study.reduction))
                alive = [d for d in alive if d.number in keep]
        return reached

    def _open_replicas(self, designs: Sequence[Design], objects: Sequence[int]) -> list[Job]:
        """The next replica of every open cell of ``designs`` on ``objects``."""
        jobs = []
        for d in designs:
            for o in objects:
                state, replicas = self.state(d, o)
                if state is CellState.OPEN:
                    jobs.append(self.designs.replica(d, o, next_replica(replicas, self.study.replicas)))
        return jobs

    def _run(self, jobs: Sequence[Job], kind: str, rung: tuple[int, int], n_designs: int) -> Iterator[Batch]:
        """Spend the trials of one round (each counted once, within the budget); yield those not
        stored yet."""
        new = list({j.job_id: j for j in jobs if j.job_id not in self.requested}.values())
        left = self.study.budget - self.spent
        if len(new) > left:
            new, self.exhausted = new[:left], True
        self.requested.update(j.job_id for j in new)
        self.spent += len(new)
        todo = [j for j in new if j.job_id not in self.known]
        if not todo:
            return
        if self.progress is not None:
            best = self.best()
            self.progress(
                Progress(
                    self.batch_number,
                    rung,
                    kind,
                    n_designs,
                    len(todo),
                    self.spent,
                    self.study.budget,
                    None if best is None else (best[0].values, best[1]),
                )
            )
        yield Batch(self.batch_number, n_designs, todo, kind=kind, replicas=self.study.replicas)

    def _label_note(self) -> list[str]:
        """A note when no trial the search ran gave the objective's label value (a misspelt value?)."""
        objective = self.study.objective
        seen = {
            out[1].get(objective.label)
            for job_id in self.requested
            if (out := self.known.get(job_id)) is not None and out[0] == "ok"
        }
        if not seen or objective.value in seen:
            return []
        given = ", ".join(sorted(str(v) for v in seen if v is not None)) or "none"
        return [f"no trial gave {objective.label} = {objective.value}; its trials gave: {given}"]

    def record(self) -> dict[str, Any]:
        """What the manifest records of the search at the end of a run."""
        best = self.best()
        infeasible = [{"values": d.asked, "why": d.why} for d in self.designs.infeasible[:MAX_LISTED]]
        return {
            "simulations": self.spent,
            "budget": self.study.budget,
            "batches": self.batch_number,
            "designs_asked": self.asked,
            "designs": len(self.designs.numbered),
            "infeasible_designs": len(self.designs.infeasible),
            "best": None
            if best is None
            else {"design": best[0].number, "values": best[0].values, "robust": best[1].robust},
            "infeasible": infeasible,
            "notes": [*self.notes, *self._label_note()],
        }


def _parameter_columns(study: DesignStudy) -> list[str]:
    """The parameter columns of the search's trials: the objects' study's, and the variables'."""
    base = JobMaker(study.base.trial_plan()).job(0)
    return [*base.columns, *(param_column(k) for k in study.keys)]
