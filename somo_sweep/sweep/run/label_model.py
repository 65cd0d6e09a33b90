"""Models of a label field over a grid: from the cells simulated so far, each class's probability
at every cell.

The active sampler (:mod:`somo_sweep.sweep.run.active`) fits one after every batch. A cell is a
point of the grid, its features its index along each dimension scaled to 0 … 1 (so every axis
weighs the same, whatever its values or count). Two models:

* ``trees``: extra trees (:class:`sklearn.ensemble.ExtraTreesClassifier`), seeded; a class's
  probability is the share of trees that give it.
* ``neighbours``: no dependency; the classes of the k nearest simulated cells, weighted by
  1 / distance.

Both are deterministic for a seed and their training cells (given in cell order).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

__all__ = ["MODELS", "LabelModel", "Neighbours", "Trees", "grid_features", "make_model"]

#: The label models by name.
MODELS = ("trees", "neighbours")


class LabelModel(Protocol):
    """A classifier of cells: fitted on simulated cells, asked for every class's probability."""

    def probabilities(self, train: np.ndarray, classes: np.ndarray, query: np.ndarray) -> np.ndarray:
        """Probabilities (query × class, class ``c`` at column ``c``; rows sum to 1) at the cells
        ``query`` (features, one row each), from the cells ``train`` of classes ``classes``
        (integers 0 … C−1, every one present)."""
        ...


def grid_features(shape: tuple[int, ...]) -> np.ndarray:
    """Each cell's index along every dimension of ``shape``, scaled to 0 … 1 (cells in C order)."""
    index = np.indices(shape).reshape(len(shape), -1).T.astype(float)
    scale = np.array([max(n - 1, 1) for n in shape], dtype=float)
    return index / scale


class Trees:
    """Extra trees over the scaled indices.

    Args:
        seed: Seed of the trees' draws.
        n_trees: Trees in the forest.
    """

    def __init__(self, seed: int, n_trees: int = 50):
        self.seed, self.n_trees = seed, n_trees
        self.fits = 0

    def probabilities(self, train: np.ndarray, classes: np.ndarray, query: np.ndarray) -> np.ndarray:
        """See :class:`LabelModel` (each fit seeded with the seed and the fit's number)."""
        from sklearn.ensemble import ExtraTreesClassifier  # imported on first use: 1-2 s

        n_classes = int(classes.max()) + 1 if len(classes) else 1
        out = np.zeros((len(query), n_classes))
        if n_classes == 1 or len(query) == 0:
            out[:, 0] = 1.0
            return out
        state = int(np.random.default_rng([self.seed, self.fits]).integers(2**31))
        self.fits += 1
        forest = ExtraTreesClassifier(n_estimators=self.n_trees, random_state=state, n_jobs=1)
        forest.fit(train, classes)
        out[:, forest.classes_.astype(int)] = forest.predict_proba(query)
        return out


class Neighbours:
    """The k nearest simulated cells' classes, weighted by 1 / distance (no dependency).

    Args:
        k: Neighbours that vote.
    """

    def __init__(self, k: int = 6):
        self.k = k

    def probabilities(self, train: np.ndarray, classes: np.ndarray, query: np.ndarray) -> np.ndarray:
        """See :class:`LabelModel`."""
        n_classes = int(classes.max()) + 1 if len(classes) else 1
        out = np.zeros((len(query), n_classes))
        if len(train) == 0 or len(query) == 0:
            out[:, 0] = 1.0
            return out
        k = min(self.k, len(train))
        for start in range(0, len(query), 512):  # bounded memory: 512 × train distances at a time
            block = query[start : start + 512]
            dist = np.sqrt(((block[:, None, :] - train[None, :, :]) ** 2).sum(-1))
            near = np.argpartition(dist, k - 1, axis=1)[:, :k]
            weight = 1.0 / (np.take_along_axis(dist, near, axis=1) + 1e-3)
            votes = np.zeros((len(block), n_classes))
            np.add.at(votes, (np.repeat(np.arange(len(block)), k), classes[near].ravel()), weight.ravel())
            out[start : start + len(block)] = votes / votes.sum(axis=1, keepdims=True)
        return out


def make_model(name: str, seed: int) -> LabelModel:
    """The label model called ``name`` (:data:`MODELS`), seeded with ``seed``.

    Raises:
        ValueError: An unknown name (the study's validation names the allowed ones first).
    """
    if name == "trees":
        return Trees(seed)
    if name == "neighbours":
        return Neighbours()
    raise ValueError(f"unknown label model {name!r}; allowed: {', '.join(MODELS)}")
