"""Where a folder's robustness replicas stand, replayed from what it stores (for the readers).

A run with replicas chooses its cells round by round from the outcomes it has
(:class:`~somo_sweep.sweep.run.robustness.ReplicaChoice`) and records how it chooses in its
manifest entry. A run cut short (Ctrl-C, SIGKILL) leaves cells it chose with fewer replicas than
planned, most often none: a reader that only looks at the replicas stored would take such a cell
for one that was never chosen, and count it as checked by its neighbours, or as not robust.
:func:`replica_state` replays the choice from the stored outcomes, exactly as the resumed run will,
so the readers (``show``, ``plot``, ``classify``, ``paper fig6``, ``answer``) know every cell
that awaits replicas, and whether the plan could still choose more.

An active run (:mod:`somo_sweep.sweep.run.active_plan`) chooses its cells as it samples, so its
choice is known from what it stored: a cell with replicas stored was chosen, and its replicas
stopped when every label it follows has a replica that disagrees
(:mod:`somo_sweep.sweep.run.replica_rule`): such a cell awaits nothing. Until the run completes,
it may still choose more cells.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from somo_sweep.sweep.run.robustness import AWAITED, Outcome, ReplicaChoice, fold, label_names
from somo_sweep.sweep.store.folder import REPLICA_RUN, REPLICAS_PLANNED

__all__ = ["ReplicaState", "fold_cells", "replica_state", "stopped_cells", "unfinished"]


@dataclass(frozen=True)
class ReplicaState:
    """Where the replicas of a results folder stand.

    Attributes:
        replicas: Replicas planned per chosen cell (0: the folder's runs planned none).
        chosen: The cells (trial numbers) the plan chose so far; None when it cannot be known
            (the run was made by a version that did not record its plan).
        settled: No replica the plan asked for, or could still ask for, is missing.
        more_to_choose: The plan stopped inside a round: it may choose more cells once the
            awaited replicas run (their majorities may move).
        trials_missing: Trials of the study's grid not stored (the replicas are chosen after them).
        run_start_utc: When the run with replicas started (how the user finds it in ``show``).
        stopped: The cells whose replicas stopped early at disagreements (an active run): they
            await none.
    """

    replicas: int = 0
    chosen: frozenset[int] | None = frozenset()
    settled: bool = True
    more_to_choose: bool = False
    trials_missing: int = 0
    run_start_utc: str = ""
    stopped: frozenset[int] = frozenset()


def _outcomes(table: pd.DataFrame) -> tuple[dict[int, Outcome], dict[int, Outcome], dict[int, list[Any]]]:
    """Own outcomes of simulated trials, of inferred cells, and each trial's replica rows (number,
    outcome), by trial number: as the run's ``known`` holds them (labels without ``label_``,
    missing ones left out)."""
    names = label_names(table)
    replica = (
        pd.to_numeric(table["replica"], errors="coerce").fillna(0).astype(int)
        if "replica" in table.columns
        else pd.Series(0, index=table.index)
    )
    inferred = table["inferred"].fillna(False).astype(bool) if "inferred" in table.columns else None
    own: dict[int, Outcome] = {}
    guessed: dict[int, Outcome] = {}
    replicas: dict[int, list[Any]] = {}
    columns = ["trial", "status", *names]
    for i, row in enumerate(table[columns].itertuples(index=False, name=None)):
        trial, status, values = int(row[0]), str(row[1]), row[2:]
        labels = {n.removeprefix("label_"): v for n, v in zip(names, values, strict=True) if _given(v)}
        if replica.iloc[i] > 0:
            replicas.setdefault(trial, []).append((int(replica.iloc[i]), (status, labels)))
        elif inferred is not None and inferred.iloc[i]:
            guessed[trial] = (status, labels)
        else:
            own[trial] = (status, labels)
    return own, guessed, replicas


def stopped_cells(table: pd.DataFrame, labels: Sequence[str]) -> tuple[frozenset[int], frozenset[int]]:
    """The cells (trial numbers) with replicas stored, and those of them whose replicas stopped:
    every label of ``labels`` (without ``label_``; empty: every label column) has a replica whose
    outcome differs from the cell's own trial's (a run not ``ok`` counts as its status)."""
    own, _, stored = _outcomes(table)
    names = list(labels) or [n.removeprefix("label_") for n in label_names(table)]
    chosen, stopped = set(stored), set()
    for trial, runs in stored.items():
        mine = own.get(trial)
        if mine is None or not names:
            continue
        if all(any(_value(out, n) != _value(mine, n) for _, out in runs) for n in names):
            stopped.add(trial)
    return frozenset(chosen), frozenset(stopped)


def _value(outcome: Outcome, name: str) -> Any:
    status, labels = outcome
    return labels.get(name) if status == "ok" else status


def _given(value: Any) -> bool:
    return value is not None and not (isinstance(value, float) and value != value)


def replica_state(table: pd.DataFrame) -> ReplicaState:
    """Replay the replica plan of the folder ``table`` was read from
    (:func:`~somo_sweep.sweep.store.folder.read_results`, whose ``attrs`` carry the latest run with
    replicas); a table without that record planned none."""
    run = table.attrs.get(REPLICA_RUN)
    if not isinstance(run, dict):
        return ReplicaState()
    k, plan, start = int(run["replicas"]), run.get("plan"), str(run.get("start_utc", ""))
    finished = run.get("status") == "completed"
    if not isinstance(plan, dict):  # an older version's run: its choice is not recorded
        return ReplicaState(k, None, finished, False, 0, start)
    if plan.get("kind") == "active":
        picked, stopped = stopped_cells(table, [str(n) for n in plan.get("labels", [])])
        return ReplicaState(k, picked, finished, not finished, 0, start, stopped)
    own, guessed, stored = _outcomes(table)
    shape = tuple(int(n) for n in plan["shape"])
    size = 1
    for n in shape:
        size *= n
    missing = sum(1 for t in range(size) if t not in own and t not in guessed)
    if missing:  # the replicas are chosen once every trial of the grid is stored
        return ReplicaState(k, frozenset(), False, True, missing, start)

    def replicas(trial: int) -> list[Outcome]:
        return [out for number, out in stored.get(trial, []) if 1 <= number <= k]

    choice = ReplicaChoice(
        shape, k, str(plan["where"]), float(plan["audit_fraction"]), int(plan["seed"]), plan["labels"]
    )
    chosen: set[int] = set()
    for cells in choice.rounds(own.get, replicas, guessed):
        chosen |= cells
        if any(len(replicas(t)) < k for t in cells):
            # the next round is chosen from replicas not run yet (``all`` has chosen every cell)
            more = plan["where"] != "all"
            return ReplicaState(k, frozenset(chosen), False, more, 0, start)
    return ReplicaState(k, frozenset(chosen), True, False, 0, start)


def fold_cells(
    table: pd.DataFrame, labels: Sequence[str] | None = None, state: ReplicaState | None = None
) -> pd.DataFrame:
    """:func:`~somo_sweep.sweep.run.robustness.fold` of a folder's table, every cell the plan chose
    counted as awaiting the replicas it lacks (:func:`replica_state`)."""
    state = state if state is not None else replica_state(table)
    return fold(
        table, labels, planned=table.attrs.get(REPLICAS_PLANNED), chosen=state.chosen, stopped=state.stopped
    )


def unfinished(state: ReplicaState, cells: pd.DataFrame) -> str | None:
    """What the replicas still lack, in one sentence (None when settled), from the state and the
    folded cells (their ``replicas_awaited``)."""
    if state.settled:
        return None
    if state.trials_missing:
        return (
            f"the robustness replicas have not started: {state.trials_missing} trial(s) of the grid are "
            "not stored yet, and the cells to replicate are chosen once they are; run the same "
            "command again to finish"
        )
    if state.chosen is None:
        return (
            f"the run with {state.replicas} replicas per cell started {state.run_start_utc} did not "
            "finish, and the version that ran it did not record which cells it replicates: which "
            "cells await replicas is unknown; run the same command again to finish"
        )
    waits = cells[AWAITED] > 0 if AWAITED in cells else pd.Series(False, index=cells.index)
    none = int((waits & (cells["replicas"] == 0)).sum()) if "replicas" in cells else 0
    text = (
        f"the robustness replicas are unfinished (a run cut short): {int(waits.sum())} cell(s) await "
        f"some of their {state.replicas} replicas ({none} with none stored yet)"
    )
    if state.more_to_choose:
        text += ", and more cells may be chosen once they run"
    return text + "; run the same command again to finish"
