"""Robustness replicas: which cells to replicate, and each cell's majority label and agreement.

A label printed for one trial is a fact only if a small change of the trial keeps it. A study
with ``robustness: {replicas: K}`` (or ``somo-sweep run --robust K``) runs K replicas of the
cells that matter (:class:`ReplicaPlan`): each replica is the task's own small perturbation of
the trial (:attr:`~somo_sweep.tasks.registry.TaskSpec.perturb`), the odd-numbered ones at half
the time step (:func:`~somo_sweep.sweep.jobs.table.replica_jobs`). Replicas are stored as trials of
their own (``replica`` 1 … K, the cell's ``trial`` and grid values); :func:`fold` turns a
results table into one row per cell with, for every label L, ``label_L_majority`` (the most
common outcome of the cell's runs, its own trial's on a tie), ``label_L_agreement`` (the share
of the runs that give it) and ``robust`` (every run of the cell gives the same outcome on every
label; missing for cells without replicas). A run that did not finish ``ok`` counts as the
outcome of its status.

A cell is robust only when all its planned replicas ran. The planned count is the one the
folder's latest run that ran replicas asked for (its manifest entry's ``replicas``,
:func:`~somo_sweep.sweep.store.folder.planned_replicas`); a run cut short leaves cells with fewer,
or none yet: they *await replicas* (``replicas_awaited`` > 0) and are not robust until a resumed
run adds the rest (``robust`` stays missing, or False if the runs stored already disagree).
Which cells the plan chose is replayed from the stored outcomes (:class:`ReplicaChoice`, which
the run records in its manifest entry; :mod:`somo_sweep.sweep.run.replica_state`). Replicas
numbered above the planned count (stored by an earlier run that asked for more) are left out,
so the readers fold what the latest run reported.

Which cells (``where``): ``all`` replicates every simulated cell. ``boundary`` (default)
replicates the cells whose outcome differs from a grid neighbour's (along any axis, same
repeat), plus a seeded random audit of ``audit_fraction`` of the other simulated cells; then,
as long as a replicated cell's majority differs from its own trial's outcome, the neighbours
that this makes boundary cells are replicated too. The choice depends only on stored outcomes,
so a resumed run replays it without rerunning anything.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Callable, Collection, Iterator, Sequence
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.sweep.jobs.job import Job, replica_jobs
from somo_sweep.sweep.jobs.table import JobTable
from somo_sweep.sweep.run.adaptive import UNKNOWN
from somo_sweep.sweep.run.sampling import Batch, Known
from somo_sweep.sweep.store.folder import REPLICAS_PLANNED
from somo_sweep.sweep.study.loaded import Study

__all__ = [
    "AWAITED",
    "ROBUST",
    "Outcome",
    "ReplicaChoice",
    "ReplicaPlan",
    "boundary_mask",
    "fold",
    "label_names",
]

#: The column of :func:`fold` that says whether every run of a cell agrees.
ROBUST = "robust"
#: The column of :func:`fold` that counts the planned replicas a cell still lacks.
AWAITED = "replicas_awaited"
#: Rounds of "neighbours of a cell whose majority moved" before the plan stops (a guard).
MAX_ROUNDS = 20


def boundary_mask(keys: np.ndarray, dims: int) -> np.ndarray:
    """Cells whose key differs from a neighbour's along one of the first ``dims`` axes.

    Args:
        keys: Integer keys, :data:`~somo_sweep.sweep.run.adaptive.UNKNOWN` where not known; the axes
            after the first ``dims`` (repeats) are not neighbours.
        dims: Number of grid axes.
    """
    out = np.zeros(keys.shape, dtype=bool)
    for axis in range(dims):
        if keys.shape[axis] < 2:
            continue
        lo = [slice(None)] * keys.ndim
        hi = [slice(None)] * keys.ndim
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        a, b = keys[tuple(lo)], keys[tuple(hi)]
        differ = (a != b) & (a != UNKNOWN) & (b != UNKNOWN)
        out[tuple(lo)] |= differ
        out[tuple(hi)] |= differ
    return out


#: (status, labels) of one run: what a replica plan decides from.
Outcome = tuple[str, dict[str, str]]


class ReplicaChoice:
    """Which cells a replica plan chooses, round after round, from the outcomes of their runs.

    Pure: it sees a cell only through ``own(trial)`` (its own trial's outcome, None when not
    stored) and ``replicas(trial)`` (its replicas' outcomes stored so far), so the run and the
    readers (:mod:`somo_sweep.sweep.run.replica_state`) replay the same choice.

    Args:
        shape: The grid's shape: one dimension per axis group, then the repeats.
        replicas: Replicas per chosen cell (K).
        where: ``boundary`` or ``all``.
        audit_fraction: Share of the other simulated cells audited.
        seed: The study's seed (of the audit's draw).
        labels: Label names (without ``label_``) that decide; empty: every label.
    """

    def __init__(
        self,
        shape: tuple[int, ...],
        replicas: int,
        where: str,
        audit_fraction: float,
        seed: int,
        labels: Sequence[str] = (),
    ):
        self.shape, self.k, self.where = tuple(shape), replicas, where
        self.audit_fraction, self.seed, self.labels = audit_fraction, seed, list(labels)
        self.dims = len(self.shape) - 1
        self._codes: dict[str, int] = {}
        #: Trials replicated, and how they were chosen (for the summary and the manifest).
        self.replicated: set[int] = set()
        self.boundary = 0
        self.audited = 0
        self.moved = 0

    def _code(self, status: str, labels: dict[str, str]) -> int:
        names = self.labels or sorted(labels)
        text = status if status != "ok" else json.dumps([[n, labels.get(n)] for n in names])
        return self._codes.setdefault(text, len(self._codes))

    def _keys(
        self, own: OwnOutcome, replicas: ReplicaOutcomes, inferred: dict[int, Outcome], majority: bool
    ) -> np.ndarray:
        keys = np.full(int(np.prod(self.shape)), UNKNOWN, dtype=np.int64)
        for trial in range(keys.size):
            out = own(trial) or inferred.get(trial)
            if out is None:
                continue
            code = self._code(*out)
            if majority and trial in self.replicated:
                code = _majority([code] + [self._code(*r) for r in replicas(trial)])
            keys[trial] = code
        return keys.reshape(self.shape)

    def rounds(
        self, own: OwnOutcome, replicas: ReplicaOutcomes, inferred: dict[int, Outcome] | None = None
    ) -> Iterator[set[int]]:
        """The cells (trial numbers) each round chooses; the next round is chosen, when asked
        for, from the outcomes ``own`` and ``replicas`` give then.

        Args:
            own: A trial's own outcome, None where it is not stored (not simulated).
            replicas: The outcomes of a trial's replicas stored so far (numbers 1 … K).
            inferred: The outcomes of the cells an adaptive run did not simulate, by trial.
        """
        if self.k <= 0:
            return
        inferred = inferred or {}
        size = int(np.prod(self.shape))
        simulated = np.array([own(t) is not None for t in range(size)], dtype=bool).reshape(self.shape)
        if self.where == "all":
            chosen = set(np.flatnonzero(simulated).tolist())
        else:
            edge = boundary_mask(self._keys(own, replicas, inferred, False), self.dims) & simulated
            chosen = set(np.flatnonzero(edge).tolist())
            self.boundary = len(chosen)
            rest = np.flatnonzero(simulated & ~edge)
            n_audit = math.ceil(self.audit_fraction * len(rest)) if len(rest) else 0
            if n_audit:
                rng = np.random.default_rng([self.seed, 0x524F42])
                audit = rng.choice(rest, size=n_audit, replace=False)
                chosen |= set(int(t) for t in audit)
                self.audited = n_audit
        number = 0
        while chosen and number < MAX_ROUNDS:
            yield chosen
            self.replicated |= chosen
            before = self._keys(own, replicas, inferred, False)
            after = self._keys(own, replicas, inferred, True)
            self.moved = int((before != after).sum())
            edge = boundary_mask(after, self.dims) & simulated
            chosen = set(np.flatnonzero(edge).tolist()) - self.replicated
            number += 1

    def record(self) -> dict[str, Any]:
        """What a reader needs to replay the choice (the run's manifest entry keeps it)."""
        return {
            "shape": list(self.shape),
            "where": self.where,
            "audit_fraction": self.audit_fraction,
            "seed": self.seed,
            "labels": self.labels,
        }


#: A trial's own outcome (None: not stored); the outcomes of its replicas stored so far.
OwnOutcome = Callable[[int], Outcome | None]
ReplicaOutcomes = Callable[[int], list[Outcome]]


class ReplicaPlan:
    """The replica rounds of one study.

    Args:
        study: The study (its ``robustness`` gives K and the policy).
        table: Its job table (grid order, repeats innermost).
    """

    def __init__(self, study: Study, table: JobTable):
        spec = study.robustness
        self.study = study
        self.jobs = table.jobs
        self.ids = [i.decode() for i in table.ids]  # trial number -> job id (jobs built when needed)
        self.k = spec.replicas
        # One dimension per axis group (a cells: table is one, its rows in order).
        values = {a.key: a.values for a in study.axes}
        shape = tuple(len(values[g[0]]) for g in study.groups)
        labels = [n.removeprefix("label_") for n in (spec.labels or study.adaptive.labels)]
        self.choice = ReplicaChoice(
            (*shape, study.repeats), spec.replicas, spec.where, spec.audit_fraction, study.seed, labels
        )
        self._replicas: dict[int, list[Job]] = {}

    def replicas(self, trial: int) -> list[Job]:
        """The replica jobs of one trial (built once)."""
        if trial not in self._replicas:
            perturb = self.study.task.perturb
            assert perturb is not None  # refused when the study loads
            self._replicas[trial] = replica_jobs(self.jobs[trial], self.k, perturb)
        return self._replicas[trial]

    @property
    def replicated(self) -> set[int]:
        """Trials replicated so far."""
        return self.choice.replicated

    def rounds(
        self, known: Known, inferred: dict[int, tuple[str, dict[str, str]]] | None = None
    ) -> Iterator[Batch]:
        """The replica rounds still to run (stored replicas are not rerun).

        Args:
            known: (status, labels) of every stored or finished trial, by job id; the caller adds
                each outcome before asking for the next round.
            inferred: (status, labels) of the cells an adaptive run did not simulate, by trial.
        """

        def own(trial: int) -> Outcome | None:
            return known.get(self.ids[trial])

        def replicas(trial: int) -> list[Outcome]:
            return [known[r.job_id] for r in self.replicas(trial) if r.job_id in known]

        for number, chosen in enumerate(self.choice.rounds(own, replicas, inferred)):
            todo = [r for t in sorted(chosen) for r in self.replicas(t) if r.job_id not in known]
            if todo:
                yield Batch(number, len(chosen), todo, kind="replicas", replicas=self.k)

    def summary(self) -> dict[str, Any]:
        """What the plan did (for the manifest)."""
        choice = self.choice
        return {
            "replicas": self.k,
            "where": choice.where,
            "cells_replicated": len(choice.replicated),
            "boundary_cells": choice.boundary,
            "audited_cells": choice.audited,
            "cells_whose_majority_moved": choice.moved,
        }


def _majority(runs: Sequence[Any]) -> Any:
    """The most common value of ``runs``; on a tie the first run's if tied, else the first tied seen."""
    counts = Counter(runs)
    top = max(counts.values())
    if counts[runs[0]] == top:
        return runs[0]
    return next(r for r in runs if counts[r] == top)


def label_names(table: pd.DataFrame) -> list[str]:
    """The label columns of a results table (``label_*``, the robustness columns left out)."""
    return [
        c
        for c in table.columns
        if str(c).startswith("label_") and not str(c).endswith(("_majority", "_agreement"))
    ]


def fold(
    table: pd.DataFrame,
    labels: Sequence[str] | None = None,
    planned: int | None = None,
    chosen: Collection[int] | None = None,
    stopped: Collection[int] = (),
) -> pd.DataFrame:
    """One row per cell: its own trial's row plus, for every label, the majority, the agreement
    and the number of runs, and ``robust`` (module docstring).

    Args:
        table: A results table (:func:`~somo_sweep.sweep.store.folder.read_results`); rows without a
            ``replica`` column or value are a cell's own trials.
        labels: Label columns to fold (default: every ``label_*`` column).
        planned: Replicas planned per replicated cell; default: the table's
            ``attrs[REPLICAS_PLANNED]`` (set by ``read_results`` from the manifest), else the
            most replicas stored for one cell.
        chosen: The cells (trial numbers) the plan chose for replicas
            (:func:`~somo_sweep.sweep.run.replica_state.replica_state`): one of them with fewer
            replicas stored than planned awaits the rest, even with none stored yet. None: only
            the cells with some replicas stored are known to be chosen.
        stopped: Cells whose replicas stopped at disagreements (an active run,
            :mod:`somo_sweep.sweep.run.replica_rule`): they await no replica.

    Returns:
        The cells' own rows, in grid order, with ``replicas`` (replica runs stored and folded),
        :data:`AWAITED` (planned replicas not stored yet), ``label_L_majority``,
        ``label_L_agreement`` for each label L, and ``robust`` (True only when every planned
        replica ran and all runs agree; False when the runs stored disagree; missing where no
        replica ran or the cell awaits replicas).
    """
    names = list(labels) if labels is not None else label_names(table)
    replica, planned = _replica_numbers(table, planned)
    kept = replica <= planned
    table, replica = table[kept], replica[kept]
    own = table[replica == 0].copy()
    extra = table[replica > 0]
    counts = extra.groupby("trial").size() if len(extra) else pd.Series(dtype=int)
    own["replicas"] = own["trial"].map(counts).fillna(0).astype(int).to_numpy()
    picked = own["replicas"] > 0
    if chosen is not None:
        picked |= own["trial"].isin(list(chosen))
    awaits = picked & ~own["trial"].isin(list(stopped))
    own[AWAITED] = np.where(awaits, (planned - own["replicas"]).clip(lower=0), 0)
    if not names:
        own[ROBUST] = pd.array([pd.NA] * len(own), dtype="boolean")
        return own.reset_index(drop=True)
    all_agree = _agreement(own, table, replica, names)
    robust = pd.array(all_agree.to_numpy(), dtype="boolean")
    unchecked = (own["replicas"].to_numpy() == 0) | ((own[AWAITED].to_numpy() > 0) & all_agree.to_numpy())
    robust[unchecked] = pd.NA
    own[ROBUST] = robust
    return own.reset_index(drop=True)


def _replica_numbers(table: pd.DataFrame, planned: int | None) -> tuple[pd.Series, int]:
    """Each row's replica number (0: a cell's own trial, also where the ``replica`` column or value
    is missing) and the replicas planned per cell: ``planned``, else the table's
    ``attrs[REPLICAS_PLANNED]``, else the most replicas stored for one cell."""
    replica = (
        pd.to_numeric(table["replica"], errors="coerce").fillna(0).astype(int)
        if "replica" in table.columns
        else pd.Series(0, index=table.index)
    )
    if planned is None:
        planned = table.attrs.get(REPLICAS_PLANNED)
    if planned is None:
        planned = int(replica.max()) if len(replica) else 0
    return replica, planned


def _agreement(own: pd.DataFrame, table: pd.DataFrame, replica: pd.Series, names: Sequence[str]) -> pd.Series:
    """Add each label's majority and agreement to ``own``; whether every run agrees on every label."""
    status = table["status"].astype(str)
    all_agree = pd.Series(True, index=own.index)
    for name in names:
        values = table[name].astype(object).where(table[name].notna(), None)
        outcome = values.where(status == "ok", status)
        runs: dict[Any, list[Any]] = {}
        # Each cell's own trial first, so a tie keeps its outcome.
        for trial, _replica, value in sorted(
            zip(table["trial"], replica, outcome, strict=True), key=lambda t: (t[0], t[1])
        ):
            runs.setdefault(trial, []).append(value)
        majority = {t: _majority(v) for t, v in runs.items()}
        share = {t: sum(x == majority[t] for x in v) / len(v) for t, v in runs.items()}
        own[f"{name}_majority"] = own["trial"].map(majority).to_numpy()
        own[f"{name}_agreement"] = own["trial"].map(share).astype(float).to_numpy()
        all_agree &= own[f"{name}_agreement"] >= 1.0
    return all_agree
