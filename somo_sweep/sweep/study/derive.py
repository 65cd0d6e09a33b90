"""Variants of a loaded study: another sampling, replica count or step, extra fixed overrides.

A :class:`~somo_sweep.sweep.study.loaded.Study` never changes; each function here returns a new one,
checked as a loaded study is.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.sweep.store.schema import MAX_REPLICAS
from somo_sweep.sweep.study.axes import parse_key_path
from somo_sweep.sweep.study.checks import check_points, no_perturbation
from somo_sweep.sweep.study.loaded import Study
from somo_sweep.sweep.study.moved import moved_key

__all__ = ["derive_study", "with_auto_step", "with_replicas", "with_sampling"]


def with_sampling(study: Study, adaptive: bool) -> Study:
    """``study`` sampled adaptively (``--adaptive``) or exhaustively (``--exhaustive``)."""
    return replace(study, sampling="adaptive" if adaptive else "grid")


def with_replicas(study: Study, replicas: int) -> Study:
    """``study`` with ``replicas`` robustness replicas per chosen cell (``--robust K``).

    Raises:
        DescriptionError: Out of range, or the task defines no perturbation.
    """
    if not 0 <= replicas <= MAX_REPLICAS:
        raise DescriptionError(
            study.source,
            [Problem("robustness.replicas", f"--robust must be 0 … {MAX_REPLICAS}, got {replicas}")],
        )
    if replicas and study.task.perturb is None:
        raise DescriptionError(study.source, [Problem("robustness.replicas", no_perturbation(study.task))])
    return replace(study, robustness=study.robustness.model_copy(update={"replicas": replicas}))


def with_auto_step(study: Study, step_s: float, record: dict[str, Any] | None) -> Study:
    """``study`` (without ``simulation:``) run at the automatic step ``step_s``, each model shaped
    for it; ``record`` is how the step was chosen (for the manifest)."""
    return replace(study, auto_step_s=step_s, convergence=record)


def derive_study(study: Study, overrides: dict[str, Any], name: str, output: str | Path) -> Study:
    """A copy of ``study`` with extra fixed overrides (as in its ``set:``), a new name and folder.

    Used for configurations generated from one study (the Fig. 6 ablation). Every trial of the
    copy is checked as at load; problems are reported against ``set.<key>`` of ``study``'s file.

    Args:
        study: A loaded study.
        overrides: Key path (``task.…`` or ``model.…``) → value; replaces ``set:`` entries and
            must not name a swept axis.
        name: Name of the derived study.
        output: Its results folder.

    Raises:
        DescriptionError: A key path is malformed, swept, a parameter's name before it moved (a study
            file's are read at their new place: :mod:`.moved`), or its value does not fit.
    """
    problems: list[Problem] = []
    swept = {a.key for a in study.axes}
    for key in overrides:
        try:
            parse_key_path(key)
        except ValueError as exc:
            problems.append(Problem(f"set.{key}", str(exc)))
            continue
        if key in swept or key == "model":
            problems.append(Problem(f"set.{key}", "is a sweep axis of the study; allowed: a fixed key path"))
        elif (new := moved_key(key, study.task.moved)) is not None:
            problems.append(Problem(f"set.{key}", f"is the name {new} had before it moved; allowed: {new}"))
    if problems:
        raise DescriptionError(study.source, problems)
    # The model files are shared (their content as loaded); overrides are applied per trial.
    derived = replace(study, name=name, fixed={**study.fixed, **overrides}, output=Path(output))
    check_points(derived, {}, problems)
    if problems:
        raise DescriptionError(study.source, problems)
    return derived
