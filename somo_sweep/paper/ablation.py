"""The Fig. 6 ablation as data: configurations between our model and the original's choices.

An ablation file (``studies/pinch_grasp_ablation.yaml``) names, per grid (``full``, ``quick``),
the study of our physical model (``ours``) and the study of the original's configuration
(``original``), the grasp rule of each, and the physical factors that separate them, each as
study overrides (``task.…`` / ``model.…`` key paths) with its value in ours and in the original::

    name: fig6_ablation
    grids:
      quick: {ours: pinch_grasp_quick.yaml, original: pinch_grasp_quick_original.yaml}
    rules: {ours: contacts, original: paper}
    factors:
      springs_x2:
        description: every finger joint's stiffness doubled
        ours: {task.spring_scale: 1.0}
        original: {task.spring_scale: 2.0}
      point_contacts:
        description: no spinning friction on the finger links and tips
        ours: {task.original.finger_spinning_friction_m: null}
        original: {task.original.finger_spinning_friction_m: 0.0}

:func:`configurations` makes ``ours``, ``original``, ``ours+<f>`` and ``original-<f>`` for
every factor, each a study derived from ``ours`` (so a configuration is exactly ours plus
overrides), checks that ``original`` derived this way is the original study (the same trials),
and groups configurations that come out the same so they share one results folder. The rule is
a factor too, but a free one: both labels are stored, so every configuration is evaluated
under both rules (:mod:`somo_sweep.paper.fig6_ablation`). A factor key that names a pinch-grasp
parameter by the name it had before it moved (``task.finger_spinning_friction_m``) is read at its
new place (``task.original.finger_spinning_friction_m``), with a notice (:attr:`AblationFile.notices`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, PrivateAttr

from somo_sweep.errors import DescriptionError, Problem, SomoError
from somo_sweep.model.description import Spec
from somo_sweep.model.files import load_mapping
from somo_sweep.model.tables import bundled_path
from somo_sweep.model.validation import validate
from somo_sweep.paper.fig6 import grasp_table
from somo_sweep.paper.fig6_ablation import ConfigResult
from somo_sweep.paper.fig6_compare import Side
from somo_sweep.paper.grasp_trials import read_results
from somo_sweep.sweep.jobs.table import JobTable, build_jobs
from somo_sweep.sweep.run.execution import Outcome
from somo_sweep.sweep.run.runner import RunEvents, RunOptions, RunSummary, run_sweep
from somo_sweep.sweep.study import Study, derive_study, load_study
from somo_sweep.sweep.study.moved import Renamed, moved_key, notice
from somo_sweep.tasks.registry import get_task

__all__ = [
    "ABLATION_FILE",
    "AblationFile",
    "Configuration",
    "Factor",
    "compare_sides",
    "configurations",
    "load_ablation",
    "read_configurations",
    "run_configurations",
]

#: The bundled ablation file.
ABLATION_FILE = bundled_path("pinch_grasp_ablation.yaml")
Rule = Literal["contacts", "paper"]


class Factor(Spec):
    """One physical factor: its overrides in our model and in the original's configuration."""

    description: str = ""
    ours: dict[str, Any]
    original: dict[str, Any]


class Grid(Spec):
    """The two end studies of one grid, relative to the ablation file."""

    ours: str
    original: str


class Rules(Spec):
    """The grasp rule of each end: ours (``contacts``) and the original's (``paper``)."""

    ours: Rule = "contacts"
    original: Rule = "paper"


class AblationFile(Spec):
    """The schema of an ablation file (see the module docstring)."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$")
    grids: dict[str, Grid] = Field(min_length=1)
    rules: Rules = Rules()
    factors: dict[str, Factor] = Field(min_length=1)
    _notices: tuple[str, ...] = PrivateAttr(default=())

    @property
    def notices(self) -> tuple[str, ...]:
        """What loading the file has to tell without refusing it (factor keys given by the name a
        parameter had before it moved), one line each."""
        return self._notices


@dataclass
class Configuration:
    """One configuration of the ablation.

    Attributes:
        name: ``ours``, ``original``, ``ours+<factor>`` or ``original-<factor>``.
        base: ``ours`` or ``original``: the end it starts from.
        factor: The factor changed from ``base`` (None for the ends).
        overrides: Study overrides applied to the ``ours`` study (every factor's value).
        study: The derived study (its ``output`` is the shared results folder).
        table: Its job table.
        same_as: The configuration whose results folder it shares (None if it owns one).
    """

    name: str
    base: str
    factor: str | None
    overrides: dict[str, Any]
    study: Study
    table: JobTable
    same_as: str | None = None

    @property
    def folder(self) -> Path:
        """The results folder."""
        return self.study.output


def load_ablation(path: str | Path = ABLATION_FILE) -> tuple[AblationFile, Path]:
    """Load and validate an ablation file; returns it and its folder (study paths are relative to it).

    Raises:
        DescriptionError: Every problem of the file at once.
    """
    path = Path(path)
    data, lines = load_mapping(path)
    spec, problems = _moved_factors(validate(AblationFile, data, str(path), lines), path, lines)
    for name, factor in spec.factors.items():
        if set(factor.ours) != set(factor.original):
            problems.append(
                Problem(
                    f"factors.{name}",
                    f"ours sets {sorted(factor.ours)} but original sets {sorted(factor.original)}; "
                    "allowed: the same key paths in both",
                    lines.get(f"factors.{name}"),
                )
            )
    if problems:
        raise DescriptionError(path, problems)
    return spec, path.parent


def _moved_factors(
    spec: AblationFile, path: Path, lines: dict[str, int]
) -> tuple[AblationFile, list[Problem]]:
    """``spec`` with every factor key that names a pinch-grasp parameter by its old name renamed,
    and a notice naming each (with its line); a field given by both names is a problem."""
    moved = get_task("pinch_grasp").moved
    renamed: list[Renamed] = []
    problems: list[Problem] = []
    factors = {}
    for name, factor in spec.factors.items():
        ends: dict[str, dict[str, Any]] = {}
        for end in ("ours", "original"):
            given: dict[str, Any] = getattr(factor, end)
            ends[end] = {}
            for key, value in given.items():
                new = moved_key(key, moved)
                where = f"factors.{name}.{end}.{key}"
                if new is not None and new in given:
                    problems.append(
                        Problem(
                            where,
                            f"gives {new} by the name it had before it moved, and "
                            f"factors.{name}.{end}.{new} gives it too; allowed: {new} alone",
                            lines.get(where),
                        )
                    )
                    continue
                if new is not None:
                    renamed.append(Renamed(where, new, lines.get(where)))
                ends[end][new or key] = value
        factors[name] = factor.model_copy(update=ends)
    out = spec.model_copy(update={"factors": factors})
    out._notices = tuple(n for n in [notice(path, renamed)] if n is not None)
    return out, problems


def _values(spec: AblationFile, ends: dict[str, str]) -> dict[str, Any]:
    """Every factor's overrides, each taken from the end named in ``ends`` (default: ours)."""
    out: dict[str, Any] = {}
    for name, factor in spec.factors.items():
        out.update(factor.original if ends.get(name, "ours") == "original" else factor.ours)
    return out


def configurations(spec: AblationFile, folder: Path, grid: str, results_root: Path) -> list[Configuration]:
    """Every configuration of one grid, with its study, job table and results folder.

    ``ours`` and ``original`` keep their studies' folder names under ``results_root``; the others
    go to ``results_root/<ablation name>_<grid>/<configuration>``. Configurations with the same
    trials share the first one's folder.

    Raises:
        SomoError: Unknown grid, or the original study is not ours plus every factor's original value.
        DescriptionError: A study or an override does not load.
    """
    if grid not in spec.grids:
        raise SomoError(f"unknown grid '{grid}'; allowed: {', '.join(spec.grids)}")
    ends = spec.grids[grid]
    ours = load_study(folder / ends.ours)
    original = load_study(folder / ends.original)
    factors = list(spec.factors)
    plans: list[tuple[str, str, str | None, dict[str, str], str]] = [
        ("ours", "ours", None, {}, ours.name),
        ("original", "original", None, dict.fromkeys(factors, "original"), original.name),
    ]
    for f in factors:
        plans.append((f"ours+{f}", "ours", f, {f: "original"}, f"ours_plus_{f}"))
    for f in factors:
        ends_f = {g: "original" for g in factors if g != f}
        plans.append((f"original-{f}", "original", f, ends_f, f"original_minus_{f}"))
    out: list[Configuration] = []
    by_hash: dict[str, Configuration] = {}
    for name, base, factor, chosen, folder_name in plans:
        overrides = _values(spec, chosen)
        target = (
            results_root / folder_name
            if factor is None
            else results_root / f"{spec.name}_{grid}" / folder_name
        )
        study = derive_study(ours, overrides, name=folder_name, output=target)
        table = build_jobs(study)
        first = by_hash.get(table.study_hash)
        if first is not None:
            study = replace(study, output=first.folder)
        config = Configuration(name, base, factor, overrides, study, table, first.name if first else None)
        by_hash.setdefault(table.study_hash, config)
        out.append(config)
    _check_original(out[1], original)
    # What loading the two end studies had to say (the derived ones carry ours's).
    notices = tuple(dict.fromkeys((*out[1].study.notices, *original.notices)))
    out[1].study = replace(out[1].study, notices=notices)
    return out


def _check_original(derived: Configuration, original: Study) -> None:
    """The original study file must hold exactly ours plus every factor's original value."""
    if derived.table.study_hash != build_jobs(original).study_hash:
        raise SomoError(
            f"{original.source}: its trials differ from {derived.study.source} with every factor's "
            f"original value ({derived.overrides}); make the original study the ours study plus "
            "exactly these overrides (same grid, model, simulation and seed)"
        )


def run_configurations(
    configs: list[Configuration],
    n_jobs: int | None = None,
    adaptive: bool = True,
    on_config: Callable[[Configuration], None] | None = None,
    on_done: Callable[[Configuration, RunSummary], None] | None = None,
    on_outcome: Callable[[Outcome], None] | None = None,
) -> list[RunSummary]:
    """Run the trials missing from every configuration's folder (each shared folder once).

    Resumable: each run is :func:`somo_sweep.sweep.run.runner.run_sweep`, the function behind
    ``somo-sweep run``. Stops after a run that was interrupted (SIGINT / SIGTERM).

    Args:
        configs: From :func:`configurations`.
        n_jobs: Worker processes (default: the CPUs this process may use).
        adaptive: Sample adaptively (coarse sub-grid, then refine where labels change).
        on_config: Called before each configuration runs.
        on_done: Called with each configuration's run summary.
        on_outcome: Called with every finished trial.
    """
    summaries: list[RunSummary] = []
    for config in configs:
        if config.same_as is not None:
            continue
        if on_config is not None:
            on_config(config)
        options = RunOptions(n_jobs=n_jobs, adaptive=adaptive)
        summary = run_sweep(config.study, options, RunEvents(outcome=on_outcome), table=config.table)
        summaries.append(summary)
        if on_done is not None:
            on_done(config, summary)
        if summary.interrupted is not None:
            break
    return summaries


def read_configurations(configs: list[Configuration], rules: tuple[str, ...]) -> list[ConfigResult]:
    """Every configuration's results folder as grasp tables under each rule.

    Raises:
        SomoError: A folder is missing or holds no trials (run the configurations first).
    """
    out = []
    tables: dict[Path, dict[str, Any]] = {}
    for config in configs:
        if config.folder not in tables:
            results = read_results(config.folder)
            tables[config.folder] = {rule: grasp_table(results, rule) for rule in rules}
        folder = config.folder.name
        out.append(
            ConfigResult(
                config.name, config.base, config.factor, folder, tables[config.folder], config.overrides
            )
        )
    return out


def compare_sides(results: list[ConfigResult], spec: AblationFile) -> list[Side]:
    """Ours under our rule and the original under its rule, for the side-by-side figure."""
    by_name = {r.name: r for r in results}
    return [
        Side("ours", spec.rules.ours, by_name["ours"].tables[spec.rules.ours]),
        Side("original", spec.rules.original, by_name["original"].tables[spec.rules.original]),
    ]
