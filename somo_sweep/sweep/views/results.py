"""A results folder opened for its readers, once: what it stores, and where its replicas stand.

:func:`open_results` reads a results folder once (:func:`~somo_sweep.sweep.store.folder.open_folder`:
its trials, manifest, files left out and finished trials waiting in a killed run's journal) and
replays its replica plan once (:func:`~somo_sweep.sweep.run.replica_state.replica_state`). The
readers (``show``, ``plot``, ``answer``, ``classify``, ``paper fig6``) each take the one
:class:`Results` and pass it whole, instead of reading the folder piece by piece.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import pandas as pd

from somo_sweep.sweep.run.replica_state import ReplicaState, fold_cells, replica_state, unfinished
from somo_sweep.sweep.run.robustness import label_names
from somo_sweep.sweep.store.folder import OpenedFolder, missing_trials, open_folder
from somo_sweep.sweep.store.parts import OnDamaged
from somo_sweep.sweep.views.axes import Swept, swept

__all__ = ["Results", "open_results"]


@dataclass(frozen=True)
class Results(OpenedFolder):
    """A results folder opened for its readers (:func:`open_results`).

    Besides what :class:`~somo_sweep.sweep.store.folder.OpenedFolder` holds (``folder``,
    ``manifest``, ``trials``, ``left_out``, the ``journals`` whose rows wait: ``pending``):

    Attributes:
        replicas: Where its robustness replicas stand (the plan of its latest run with replicas,
            replayed from the stored outcomes).
    """

    replicas: ReplicaState = field(default_factory=ReplicaState)

    @classmethod
    def of(cls, opened: OpenedFolder) -> Results:
        """``opened`` with its replica plan replayed."""
        return cls(
            opened.folder,
            opened.manifest,
            opened.trials,
            opened.left_out,
            opened.journals,
            replica_state(opened.trials),
        )

    @classmethod
    def of_table(cls, trials: pd.DataFrame, manifest: dict[str, Any], folder: str | Path = "") -> Results:
        """A trials table already read (its ``attrs`` as a folder's reader sets them) and its manifest."""
        return cls.of(OpenedFolder(Path(folder), manifest, trials))

    @cached_property
    def cells(self) -> pd.DataFrame:
        """One row per cell: the robustness replicas folded into their cells
        (:func:`~somo_sweep.sweep.run.replica_state.fold_cells`), every cell the plan chose counted
        as awaiting the replicas it lacks."""
        return fold_cells(self.trials, state=self.replicas)

    @cached_property
    def labels(self) -> list[str]:
        """The label columns of its cells (``label_*``, not the robustness columns)."""
        return label_names(self.cells)

    @cached_property
    def swept(self) -> Swept:
        """The swept axes of its cells that vary, worked out once for every figure."""
        return swept(self.cells, self.manifest.get("axes", {}))

    @property
    def unfinished(self) -> str | None:
        """What the replicas still lack, in one sentence (None when settled)."""
        return unfinished(self.replicas, self.cells)

    def missing(self, stored: int) -> str | None:
        """Why ``stored`` of the study's trials are here and not all, in one sentence (None when all
        are): :func:`~somo_sweep.sweep.store.table_record.missing_trials`."""
        return missing_trials(self.trials, stored)


def open_results(folder: str | Path, on_damaged: OnDamaged | None = None) -> Results:
    """A results folder, read once, with its replica plan replayed.

    Args:
        folder: The results folder.
        on_damaged: Called with (file, why) for each file, or rows of one, left out or counted
            once (default: a warning).

    Raises:
        SomoError: Not a results folder, or rows of another study in it.
    """
    return Results.of(open_folder(folder, on_damaged))
