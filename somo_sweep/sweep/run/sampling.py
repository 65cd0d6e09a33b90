"""Which trials of a study run: every one (``grid``) or adaptively (``adaptive``), in rounds.

:class:`AdaptivePlan` maps a study's grid onto :mod:`somo_sweep.sweep.run.adaptive`: a cell is
a grid point (all its repeats), its key is the status and labels of its trials (an
``error`` or ``unstable`` trial is a key of its own, so refinement closes in on failures
too), and the cells never simulated become *inferred* rows: the labels their settled
neighbours agree on, no metrics, ``inferred`` true. The runner executes one
:class:`Batch` at a time and records outcomes in ``known``, which the plan reads to
decide the next round.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.jobs.table import JobTable
from somo_sweep.sweep.run.adaptive import UNKNOWN, AdaptiveGrid, Cell, infer, next_cells
from somo_sweep.sweep.study.checks import unknown_labels
from somo_sweep.sweep.study.loaded import Study

__all__ = ["INFERRED_MESSAGE", "AdaptivePlan", "Batch", "Known", "describe", "grid_of"]

#: (status, labels) of a finished trial, by job id.
Known = dict[str, tuple[str, dict[str, str]]]
#: The ``message`` of an inferred row.
INFERRED_MESSAGE = "inferred, not simulated: every simulated cell of its settled box agrees"


@dataclass(frozen=True)
class Batch:
    """Trials to run together.

    Attributes:
        number: Refinement round (0 is the coarse sub-grid), or replica round; None for a plain
            grid run.
        cells: Grid cells in this round (some may be stored already).
        jobs: The round's trials not yet stored.
        kind: ``trials`` (the study's own) or ``replicas`` (:mod:`somo_sweep.sweep.run.robustness`).
        replicas: For a replica round: the replicas each of its cells runs.
    """

    number: int | None
    cells: int
    jobs: Sequence[Job]
    kind: str = "trials"
    replicas: int = 0


def _refinable(values: tuple[Any, ...]) -> bool:
    numbers = [v for v in values if not isinstance(v, bool) and isinstance(v, int | float)]
    if len(numbers) != len(values) or not all(math.isfinite(v) for v in numbers):
        return False
    steps = np.diff(np.asarray(numbers, dtype=float))
    return bool((steps > 0).all() or (steps < 0).all())


def grid_of(study: Study) -> AdaptiveGrid:
    """The study's grid: one dimension per axis group, refined where numeric and monotonic.

    A ``cells:`` table is a dimension run row by row, never refined: its rows are points chosen
    one by one, not samples of an axis.

    Raises:
        DescriptionError: The study's only dimension is its ``cells:`` table (nothing to refine).
    """
    axes = {a.key: a.values for a in study.axes}
    shape = [len(axes[g[0]]) for g in study.groups]
    refined = [all(_refinable(axes[k]) for k in g) and not study.is_cells(g) for g in study.groups]
    if study.cells is not None and not any(refined):
        raise DescriptionError(
            study.source,
            [
                Problem(
                    "sampling",
                    "adaptive sampling refines numeric sweep: axes, and this study has none besides its "
                    f"cells: table, whose {len(study.cells.rows)} rows each run; allowed: sampling: grid "
                    "(or --exhaustive), or a numeric sweep: axis to refine",
                )
            ],
        )
    return AdaptiveGrid.build(shape, refined, study.adaptive.coarse_step)


def _label_name(name: str) -> str:
    return name.removeprefix("label_")


class AdaptivePlan:
    """The adaptive rounds of one study and the rows of the cells it does not simulate.

    Args:
        study: The study.
        table: Its job table (grid order: cell after cell, repeats innermost).
    """

    def __init__(self, study: Study, table: JobTable):
        self.study = study
        self.table = table
        self.jobs = table.jobs
        self.grid = grid_of(study)
        self.labels = [_label_name(n) for n in study.adaptive.labels]
        self.keys = np.full(self.grid.shape, UNKNOWN, dtype=np.int64)
        self._codes: dict[str, int] = {}
        self._checked = False
        #: What the user should know about the refinement (printed with the run's summary).
        self.notes: list[str] = []

    def describe(self) -> str:
        """What the plan does, in one paragraph (for ``--dry-run``)."""
        return describe(self.study, self.grid)

    def cell_trials(self, cell: Cell) -> range:
        """The trial numbers (one per repeat) of a grid cell."""
        point = int(np.ravel_multi_index(cell, self.grid.shape)) if cell else 0
        reps = self.study.repeats
        return range(point * reps, (point + 1) * reps)

    def cell_jobs(self, cell: Cell) -> Sequence[Job]:
        """The trials (one per repeat) of a grid cell."""
        trials = self.cell_trials(cell)
        return self.jobs[trials.start : trials.stop]

    def _ids(self, cell: Cell) -> list[str]:
        return [self.table.ids[t].decode() for t in self.cell_trials(cell)]

    def key(self, status: str, labels: dict[str, str]) -> str:
        """The key of one trial: its status, and if ``ok`` the labels refinement follows."""
        if status != "ok":
            return status
        names = self.labels or sorted(labels)
        return json.dumps([[n, labels.get(n)] for n in names])

    def _cell_key(self, cell: Cell, known: Known) -> int | None:
        outcomes = [known.get(job_id) for job_id in self._ids(cell)]
        if any(o is None for o in outcomes):
            return None
        text = json.dumps([self.key(*o) for o in outcomes if o is not None])
        return self._codes.setdefault(text, len(self._codes))

    def _check_labels(self, known: Known) -> None:
        """Every label the study names must come out of its ``ok`` trials.

        Without any label (a task that gives none, and none named) refinement follows the
        trials' status alone, and :attr:`notes` says so.
        """
        oks = [labels for status, labels in known.values() if status == "ok"]
        if self._checked or not oks:
            return
        self._checked = True
        seen = {n for labels in oks for n in labels}
        if not seen and not self.labels:
            self.notes.append(
                f"task {self.study.task.name} gives no labels: refinement followed the trials' status "
                "only, and inferred cells have a status and no metrics"
            )
        unknown = unknown_labels(self.study.task, "adaptive.labels", self.labels, seen, "its trials give")
        if unknown:
            raise DescriptionError(self.study.source, unknown)

    def _merge_stored(self, known: Known) -> bool:
        """Give the plan the keys of cells stored in the folder that it never asked for.

        An earlier run with other adaptive settings, or a full-grid run, may have stored them;
        a box that would be filled across such a cell of another key is then not settled.
        Returns whether any key was added.
        """
        trials = self.table.trial_of(list(known))
        points = {int(t) // self.study.repeats for t in trials if t >= 0}
        added = False
        for point in sorted(points):
            cell = tuple(int(i) for i in np.unravel_index(point, self.grid.shape)) if self.grid.shape else ()
            if self.keys[cell] != UNKNOWN:
                continue
            code = self._cell_key(cell, known)
            if code is not None:
                self.keys[cell] = code
                added = True
        return added

    def rounds(self, known: Known) -> Iterator[Batch]:
        """The rounds still to run; finished rounds are replayed from ``known``, not rerun.

        The caller runs each batch and adds every outcome to ``known`` before asking for the
        next one.

        Raises:
            DescriptionError: ``adaptive.labels`` names a label the task does not give.
        """
        number, merged = 0, False
        while True:
            cells = next_cells(self.grid, self.keys)
            if not cells:
                # The plan's own rounds are replayed first, exactly as they ran; cells stored by
                # other runs join only then, and refinement goes on if they disagree.
                if merged or not self._merge_stored(known):
                    return
                merged = True
                continue
            todo = [t for c in cells for t in self.cell_trials(c) if self.table.ids[t].decode() not in known]
            if todo:
                yield Batch(number, len(cells), self.table.select(todo))
            self._check_labels(known)
            for cell in cells:
                code = self._cell_key(cell, known)
                if code is None:
                    raise RuntimeError(f"round {number}: cell {cell} has no outcome")
                self.keys[cell] = code
            number += 1

    @property
    def simulated_cells(self) -> int:
        """Cells simulated so far (by this plan or stored by earlier runs)."""
        return int((self.keys != UNKNOWN).sum())

    def inferred_rows(self, known: Known, study_hash: str) -> list[dict[str, Any]]:
        """Rows of the cells never simulated (after the last round): agreed labels, no metrics.

        A label column gets a value only where every simulated cell of the settled box agrees
        on it (the labels refinement followed always do); trials stored outside the plan
        (e.g. by an earlier full-grid run) are simulated and get no inferred row.
        """
        rows: list[dict[str, Any]] = []
        for box, _, cells in infer(self.grid, self.keys):
            closure = tuple(slice(lo, hi + 1) for lo, hi in box)
            origin = np.array([lo for lo, _ in box])
            sources = [
                tuple(int(i) for i in origin + idx) for idx in np.argwhere(self.keys[closure] != UNKNOWN)
            ]
            for repeat in range(self.study.repeats):
                outcomes = [known[self._ids(c)[repeat]] for c in sources]
                status = outcomes[0][0]
                names = sorted({n for _, labels in outcomes for n in labels})
                agreed = {}
                for name in names:
                    values = {labels.get(name) for _, labels in outcomes}
                    agreed[f"label_{name}"] = values.pop() if len(values) == 1 else None
                for cell in cells:
                    if self._ids(cell)[repeat] in known:
                        continue
                    rows.append(_row(self.cell_jobs(cell)[repeat], status, agreed, study_hash))
        return sorted(rows, key=lambda r: int(r["trial"]))


def _row(job: Job, status: str, labels: dict[str, str | None], study_hash: str) -> dict[str, Any]:
    return {
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
        "inferred": True,
    }


def _nth(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return "every value" if n == 1 else f"every {n}{suffix} value"


def describe(study: Study, grid: AdaptiveGrid | None = None) -> str:
    """What adaptive sampling of ``study`` does: grid, refined axes, coarse sub-grid, bound."""
    grid = grid or grid_of(study)
    dims = []
    for g, n, refined, stride in zip(study.groups, grid.shape, grid.refined, grid.strides, strict=True):
        if study.is_cells(g):
            dims.append(f"  cells ({', '.join(g)}): {n} rows, every row (not refined)")
            continue
        how = f"refined, coarse: {_nth(stride)} and the last" if refined else "every value (not refined)"
        dims.append(f"  {' + '.join(g)}: {n} values, {how}")
    labels = ", ".join(f"label_{_label_name(n)}" for n in study.adaptive.labels) or "every label_* column"
    reps = study.repeats
    return "\n".join(
        [
            f"adaptive sampling of a {' x '.join(map(str, grid.shape)) or '1'} grid ({grid.n_cells} cells):",
            *dims,
            f"round 0 simulates the coarse sub-grid: {grid.n_coarse()} cells ({grid.n_coarse() * reps} "
            f"trials); later rounds bisect between cells whose status or {labels} differ; at most "
            f"{grid.n_cells} cells ({grid.n_cells * reps} trials); cells never simulated are stored as "
            "inferred",
        ]
    )
