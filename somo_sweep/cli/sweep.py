"""``somo-sweep run``: run a study (:func:`~somo_sweep.sweep.run.runner.run_sweep`) and show it as it
goes: the step's choice, a bar per round, the summary (a dry run prints :mod:`somo_sweep.cli.dry_run`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, NoReturn, cast

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from somo_sweep.cli.dry_run import DRY_ROWS, print_dry_run
from somo_sweep.cli.output import fail, say_notes
from somo_sweep.cli.results import ALLOW_OUTSIDE, MAX_TRIALS, save_plots
from somo_sweep.errors import Interrupted, SomoError

if TYPE_CHECKING:  # the heavy modules are imported when a command runs
    from somo_sweep.sweep.run.convergence import StepChoice, StepEvents
    from somo_sweep.sweep.run.execution import Backend
    from somo_sweep.sweep.run.options import RunEvents, RunOptions, RunSummary
    from somo_sweep.sweep.run.runner import RunPlan
    from somo_sweep.sweep.run.sampling import Batch
    from somo_sweep.sweep.study import Study

__all__ = ["JOBS", "MAX_TRIALS", "run", "step_events"]


def _err() -> Console:
    """The standard error's console, made at each use (see :func:`_out`)."""
    return Console(stderr=True)


def _out() -> Console:
    """The standard output's console, made at each use: its width follows the terminal (or
    ``COLUMNS``) as it is now, not as it was when this module was imported."""
    return Console()


#: ``--jobs``, as ``run`` and ``compare-engines`` take it.
JOBS = Annotated[
    int,
    typer.Option("--jobs", "-j", help="Worker processes (loky); default: the CPUs this process may use."),
]
_DRY_RUN = Annotated[
    bool,
    typer.Option(
        "--dry-run",
        help="Print the job table, the runs (replicas counted) and the time they take, from one trial "
        "of the study timed; write nothing.",
    ),
]
_ESTIMATE = Annotated[
    bool,
    typer.Option(
        "--estimate/--no-estimate",
        help="With --dry-run: time trial 0 of the study to estimate the run's wall time (default); "
        "--no-estimate counts the runs only.",
    ),
]
_BACKEND = Annotated[str, typer.Option(help="loky (this machine) or dask (a cluster).")]
_SCHEDULER = Annotated[str | None, typer.Option(help="Dask scheduler address, tcp://HOST:8786.")]
_OUT = Annotated[
    Path | None,
    typer.Option("--out", help="Results folder, anywhere (default: the study's, inside results/)."),
]
_PLOTS = Annotated[bool, typer.Option("--plots/--no-plots", help="Draw summary plots at the end.")]
_TIMEOUT = Annotated[float | None, typer.Option(help="Per-trial wall-time limit, s.")]
_OVERWRITE = Annotated[
    bool, typer.Option("--overwrite", help="Delete results of a different (changed) study in --out.")
]
_RETRY_ERRORS = Annotated[
    bool, typer.Option("--retry-errors", help="Run again the trials stored as error (resume skips them).")
]
_ALLOW_ERRORS = Annotated[
    bool, typer.Option("--allow-errors", help="Exit 0 even if trials ended in error (default: exit 1).")
]
_MAX_TRIALS = Annotated[int, typer.Option("--max-trials", help="Refuse a study with more trials than this.")]
_ADAPTIVE = Annotated[
    bool | None,
    typer.Option(
        "--adaptive/--exhaustive",
        help="Simulate a coarse sub-grid, then only where labels change; the other cells are "
        "stored as inferred (default: the study's sampling:, else exhaustive).",
    ),
]
#: Most replicas ``--robust`` takes (the library's :data:`somo_sweep.sweep.store.schema.MAX_REPLICAS`;
#: named here so that the command line imports no Arrow).
MAX_REPLICAS = 16
_ROBUST = Annotated[
    int | None,
    typer.Option(
        "--robust",
        metavar="K",
        min=0,
        max=MAX_REPLICAS,
        help="Run K perturbed replicas of the cells that matter (label boundaries, plus a 10 % audit "
        "of the rest) and store each cell's majority label, agreement and robust flag "
        "(default: the study's robustness:, else 0).",
    ),
]
_CHUNK_ROWS = Annotated[int, typer.Option(help="Rows per Parquet part file.", hidden=True)]


def run(
    study: Annotated[Path, typer.Argument(help="Study file (YAML or JSON).")],
    jobs: JOBS = 0,
    dry_run: _DRY_RUN = False,
    estimate: _ESTIMATE = True,
    backend: _BACKEND = "loky",
    scheduler: _SCHEDULER = None,
    out: _OUT = None,
    plots: _PLOTS = True,
    timeout: _TIMEOUT = None,
    overwrite: _OVERWRITE = False,
    retry_errors: _RETRY_ERRORS = False,
    allow_errors: _ALLOW_ERRORS = False,
    max_trials: _MAX_TRIALS = MAX_TRIALS,
    allow_outside: ALLOW_OUTSIDE = False,
    adaptive: _ADAPTIVE = None,
    robust: _ROBUST = None,
    chunk_rows: _CHUNK_ROWS = 50,
) -> None:
    """Run a study: every trial missing from its results folder, in parallel, into Parquet.

    Exits 1 if a trial of the study ended in error (see --allow-errors, --retry-errors).
    """
    from somo_sweep.sweep.run.options import RunOptions

    chosen = cast("Backend", backend)  # RunOptions.check refuses any other
    options = RunOptions(
        jobs, chosen, scheduler, timeout, overwrite, retry_errors, adaptive, robust, chunk_rows
    )
    try:
        options.check(max_trials)
        if out is not None and out.exists() and not out.is_dir():
            raise SomoError(f"--out {out} is a file, not a folder")
    except SomoError as exc:
        fail(exc)
    plan = _planned(study, out, max_trials, allow_outside, options, dry_run, estimate)
    if plan is None:  # a dry run: printed
        return
    summary = _run(plan)
    _report(summary, plots, allow_errors)


def _planned(
    path: Path,
    out: Path | None,
    max_trials: int,
    allow_outside: bool,
    options: RunOptions,
    dry: bool = False,
    estimate: bool = True,
) -> RunPlan | None:
    """The study's run as ``options`` make it, or None once its dry run (``dry``) is printed."""
    from somo_sweep.sweep.run.runner import dry_run, plan_run
    from somo_sweep.sweep.study import load_study

    try:
        study = load_study(path, out, max_trials, allow_outside)
        say_notes(study.notices)
        plan = plan_run(study, options)
        if dry:
            print_dry_run(dry_run(plan, DRY_ROWS), options.workers, estimate)
            return None
        return plan
    except SomoError as exc:
        fail(exc)
    except KeyboardInterrupt:
        _interrupted("jobs", 2)


def _run(plan: RunPlan) -> RunSummary:
    """Run the plan with a progress bar per round; an error or an interrupt ends the command."""
    from somo_sweep.sweep.run.runner import run_plan

    view = _RunView(plan.study)
    try:
        return run_plan(plan, view.events())
    except SomoError as exc:
        view.stop()
        fail(exc)
    except Interrupted as exc:
        view.stop()
        _interrupted(exc.stage, exc.signum)
    except KeyboardInterrupt:  # before the run's own stages (the URDF cache checked, workers starting)
        view.stop()
        _interrupted("jobs", 2)
    finally:
        view.stop()


def _interrupted(stage: str, signum: int) -> NoReturn:
    """Say what an interrupt before the first trial stopped, and exit with the signal's code."""
    if stage == "step":
        _err().print(
            "interrupted while choosing the time step: no trial of the study ran yet; run the "
            "same command again to start over"
        )
        raise typer.Exit(128 + signum)
    if stage == "folder":
        typer.echo(
            "interrupted while opening the results folder, before any trial: finished trial(s) kept; run the "
            "same command again to resume",
            err=True,
        )
    else:
        typer.echo(
            "interrupted while building the job table, before any trial: nothing was written", err=True
        )
    raise typer.Exit(130)


def step_events(say: Callable[[str], None], folder: Path) -> StepEvents:
    """How the choice of a study's automatic step is told (``say`` one line at a time)."""
    from somo_sweep.sweep.run.convergence import StepEvents

    def reused(choice: StepChoice) -> None:
        say(f"automatic step {choice.step_s * 1e3:g} ms (chosen earlier, from {folder})")

    def choosing() -> None:
        say(
            "no simulation: block: choosing the time step from this study's own cells (label convergence "
            "against half the step)"
        )

    def rung(step_s: float, runs: int) -> None:
        say(f"  trying {step_s * 1e3:g} ms: {runs} sample run(s)")

    def chosen(choice: StepChoice) -> None:
        for line in choice.describe():
            say(f"  {line}")

    return StepEvents(reused, choosing, rung, chosen)


class _RunView:
    """What ``run`` shows on stderr as the run goes: the step's choice, notes, a bar per round."""

    def __init__(self, study: Study):
        self.study = study
        self.live: list[Progress] = []  # the progress bar, once the results folder is open

    def events(self) -> RunEvents:
        from somo_sweep.sweep.run.options import RunEvents

        step = step_events(lambda text: typer.echo(text, err=True), self.study.output)
        return RunEvents(step, self.started, self.new_round, self.advanced)

    def started(self, summary: RunSummary) -> None:
        for note in summary.notes:
            typer.echo(f"note: {note}", err=True)
        if summary.stored_errors:
            typer.echo(
                f"resuming {summary.folder}: {summary.skipped} of {summary.total} trials already stored, "
                f"{summary.stored_errors} of them as error; run with --retry-errors to run those again",
                err=True,
            )
        elif summary.skipped:
            typer.echo(
                f"resuming {summary.folder}: {summary.skipped} of {summary.total} trials already done",
                err=True,
            )
        progress = _progress()
        progress.start()
        self.live.append(progress)

    def new_round(self, batch: Batch) -> None:
        if batch.kind == "active":  # one bar for every batch: its total grows batch after batch
            progress = self.live[0]
            if not progress.tasks:
                progress.add_task("active sampling", total=0, rate=0.0)
            task = progress.tasks[-1]
            progress.update(task.id, total=(task.total or 0) + len(batch.jobs))
            return
        if batch.kind == "replicas":
            name = f"replicas {batch.number}: {batch.cells} cells x {batch.replicas}"
        else:
            name = self.study.name if batch.number is None else f"round {batch.number}: {batch.cells} cells"
            if batch.number == 0:
                name += " (coarse)"
        self.live[0].add_task(name, total=len(batch.jobs), rate=0.0)

    def advanced(self, _: object) -> None:
        task = self.live[0].tasks[-1]
        self.live[0].advance(task.id)
        self.live[0].update(task.id, rate=(task.completed / task.elapsed) if task.elapsed else 0.0)

    def stop(self) -> None:
        while self.live:
            self.live.pop().stop()


def _report(summary: RunSummary, plots: bool, allow_errors: bool) -> None:
    """The run's summary, its plots; exit 128 + signal if it was stopped, 1 if trials ended in error."""
    from somo_sweep.cli.summary import print_run_summary

    print_run_summary(_out(), summary)
    if summary.interrupted is not None:
        replicas = f" and {summary.replicas_run} robustness replica run(s)" if summary.replicas_run else ""
        _err().print(
            f"interrupted: {summary.run} finished trial(s){replicas} kept; run the same command again to "
            "resume"
        )
        raise typer.Exit(128 + summary.interrupted)
    if plots and summary.run:
        try:
            save_plots(summary.folder)
        except Exception as exc:  # the results are safe; a plot problem must not fail the run
            _err().print(
                f"warning: summary plots not drawn ({type(exc).__name__}: {exc}); try somo-sweep plot"
            )
    if summary.errors and not allow_errors:
        between = (
            f", and {summary.inferred_errors} inferred cell(s) between them are marked error without running"
            if summary.inferred_errors
            else ""
        )
        typer.echo(
            f"{summary.errors} of {summary.total} trial(s) ended in error{between} (exit code 1); see "
            f"somo-sweep show {summary.folder}; --retry-errors runs them again, --allow-errors accepts them",
            err=True,
        )
        raise typer.Exit(1)


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.2f} trials/s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=_err(),
    )
