"""A study sampled actively: the sampler's batches as jobs, and the rows of the cells it inferred.

:class:`ActivePlan` maps a study onto :class:`~somo_sweep.sweep.run.active.Sampler`: one grid
dimension per axis group, then the repeats (a cell is one trial; trial numbers are the grid's C
order), and a run's value of each followed label (``active.labels``, default every label the trials
give; a run not ``ok`` gives its status for every label). Replicas are the study's robustness
replicas (``robustness.replicas``, the same jobs as any other run of the study: same ids); with
``robustness.where: all`` every simulated cell is replicated, else the cells on an edge of the
label field. The session (:mod:`somo_sweep.sweep.run.session`) runs one batch at a time and
records each outcome in ``known``; once the sampler stops, :meth:`ActivePlan.inferred_rows` gives
the cells it never simulated, each with its likeliest labels and their ``confidence``.

Only outcomes of runs the sampler asked for are read, so a resumed run replays the batches of
the first from the stored runs and simulates none of them again; runs stored by other runs of the
study (an exhaustive run, another target) are taken as they are when the sampler asks for them,
and a cell another run simulated is never stored as inferred.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.jobs.job import Job, replica_jobs
from somo_sweep.sweep.jobs.table import JobTable
from somo_sweep.sweep.run.active import NOT_ROBUST, Run, Sampler, SamplerSettings
from somo_sweep.sweep.run.sampling import Batch, Known
from somo_sweep.sweep.study.checks import unknown_labels
from somo_sweep.sweep.study.loaded import Study

__all__ = ["INFERRED_MESSAGE", "ActivePlan", "describe", "run_value", "sampler_settings"]

#: The ``message`` of a cell the active sampler inferred.
INFERRED_MESSAGE = (
    "inferred, not simulated: the label model's likeliest labels (their probability: confidence)"
)


def run_value(status: str, labels: dict[str, str], names: list[str]) -> Run:
    """A run's value of each followed label: its label where it ended ``ok``, else ``(status)``;
    ``(none)`` for a label an ``ok`` run does not give."""
    if not names:  # no label to follow: the status alone
        return (f"({status})",)
    if status != "ok":
        return tuple(f"({status})" for _ in names)
    return tuple(str(labels[n]) if labels.get(n) is not None else "(none)" for n in names)


def _shape(study: Study) -> tuple[int, ...]:
    values = {a.key: a.values for a in study.axes}
    return (*(len(values[g[0]]) for g in study.groups), study.repeats)


def sampler_settings(study: Study) -> SamplerSettings:
    """The sampler's settings a study gives (``active:``, ``robustness:``, ``seed``)."""
    spec, robustness = study.active, study.robustness
    return SamplerSettings(
        replicas=robustness.replicas,
        target_agreement=spec.target_agreement,
        batch=spec.batch,
        initial=spec.initial,
        exploration=spec.exploration,
        model=spec.model,
        replicate="all" if robustness.where == "all" else "edges",
        seed=study.seed,
    )


class ActivePlan:
    """The active batches of one study and the rows of the cells it does not simulate.

    Args:
        study: The study (``sampling: active``).
        table: Its job table (grid order: cell after cell, repeats innermost).
    """

    def __init__(self, study: Study, table: JobTable):
        spec = study.active
        self.study, self.table = study, table
        self.settings = sampler_settings(study)
        self.sampler = Sampler(_shape(study), self.settings)
        self.names = [n.removeprefix("label_") for n in spec.labels]
        self._replicas: dict[int, list[Job]] = {}
        #: What the user should know about the sampling (printed with the run's summary).
        self.notes: list[str] = []

    def describe(self) -> str:
        """What the plan does, in one paragraph (for ``--dry-run``)."""
        return describe(self.study)

    def record(self) -> dict[str, Any]:
        """How the run chooses its replicas, for the readers (its manifest entry's ``replica_plan``)."""
        return {"kind": "active", "shape": list(self.sampler.shape), "labels": self.names}

    def job(self, cell: int, number: int) -> Job:
        """The job of a cell's trial (``number`` 0) or replica."""
        if number == 0:
            return self.table.jobs[cell]
        if cell not in self._replicas:
            perturb = self.study.task.perturb
            assert perturb is not None  # refused when the study loads
            self._replicas[cell] = replica_jobs(self.table.jobs[cell], self.settings.replicas, perturb)
        return self._replicas[cell][number - 1]

    def _job_id(self, cell: int, number: int) -> str:
        return self.table.ids[cell].decode() if number == 0 else self.job(cell, number).job_id

    def _names(self, known: Known, first: list[str]) -> list[str]:
        """The followed labels: ``active.labels``, else every label the first batch's ``ok`` runs give.

        Raises:
            DescriptionError: ``active.labels`` names a label the trials do not give.
        """
        oks = [known[i][1] for i in first if i in known and known[i][0] == "ok"]
        seen = sorted({n for labels in oks for n in labels})
        if not self.names:
            if not seen and oks:
                self.notes.append(
                    f"task {self.study.task.name} gives no labels: the sampler followed the trials' status"
                )
            return seen
        problems = unknown_labels(self.study.task, "active.labels", self.names, set(seen), "its trials give")
        if problems and oks:
            raise DescriptionError(self.study.source, problems)
        return self.names

    def rounds(self, known: Known) -> Iterator[Batch]:
        """The batches still to run; the ones finished before are replayed from ``known``.

        The caller runs each batch and adds every outcome to ``known`` before asking for the next.
        """
        names: list[str] | None = None

        def outcome(cell: int, number: int) -> Run | None:
            nonlocal names
            found = known.get(self._job_id(cell, number))
            if found is None:
                return None
            if names is None:
                names = self._names(known, first)
            return run_value(found[0], found[1], names)

        first: list[str] = []
        for number, batch in enumerate(self.sampler.batches(outcome)):
            ids = [self._job_id(c, r) for c, r in batch]
            if number == 0:
                first = ids
            todo = [self.job(c, r) for (c, r), i in zip(batch, ids, strict=True) if i not in known]
            # The odd replicas (half the step, the longest runs) first: less time at the batch's end
            # with a worker idle. The order changes no decision: the next batch reads them all.
            todo.sort(key=lambda job: job.replica % 2 == 0)
            if todo:
                yield Batch(number, len({c for c, _ in batch}), todo, kind="active")
        if names is not None:
            self.names = names

    @property
    def simulated_cells(self) -> int:
        """Cells simulated so far (asked for by the sampler)."""
        return len(self.sampler.own)

    def summary(self) -> dict[str, Any]:
        """What the sampling did (for the manifest and the run's summary)."""
        sampler = self.sampler
        return {
            "runs": sampler.runs,
            "cells_simulated": len(sampler.own),
            "cells_replicated": len(sampler.chosen),
            "estimated_agreement": round(sampler.estimate, 4),
            "target_agreement": self.settings.target_agreement,
            "labels": self.names,
        }

    def inferred_rows(self, known: Known, study_hash: str) -> list[dict[str, Any]]:
        """Rows of the cells never simulated (after the last batch): the likeliest class's labels,
        ``confidence`` its probability, no metrics. A label the class calls not robust, or a
        status, is left empty; a class of one status (every run of it ``error``) is that status."""
        sampler, rows = self.sampler, []
        classes = sampler.claims()
        for cell in range(sampler.n):
            if cell in sampler.own or self.table.ids[cell].decode() in known:
                continue
            values = classes[cell]
            statuses = {v for v in values if v.startswith("(") and v != NOT_ROBUST}
            status = statuses.pop()[1:-1] if len(statuses) == 1 and len(set(values)) == 1 else "ok"
            labels = {
                f"label_{n}": (None if v.startswith("(") else v)
                for n, v in zip(self.names, values, strict=False)  # no name: the status alone
            }
            job = self.table.jobs[cell]
            rows.append(
                {
                    "job_id": job.job_id,
                    "trial": job.trial,
                    "repeat": job.repeat,
                    "seed": job.seed,
                    "status": status,
                    "message": INFERRED_MESSAGE,
                    "wall_time_s": None,
                    "host": "",
                    "study_hash": study_hash,
                    **job.columns,
                    **labels,
                    "confidence": round(float(sampler.confidence[cell]), 4),
                    "inferred": True,
                }
            )
        return rows


def describe(study: Study) -> str:
    """What active sampling of ``study`` does, in a few lines (for ``--dry-run``)."""
    spec, k = study.active, study.robustness.replicas
    shape = _shape(study)
    labels = ", ".join(f"label_{n.removeprefix('label_')}" for n in spec.labels) or "every label_* column"
    which = (
        "every simulated cell"
        if study.robustness.where == "all"
        else "the cells on an edge of the label field"
    )
    replicas = f"{k} replicas of {which}, one at a time, a label's stopping at its first disagreement"
    return "\n".join(
        [
            f"active sampling of a {' x '.join(map(str, shape[:-1])) or '1'} grid "
            f"({math.prod(shape)} trials), following {labels}:",
            f"  batch 0: {min(spec.initial, math.prod(shape))} cells at random; then batches of {spec.batch} "
            "runs: "
            f"the open cells' next replicas, then the cells the {spec.model} model is least sure of "
            f"({spec.exploration:.0%} of them at random)",
            f"  {replicas if k else 'no replicas'}",
            f"  stops when the estimated agreement reaches {spec.target_agreement:g}; cells never simulated "
            "are stored as inferred, with their confidence",
        ]
    )
