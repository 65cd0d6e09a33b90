"""``somo-sweep show``, ``plot`` and ``recheck``: what a results folder holds, drawn, and re-run."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console

from somo_sweep.cli.output import (
    check_replaceable,
    fail,
    figure_bytes,
    file_target,
    json_report,
    say_notes,
    write_atomic,
    write_outputs,
)
from somo_sweep.errors import SomoError

if TYPE_CHECKING:
    from somo_sweep.sweep.store.parts import Damage

__all__ = ["ALLOW_OUTSIDE", "MAX_TRIALS", "damaged", "plot", "recheck", "save_plots", "show"]


def _out() -> Console:
    """The standard output's console, made at each use: its width follows the terminal (or
    ``COLUMNS``) as it is now, not as it was when this module was imported."""
    return Console()


#: Default of ``--max-trials`` (the library's :data:`somo_sweep.sweep.study.file.MAX_TRIALS`).
MAX_TRIALS = 1_000_000
#: Keys of every ``recheck --report`` file (earlier versions wrote it without the JSON mark).
RECHECK_KEYS = frozenset({"trials", "columns_compared", "identical", "mismatches"})

ALLOW_OUTSIDE = Annotated[
    bool,
    typer.Option(
        "--allow-outside", help="Let model files include files outside their own folder (file: ../x.yaml)."
    ),
]


def damaged(path: Path, reason: Damage) -> None:
    """Warn of a file of a results folder that a reader left out (or whose rows it counted once)."""
    from somo_sweep.sweep.store.folder import INFERRED

    if reason.kind == "unreadable":
        typer.echo(
            f"warning: part file {path} {reason}: its trials are left out; give read access to it", err=True
        )
        return
    if path.name == INFERRED and path.parent.joinpath("manifest.json").exists():
        what = reason.detail if reason.kind == "repeats" else f"skipped ({reason})"
        typer.echo(f"warning: {path}: {what}; the next adaptive run of this study rebuilds it", err=True)
        return
    if reason.kind == "repeats":  # readable, but a copy: its rows are counted once
        typer.echo(f"warning: part file {path} {reason}", err=True)
        return
    typer.echo(
        f"warning: skipped damaged part file {path} ({reason}); the next somo-sweep run of this study "
        "moves it to trials/quarantine/ and runs its trials again",
        err=True,
    )


def save_plots(folder: Path) -> None:
    """The summary figure and, for a study with labels, a label map per label column."""
    from somo_sweep.sweep.store.folder import SKIPPED
    from somo_sweep.sweep.store.manifest import record_files
    from somo_sweep.sweep.views.label_maps import label_maps
    from somo_sweep.sweep.views.plots import summary_figure
    from somo_sweep.sweep.views.results import open_results

    results = open_results(folder, damaged)
    if results.trials.empty:
        left_out = int(results.trials.attrs.get(SKIPPED, 0))
        why = f": {left_out} damaged file(s) were left out (the warnings above name them)" if left_out else ""
        raise SomoError(
            f"{folder}: no trial stored that can be read{why}; nothing to plot, nothing was written"
        )
    target = folder / "plots"
    if target.is_symlink():
        raise SomoError(f"{target} is a symbolic link; the plots go in the results folder itself: remove it")
    summary = summary_figure(results)  # drawn once, rendered in both formats
    files = [
        (target / "summary.png", figure_bytes(summary, "png", 120, close=False)),
        (target / "summary.svg", figure_bytes(summary, "svg", 120)),
    ]
    files += [(target / f"{name}.png", figure_bytes(fig, "png", 120)) for name, fig in label_maps(results)]
    written = write_outputs(files)
    record_files(folder, written)
    maps = [path.name for path, _ in files[2:]]
    if maps:
        _out().print(f"label maps: {', '.join(maps)} in {target}")
    _out().print(f"plots: {target / 'summary.png'} (and .svg)")


def show(results: Annotated[Path, typer.Argument(help="Results folder, e.g. results/<study>.")]) -> None:
    """Print a results folder's summary: counts by status and label, per-axis breakdown."""
    from somo_sweep.cli.summary import print_results
    from somo_sweep.sweep.store.lock import holder_now
    from somo_sweep.sweep.views.results import open_results

    try:
        opened = open_results(results, damaged)
        say_notes(_old_columns(results, opened.trials.columns, opened.manifest))
        print_results(_out(), opened, holder_now(results))
    except SomoError as exc:
        fail(exc)


def _old_columns(folder: Path, columns: Iterable[object], manifest: dict[str, Any]) -> list[str]:
    """The note on a folder whose columns name parameters that have moved since (none: none)."""
    from somo_sweep.sweep.study.moved import old_columns_notice
    from somo_sweep.tasks.registry import all_tasks

    spec = all_tasks().get(str(manifest.get("study", {}).get("task")))
    said = old_columns_notice(folder, map(str, columns), spec.moved) if spec is not None else None
    return [said] if said else []


def plot(results: Annotated[Path, typer.Argument(help="Results folder, e.g. results/<study>.")]) -> None:
    """Draw a results folder's summary plots (PNG and SVG in <folder>/plots)."""
    try:
        save_plots(results)
    except SomoError as exc:
        fail(exc)


def recheck(
    study: Annotated[Path, typer.Argument(help="Study file whose finished results to recheck.")],
    trials: Annotated[int, typer.Option("--trials", "-n", help="How many stored trials to re-run.")] = 20,
    seed: Annotated[int, typer.Option(help="Seed of the random draw of trials.")] = 0,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Results folder, anywhere (default: the study's, inside results/)."),
    ] = None,
    report: Annotated[
        str | None,
        typer.Option(
            metavar="<path>",
            help="Also write the comparison as JSON here; a folder (out/, or one that exists) gets "
            "recheck.json in it.",
        ),
    ] = None,
    max_trials: Annotated[
        int, typer.Option("--max-trials", help="Refuse a study with more trials than this.")
    ] = MAX_TRIALS,
    allow_outside: ALLOW_OUTSIDE = False,
) -> None:
    """Re-run random stored trials in this process; exit 1 unless every cell is identical."""
    import json

    from somo_sweep.sweep.study import load_study
    from somo_sweep.sweep.views.recheck import recheck as run_recheck

    if max_trials < 1:
        fail(SomoError(f"--max-trials must be >= 1, got {max_trials}"))
    if not 0 <= seed < 2**63:
        fail(SomoError(f"--seed must be from 0 to 2**63 - 1, got {seed}"))
    target = file_target(report, "recheck.json")
    try:
        if target is not None:
            check_replaceable(target, [study], kind="json", older_keys=RECHECK_KEYS)
        loaded = load_study(study, out, max_trials, allow_outside)
        say_notes(loaded.notices)
        result = run_recheck(loaded, trials, seed, damaged)
    except SomoError as exc:
        fail(exc)
    if target is not None:
        write_atomic(target, json_report(json.loads(json.dumps(result.to_dict(), default=str)), "recheck"))
    n_bad = len({m.trial for m in result.mismatches})
    typer.echo(
        f"re-ran {len(result.trials)} trial(s) {sorted(result.trials)}: "
        f"{len(result.trials) - n_bad} identical, {n_bad} different "
        f"({result.columns_compared} cells compared; status, labels, metrics, parameters)"
    )
    for m in result.mismatches[:20]:
        typer.echo(f"  trial {m.trial}: {m.column}: stored {m.stored!r}, re-run {m.rerun!r}")
    if not result.identical:
        raise typer.Exit(1)
