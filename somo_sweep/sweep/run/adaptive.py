"""Adaptive sampling of a grid: a coarse sub-grid, then bisection wherever labels change.

The grid has one dimension per axis group of a study (linked axes are one dimension).
A dimension is *refined* when it has at least :data:`MIN_REFINED_VALUES` values that are
numbers, strictly monotonic in every axis of the group; every other dimension is
simulated at each of its values.

The coarse sub-grid takes every ``stride``-th index of a refined dimension, always with
its last index. Consecutive coarse indices bound *boxes* (closed index ranges; a
dimension that is not refined contributes one index per box). A box is **settled** when
every simulated cell inside it or on its faces has the same *key* (a cell's status and
labels). A box that is not settled is split at its midpoint along the dimensions whose
corner edges change key (along all its longer dimensions when only a cell inside it
differs); a dimension one step long whose edges change key is replaced by the box's two
faces across it, which hold all its cells. The corners of the new boxes are simulated
next. Refinement ends when every box whose corners are all simulated is settled or has
no cell left between its corners. Each cell that was never simulated takes the key of
the settled box that holds it; a cell two settled boxes would fill differently is
simulated instead.

Decisions depend only on the keys of the cells this procedure asked for, so the cells
simulated are the same whatever order trials finish in, and an interrupted refinement
replays its finished rounds from the stored keys without simulating them again (cells
stored by other runs are added only after that, by
:class:`~somo_sweep.sweep.run.sampling.AdaptivePlan`). A label
region that fits between two coarse cells of the same key is not seen; a smaller
``stride`` trades trials for that risk.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MIN_REFINED_VALUES",
    "UNKNOWN",
    "AdaptiveGrid",
    "Box",
    "Cell",
    "default_stride",
    "infer",
    "next_cells",
]

#: A dimension with fewer values is simulated at every value.
MIN_REFINED_VALUES = 3
#: The key of a cell that has not been simulated (keys are integers >= 0).
UNKNOWN = -1

Cell = tuple[int, ...]
#: Closed index range (lo, hi) per dimension.
Box = tuple[tuple[int, int], ...]


def default_stride(n_values: int) -> int:
    """Coarse stride of a refined dimension: the largest power of two ≤ (n − 1) / 2 (at least 1).

    It keeps at least three coarse values per dimension (both ends and one inside), so a
    label that changes only once along a dimension is bracketed from the first round.
    """
    stride = 1
    while stride * 4 <= n_values - 1:
        stride *= 2
    return stride


@dataclass(frozen=True)
class AdaptiveGrid:
    """The shape of a grid and how each dimension is sampled.

    Attributes:
        shape: Number of values per dimension.
        refined: Whether each dimension is refined (else simulated at every value).
        strides: Coarse stride per dimension, in index steps (1 where not refined).
    """

    shape: tuple[int, ...]
    refined: tuple[bool, ...]
    strides: tuple[int, ...]

    @classmethod
    def build(cls, shape: Sequence[int], refined: Sequence[bool], stride: int | None = None) -> AdaptiveGrid:
        """A grid; refined dimensions get ``stride`` (default: :func:`default_stride` of each)."""
        ok = tuple(bool(r) and n >= MIN_REFINED_VALUES for n, r in zip(shape, refined, strict=True))
        strides = tuple(
            (min(stride, n - 1) if stride is not None else default_stride(n)) if r else 1
            for n, r in zip(shape, ok, strict=True)
        )
        return cls(tuple(shape), ok, strides)

    @property
    def n_cells(self) -> int:
        """Cells in the whole grid."""
        return int(np.prod(self.shape, dtype=np.int64)) if self.shape else 1

    def coarse_indices(self, dim: int) -> list[int]:
        """The coarse indices of one dimension (every stride-th and the last)."""
        n, step = self.shape[dim], self.strides[dim]
        return sorted({*range(0, n, step), n - 1})

    def coarse_boxes(self) -> Iterator[Box]:
        """The boxes between consecutive coarse indices, in grid order."""
        per_dim: list[list[tuple[int, int]]] = []
        for dim in range(len(self.shape)):
            idx = self.coarse_indices(dim)
            if self.refined[dim] and len(idx) > 1:
                per_dim.append(list(itertools.pairwise(idx)))
            else:
                per_dim.append([(i, i) for i in range(self.shape[dim])])
        yield from itertools.product(*per_dim)

    def n_coarse(self) -> int:
        """Cells of the coarse sub-grid."""
        return int(np.prod([len(self.coarse_indices(d)) for d in range(len(self.shape))], dtype=np.int64))


def _corners(box: Box) -> list[Cell]:
    return sorted(set(itertools.product(*({lo, hi} for lo, hi in box))))


def _closure(box: Box) -> tuple[slice, ...]:
    return tuple(slice(lo, hi + 1) for lo, hi in box)


def _edges_differ(keys: np.ndarray, box: Box, dim: int) -> bool:
    """Whether two corners of the box joined by an edge along ``dim`` have different keys."""
    lo, hi = box[dim]
    if lo == hi:
        return False
    for corner in _corners(box):
        if corner[dim] == lo:
            other = (*corner[:dim], hi, *corner[dim + 1 :])
            if keys[corner] != keys[other]:
                return True
    return False


def _children(keys: np.ndarray, box: Box) -> list[Box] | None:
    """The boxes that replace a box that is not settled (None: no cell lies between its corners).

    Split at the midpoint along the dimensions whose corner edges change key (all dimensions
    longer than one step when only a cell inside the box differs); a dimension one step
    long whose edges change key is replaced by its two faces, which hold all its cells.
    """
    long = [d for d, (lo, hi) in enumerate(box) if hi - lo > 1]
    split = [d for d in long if _edges_differ(keys, box, d)]
    faces = [d for d, (lo, hi) in enumerate(box) if hi - lo == 1 and _edges_differ(keys, box, d)]
    if not split and not faces:
        split = long
    elif split:
        faces = []
    if not split and not faces:
        return None
    parts: list[list[tuple[int, int]]] = []
    for d, (lo, hi) in enumerate(box):
        if d in split:
            mid = (lo + hi) // 2
            parts.append([(lo, mid), (mid, hi)])
        elif d in faces:
            parts.append([(lo, lo), (hi, hi)])
        else:
            parts.append([(lo, hi)])
    return list(itertools.product(*parts))


def _settled_key(keys: np.ndarray, box: Box) -> int | None:
    """The one key of every simulated cell in the box's closure, or None if they differ."""
    found = np.unique(keys[_closure(box)])
    found = found[found != UNKNOWN]
    return int(found[0]) if len(found) == 1 else None


def _walk(grid: AdaptiveGrid, keys: np.ndarray) -> tuple[list[Cell], list[tuple[Box, int]]]:
    """(cells wanted next, settled boxes with their key) given the keys known so far."""
    wanted: set[Cell] = set()
    settled: list[tuple[Box, int]] = []
    stack = list(grid.coarse_boxes())
    while stack:
        box = stack.pop()
        missing = [c for c in _corners(box) if keys[c] == UNKNOWN]
        if missing:
            wanted.update(missing)
            continue
        key = _settled_key(keys, box)
        children = None if key is not None else _children(keys, box)
        if children is not None:
            stack.extend(children)
        elif key is not None:
            settled.append((box, key))
    return sorted(wanted), settled


def _fill(
    grid: AdaptiveGrid, keys: np.ndarray, settled: list[tuple[Box, int]]
) -> tuple[list[tuple[Box, int, list[Cell]]], list[Cell]]:
    """(settled boxes with the unknown cells they fill, cells two settled boxes disagree on)."""
    filled = np.full(grid.shape, UNKNOWN, dtype=np.int64)
    out: list[tuple[Box, int, list[Cell]]] = []
    clashes: set[Cell] = set()
    for box, key in sorted(settled):
        view = filled[_closure(box)]
        free = keys[_closure(box)] == UNKNOWN
        origin = np.array([lo for lo, _ in box])
        clash = free & (view != UNKNOWN) & (view != key)
        clashes.update(tuple(int(i) for i in origin + idx) for idx in np.argwhere(clash))
        new = free & (view == UNKNOWN)
        if new.any():
            view[new] = key
            out.append((box, key, [tuple(int(i) for i in origin + idx) for idx in np.argwhere(new)]))
    return out, sorted(clashes)


def next_cells(grid: AdaptiveGrid, keys: np.ndarray) -> list[Cell]:
    """The cells to simulate next, in grid order (empty: refinement is complete).

    Cells that two settled boxes would fill differently are simulated too (with splits
    along single dimensions, two boxes may share cells but no simulated one).

    Args:
        grid: The grid.
        keys: Key of every cell (integers >= 0), :data:`UNKNOWN` where not simulated; only
            the cells this procedure asked for should be known.
    """
    wanted, settled = _walk(grid, keys)
    return wanted or _fill(grid, keys, settled)[1]


def infer(grid: AdaptiveGrid, keys: np.ndarray) -> list[tuple[Box, int, list[Cell]]]:
    """The cells never simulated, filled from the settled boxes that hold them.

    Args:
        grid: The grid.
        keys: Keys of the simulated cells (:data:`UNKNOWN` elsewhere), refinement complete.

    Returns:
        For each settled box with cells to fill: the box, its key and those cells (each
        cell once, in the first box that holds it).

    Raises:
        ValueError: Refinement is not complete (:func:`next_cells` is not empty).
    """
    wanted, settled = _walk(grid, keys)
    filled, clashes = _fill(grid, keys, settled)
    if wanted or clashes:
        raise ValueError(f"refinement is not complete: {len(wanted) + len(clashes)} cell(s) to simulate")
    return filled
