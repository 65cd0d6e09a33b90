"""``somo-sweep run / show / plot / tasks``: the sweep engine's commands."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

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

from somo_sweep.cli.output import fail, figure_bytes, write_atomic
from somo_sweep.errors import SomoError

if TYPE_CHECKING:  # the heavy modules are imported when a command runs
    from somo_sweep.sweep.jobs import JobTable
    from somo_sweep.sweep.study import Study

_err = Console(stderr=True)
_out = Console()


def run(
    study: Annotated[Path, typer.Argument(help="Study file (YAML or JSON).")],
    jobs: Annotated[
        int, typer.Option("--jobs", "-j", help="Worker processes (loky); default: all cores.")
    ] = 0,
    dry_run: Annotated[
        bool, typer.Option("--dry-run", help="Print the job table; simulate nothing.")
    ] = False,
    backend: Annotated[str, typer.Option(help="loky (this machine) or dask (a cluster).")] = "loky",
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address, tcp://HOST:8786.")] = None,
    out: Annotated[
        Path | None, typer.Option("--out", help="Results folder (default: results/<study>).")
    ] = None,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="Draw summary plots at the end.")] = True,
    timeout: Annotated[float | None, typer.Option(help="Per-trial wall-time limit, s.")] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Delete results of a different (changed) study in --out.")
    ] = False,
    retry_errors: Annotated[
        bool, typer.Option("--retry-errors", help="Run again the trials stored as error (resume skips them).")
    ] = False,
    chunk_rows: Annotated[int, typer.Option(help="Rows per Parquet part file.", hidden=True)] = 50,
) -> None:
    """Run a study: every trial missing from its results folder, in parallel, into Parquet."""
    from somo_sweep.sweep.jobs import build_jobs
    from somo_sweep.sweep.runner import run_study
    from somo_sweep.sweep.study import load_study

    if backend not in ("loky", "dask"):
        fail(SomoError(f"--backend must be loky or dask, got '{backend}'"))
    if jobs < 0:
        fail(SomoError(f"--jobs must be >= 1, got {jobs}"))
    if backend == "dask" and not scheduler:
        fail(SomoError("--backend dask needs --scheduler ADDRESS (e.g. tcp://HOST:8786)"))
    try:
        st = load_study(study, out)
        table = build_jobs(st)
    except SomoError as exc:
        fail(exc)
    if dry_run:
        _print_dry_run(st, table)
        return
    n_jobs = jobs or os.cpu_count() or 1
    progress = Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.2f} trials/s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=_err,
    )
    bar = progress.add_task(st.name, total=None, rate=0.0)

    def started(n_todo: int, n_done: int) -> None:
        if n_done:
            _err.print(f"resuming {st.output}: {n_done} of {n_done + n_todo} trials already done")
        progress.update(bar, total=n_todo)

    def advanced(_: object) -> None:
        progress.advance(bar)
        task = progress.tasks[0]
        progress.update(bar, rate=(task.completed / task.elapsed) if task.elapsed else 0.0)

    try:
        with progress:
            summary = run_study(
                st,
                n_jobs,
                backend,  # type: ignore[arg-type]
                scheduler,
                table,
                chunk_rows=chunk_rows,
                timeout_s=timeout,
                overwrite=overwrite,
                retry_errors=retry_errors,
                on_start=started,
                on_outcome=advanced,
            )
    except SomoError as exc:
        fail(exc)
    from somo_sweep.sweep.summary import print_run_summary

    print_run_summary(_out, summary)
    if summary.interrupted is not None:
        _err.print(f"interrupted: {summary.run} finished trial(s) kept; run the same command again to resume")
        raise typer.Exit(128 + summary.interrupted)
    if plots and summary.run:
        try:
            _save_plots(st.output)
        except Exception as exc:  # the results are safe; a plot problem must not fail the run
            _err.print(f"warning: summary plots not drawn ({type(exc).__name__}: {exc}); try somo-sweep plot")


def _print_dry_run(st: Study, table: JobTable) -> None:
    frame = table.frame()
    typer.echo(
        f"{st.name}: task {st.task.name}, {len(frame)} trials "
        f"({st.n_points} grid points x {st.repeats} repeat(s)), study hash {table.study_hash}, "
        f"output {st.output}"
    )
    typer.echo(frame.head(10).to_string(index=False))
    if len(frame) > 10:
        typer.echo(f"... {len(frame) - 10} more")


def _save_plots(folder: Path) -> None:
    from somo_sweep.sweep.plots import summary_figure
    from somo_sweep.sweep.store import read_manifest, read_results

    fig = summary_figure(read_results(folder), read_manifest(folder))
    target = folder / "plots"
    write_atomic(target / "summary.png", figure_bytes(fig, "png", 120))
    fig = summary_figure(read_results(folder), read_manifest(folder))
    write_atomic(target / "summary.svg", figure_bytes(fig, "svg", 120))
    _out.print(f"plots: {target / 'summary.png'} (and .svg)")


def show(results: Annotated[Path, typer.Argument(help="Results folder, e.g. results/<study>.")]) -> None:
    """Print a results folder's summary: counts by status and label, per-axis breakdown."""
    from somo_sweep.sweep.store import read_manifest, read_results
    from somo_sweep.sweep.summary import print_results

    try:
        print_results(_out, read_results(results), read_manifest(results))
    except SomoError as exc:
        fail(exc)


def plot(results: Annotated[Path, typer.Argument(help="Results folder, e.g. results/<study>.")]) -> None:
    """Draw a results folder's summary plots (PNG and SVG in <folder>/plots)."""
    try:
        _save_plots(results)
    except SomoError as exc:
        fail(exc)


def tasks() -> None:
    """List the registered tasks (study files name them in ``task:``)."""
    from somo_sweep.tasks import all_tasks

    for name, spec in all_tasks().items():
        tags = f" [{', '.join(spec.tags)}]" if spec.tags else ""
        typer.echo(f"{name}{tags}: {spec.description}")


def recheck(
    study: Annotated[Path, typer.Argument(help="Study file whose finished results to recheck.")],
    trials: Annotated[int, typer.Option("--trials", "-n", help="How many stored trials to re-run.")] = 20,
    seed: Annotated[int, typer.Option(help="Seed of the random draw of trials.")] = 0,
    out: Annotated[
        Path | None, typer.Option("--out", help="Results folder (default: results/<study>).")
    ] = None,
    report: Annotated[Path | None, typer.Option(help="Also write the comparison as JSON here.")] = None,
) -> None:
    """Re-run random stored trials in this process; exit 1 unless every cell is identical."""
    from somo_sweep.sweep.recheck import recheck as run_recheck
    from somo_sweep.sweep.recheck import write_report
    from somo_sweep.sweep.study import load_study

    try:
        result = run_recheck(load_study(study, out), trials, seed)
    except SomoError as exc:
        fail(exc)
    if report is not None:
        write_report(result, report)
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
