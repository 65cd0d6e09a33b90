"""A design question as a user types it (axis names, a label), made into a
:class:`~somo_sweep.sweep.views.answers.Question` on a results table.

An axis may be named as the study names it (``task.distal_segment_ratio``), by its column
(``task_distal_segment_ratio``) or by its last field alone (``distal_segment_ratio``) when that is
unique; ``repeat`` names the repeats. A label is ``NAME=VALUE`` (``grasp=pinch``) or a value alone,
looked for in the label columns in order. The axes the question does not name, with more than one
value, are the ones it is answered per value of.
"""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from somo_sweep.errors import SomoError, did_you_mean, shown
from somo_sweep.sweep.run.robustness import label_names
from somo_sweep.sweep.store.folder import SWEPT_AXES
from somo_sweep.sweep.views.answers import Question
from somo_sweep.sweep.views.axes import grid_keys

__all__ = ["label_of", "question_for", "swept_axes"]


def swept_axes(trials: pd.DataFrame, varying: bool = True) -> dict[str, str]:
    """The swept axes of a results table, name → column: the study's key paths (its manifest's,
    in ``attrs``; else every ``task_*`` column), and ``repeat`` when trials repeat; with
    ``varying``, only those with more than one value (float noise aside)."""
    named = trials.attrs.get(SWEPT_AXES)
    if isinstance(named, dict):
        axes = {str(k): v for k, v in named.items() if isinstance(v, str) and v in trials.columns}
    else:
        axes = {str(c): str(c) for c in trials.columns if str(c).startswith("task_")}
    if "repeat" in trials.columns and trials["repeat"].nunique() > 1:
        axes["repeat"] = "repeat"
    if not varying:
        return axes
    return {k: c for k, c in axes.items() if grid_keys(trials, [c])[c].nunique() > 1}


def _column(name: str, axes: dict[str, str], option: str) -> str:
    """The column of the axis ``name`` (module docstring).

    Raises:
        SomoError: No such axis, or a last field two axes share; naming the swept axes.
    """
    if name in axes:
        return axes[name]
    if name in axes.values():
        return name
    tails = [k for k in axes if k.rsplit(".", 1)[-1] == name]
    if len(tails) == 1:
        return axes[tails[0]]
    known = ", ".join(axes) or "none with more than one value"
    if len(tails) > 1:
        raise SomoError(f"{option} {name}: several axes end so ({', '.join(tails)}); give the whole key path")
    hint = did_you_mean(name, [*axes, *(k.rsplit(".", 1)[-1] for k in axes)])
    raise SomoError(f"{option} {shown(name)}: not a swept axis of these results{hint}; allowed: {known}")


def label_of(trials: pd.DataFrame, given: str) -> tuple[str, str]:
    """The label column and value of ``NAME=VALUE`` or ``VALUE`` (module docstring).

    Raises:
        SomoError: An unknown label name, or a value no label column holds; naming what there is.
    """
    columns = label_names(trials)
    if not columns:
        raise SomoError("these results have no label columns: there is no label to ask for")
    if "=" in given:
        name, value = (part.strip() for part in given.split("=", 1))
        column = f"label_{name.removeprefix('label_')}"
        if column not in columns:
            allowed = ", ".join(c.removeprefix("label_") for c in columns)
            hint = did_you_mean(name, [c.removeprefix("label_") for c in columns])
            raise SomoError(f"--label {shown(given)}: no label '{shown(name)}'{hint}; allowed: {allowed}")
        return column, value
    for column in columns:
        if trials[column].astype(str).eq(given).any():
            return column, given
    values = sorted({str(v) for c in columns for v in trials[c].dropna().unique()})
    raise SomoError(
        f"--label {shown(given)}: no trial has this label; the labels are: {', '.join(values[:20])} "
        "(give NAME=VALUE, e.g. grasp=pinch)"
    )


def question_for(
    trials: pd.DataFrame,
    axis: str,
    every: Sequence[str],
    some: Sequence[str] = (),
    label: str = "pinch",
    largest: bool = False,
) -> Question:
    """The question, its axes resolved on ``trials`` (a results table); the other swept axes are
    the ones it is answered per value of.

    Raises:
        SomoError: An unknown or repeated axis, no object axis, or an unknown label.
    """
    axes = swept_axes(trials, varying=False)
    option = "--largest" if largest else "--smallest"
    asked = _column(axis, axes, option)
    if not every:
        raise SomoError(
            "give the object axes with --every (the label must hold at each of their values); the swept "
            f"axes are: {', '.join(axes)}"
        )
    objects = tuple(_column(a, axes, "--every") for a in every)
    chosen = tuple(_column(a, axes, "--some") for a in some)
    named = [asked, *objects, *chosen]
    twice = next((c for c in named if named.count(c) > 1), None)
    if twice is not None:
        raise SomoError(f"axis {twice} is named twice; give each axis one role")
    column, value = label_of(trials, label)
    per = tuple(c for c in swept_axes(trials).values() if c not in named)
    return Question(asked, column, value, objects, chosen, per, largest)
