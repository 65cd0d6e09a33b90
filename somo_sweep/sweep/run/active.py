"""Active sampling: trials and replicas placed in batches where a model of the labels is unsure.

One sampler decides both which cells of a grid to simulate and which of them to replicate; it
knows nothing of studies or jobs (:mod:`somo_sweep.sweep.run.active_plan` maps a study onto it),
only a grid shape, the number of replicas K and, for every run it asked for, the value of each
label it follows (a run that did not end ``ok``: its status, for every label).

* **A cell's class** is, for each followed label, its own trial's value, or *not robust* once a
  replica disagrees on it. Replicas run one number at a time and a label's replicas stop at its
  first disagreement (:mod:`somo_sweep.sweep.run.replica_rule`): a cell's replicas stop when every
  followed label has disagreed or all K ran.
* **The model** (:mod:`somo_sweep.sweep.run.label_model`: extra trees, or the nearest simulated
  cells' classes) gives every cell not simulated each class's probability.
* **Each batch**: the next replica of every replicated cell still open, then new cells up to the
  batch size: the most uncertain (smallest margin between their two likeliest classes), a share
  ``exploration`` of them drawn at random instead (seeded). The first batch is ``initial`` cells
  drawn at random.
* **Which cells are replicated**: a simulated cell whose class differs from a grid neighbour's
  (simulated, or the model's likeliest class where not), once, for good (``replicate: edges``);
  or every simulated cell (``replicate: all``).
* **Stop**: when no replicated cell is open and the estimated agreement reaches the target:
  the mean over cells of the chance that a cell's class is right, 1 for a simulated cell (its
  replicas ran, or none of its neighbours differs), the model's probability of its likeliest
  class for the others; and no cell left to infer has a likeliest class that is not robust (those
  are simulated first, the least sure first: a cell is inferred with labels, never as not
  robust). The run then stores the cells never simulated as *inferred*, with that probability as
  their confidence.

Decisions read only the outcomes of the runs the sampler asked for, and every draw is seeded, so
the runs and the classes are a function of the seed and the outcomes: the same whatever the
worker count, and a resumed run replays its batches from the stored outcomes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from somo_sweep.sweep.run.label_model import LabelModel, grid_features, make_model
from somo_sweep.sweep.run.replica_rule import Verdict, next_replica, verdict

__all__ = ["NOT_ROBUST", "Request", "Run", "Sampler", "SamplerSettings"]

#: A label's value in a cell's class once a replica disagrees on it.
NOT_ROBUST = "(not robust)"
#: One run's value of each followed label, in order.
Run = tuple[str, ...]
#: A run to simulate: (cell, replica number; 0 is the cell's own trial).
Request = tuple[int, int]


@dataclass(frozen=True)
class SamplerSettings:
    """How the sampler places runs (module docstring).

    Attributes:
        replicas: Replicas per replicated cell (K; 0: none, the classes are the trials' labels).
        target_agreement: The estimated share of right cells at which it stops (0 … 1).
        batch: Runs per batch (more when more replicas are open).
        initial: Cells of the first batch, drawn at random.
        exploration: Share of each batch's new cells drawn at random.
        model: ``trees`` or ``neighbours``.
        replicate: ``edges`` or ``all``.
        seed: Seed of every draw.
    """

    replicas: int
    target_agreement: float = 0.98
    batch: int = 20
    initial: int = 60
    exploration: float = 0.1
    model: str = "trees"
    replicate: str = "edges"
    seed: int = 0


class Sampler:
    """The batches of one grid (module docstring).

    Args:
        shape: The grid's shape; cells are numbered in C order.
        settings: How to place runs.
        model: The label model (default: the one ``settings.model`` names).
    """

    def __init__(self, shape: tuple[int, ...], settings: SamplerSettings, model: LabelModel | None = None):
        self.shape, self.settings = tuple(shape), settings
        self.n = math.prod(self.shape)
        self.features = grid_features(self.shape)
        self.neighbours = _neighbours(self.shape)
        self.model = model or make_model(settings.model, settings.seed)
        self.own: dict[int, Run] = {}
        self.replicas: dict[int, list[Run | None]] = {}
        self.chosen: set[int] = set()
        self.rng = np.random.default_rng([settings.seed, 0x414354])
        self.classes: list[Run] = []  # class code -> class
        self.likeliest = np.full(self.n, -1, dtype=np.int64)  # class code per cell
        self.confidence = np.zeros(self.n)
        self.margin = np.ones(self.n)  # 1 − (p1 − p2): larger is less sure
        #: Runs asked for so far, and the estimated agreement after each batch.
        self.runs = 0
        self.estimate = 0.0
        self.trace: list[tuple[int, float]] = []

    # -- a cell's runs ---------------------------------------------------------------------

    def verdicts(self, cell: int) -> list[Verdict]:
        """Each followed label's verdict on a simulated cell (ROBUST for all when K is 0)."""
        own, k = self.own[cell], self.settings.replicas
        runs = self.replicas.get(cell, [])
        return [verdict(runs, k, _same_at(own, i)) for i in range(len(own))]

    def cell_class(self, cell: int) -> Run:
        """A simulated cell's class: each label's own value, or :data:`NOT_ROBUST`."""
        own = self.own[cell]
        if cell not in self.chosen:
            return own
        return tuple(NOT_ROBUST if v is Verdict.BROKEN else own[i] for i, v in enumerate(self.verdicts(cell)))

    def is_open(self, cell: int) -> bool:
        """Whether a replicated cell still has replicas to run."""
        return cell in self.chosen and any(v is Verdict.OPEN for v in self.verdicts(cell))

    # -- the batches -----------------------------------------------------------------------

    def batches(self, outcome: Callable[[int, int], Run | None]) -> Iterator[list[Request]]:
        """The batches, each chosen from the outcomes of the ones before: the caller runs a batch
        and makes ``outcome(cell, replica)`` give each of its runs before asking for the next.

        Raises:
            RuntimeError: A run of the batch before has no outcome.
        """
        while batch := self._next():
            self.runs += len(batch)
            yield batch
            for cell, number in batch:
                out = outcome(cell, number)
                if out is None:
                    raise RuntimeError(f"cell {cell}, replica {number}: no outcome")
                if number == 0:
                    self.own[cell] = tuple(out)
                else:
                    runs = self.replicas.setdefault(cell, [None] * self.settings.replicas)
                    runs[number - 1] = tuple(out)
            self._update()

    def _next(self) -> list[Request]:
        settings = self.settings
        if not self.own:
            size = min(max(settings.initial, 1), self.n)
            return [(int(c), 0) for c in sorted(self.rng.choice(self.n, size=size, replace=False))]
        k = settings.replicas
        replicas = [
            (c, next_replica(self.replicas.get(c, []), k)) for c in sorted(self.chosen) if self.is_open(c)
        ]
        if self.estimate < settings.target_agreement:
            return replicas + [(c, 0) for c in self._new_cells(max(settings.batch - len(replicas), 0))]
        # The target is reached: simulate still the cells whose likeliest class is not robust on
        # some label (an inferred cell stores labels, never "not robust"), the least sure first.
        doubtful = [c for c in range(self.n) if c not in self.own and self._doubtful(c)]
        doubtful.sort(key=lambda c: (-self.margin[c], c))
        return replicas + [(c, 0) for c in sorted(doubtful[: max(settings.batch - len(replicas), 0)])]

    def _doubtful(self, cell: int) -> bool:
        code = int(self.likeliest[cell])
        return code >= 0 and NOT_ROBUST in self.classes[code]

    def _new_cells(self, wanted: int) -> list[int]:
        """``wanted`` cells not simulated: the least sure, a share of them drawn at random."""
        free = np.array([c for c in range(self.n) if c not in self.own], dtype=np.int64)
        if wanted <= 0 or not len(free):
            return []
        wanted = min(wanted, len(free))
        explore = min(round(self.settings.exploration * wanted), wanted)
        tiebreak = self.rng.random(len(free))
        order = np.lexsort((tiebreak, -self.margin[free]))
        sure = list(free[order[: wanted - explore]])
        rest = free[order[wanted - explore :]]
        drawn = list(self.rng.choice(rest, size=explore, replace=False)) if explore else []
        return sorted(int(c) for c in sure + drawn)

    def _update(self) -> None:
        """Fit the model, choose the cells to replicate, estimate the agreement."""
        simulated = np.array(sorted(self.own), dtype=np.int64)
        codes: dict[Run, int] = {c: i for i, c in enumerate(self.classes)}
        labels = np.array([codes.setdefault(self.cell_class(int(c)), len(codes)) for c in simulated])
        self.classes = list(codes)
        free = np.setdiff1d(np.arange(self.n), simulated)
        probabilities = self.model.probabilities(self.features[simulated], labels, self.features[free])
        self.likeliest[simulated] = labels
        self.confidence[simulated] = 1.0
        self.margin[simulated] = 0.0
        if len(free):
            top = np.sort(probabilities, axis=1)[:, ::-1]
            second = top[:, 1] if top.shape[1] > 1 else np.zeros(len(free))
            self.likeliest[free] = probabilities.argmax(axis=1)
            self.confidence[free] = top[:, 0]
            self.margin[free] = 1.0 - (top[:, 0] - second)
        self.probabilities = (free, probabilities)
        self._choose_replicated(simulated)
        self.estimate = float(self.confidence.mean())
        self.trace.append((self.runs, self.estimate))

    def _choose_replicated(self, simulated: np.ndarray) -> None:
        if self.settings.replicas <= 0:
            return
        for cell in (int(c) for c in simulated):
            if cell in self.chosen:
                continue
            edge = bool((self.likeliest[self.neighbours[cell]] != self.likeliest[cell]).any())
            if self.settings.replicate == "all" or edge:
                self.chosen.add(cell)

    def claims(self) -> list[Run]:
        """Every cell's class: a simulated cell's own (:meth:`cell_class`), the likeliest class of
        the model for the others (after the last batch)."""
        out: list[Run] = []
        for cell in range(self.n):
            out.append(self.cell_class(cell) if cell in self.own else self.classes[int(self.likeliest[cell])])
        return out


def _same_at(own: Run, i: int) -> Callable[[Run], bool]:
    """Whether a replica gives the cell's own value of label ``i``."""
    return lambda run: run[i] == own[i]


def _neighbours(shape: tuple[int, ...]) -> list[np.ndarray]:
    """Each cell's grid neighbours (one index step along one dimension), in C order."""
    index = np.arange(math.prod(shape)).reshape(shape) if shape else np.zeros((), dtype=np.int64)
    found: list[list[int]] = [[] for _ in range(index.size)]
    for axis in range(len(shape)):
        if shape[axis] < 2:
            continue
        lo = np.take(index, range(shape[axis] - 1), axis=axis).ravel()
        hi = np.take(index, range(1, shape[axis]), axis=axis).ravel()
        for a, b in zip(lo.tolist(), hi.tolist(), strict=True):
            found[a].append(b)
            found[b].append(a)
    return [np.array(sorted(f), dtype=np.int64) for f in found]
