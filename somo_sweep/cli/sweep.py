"""``somo-sweep run / show / plot / tasks``: the sweep engine's commands."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
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

from somo_sweep.cli.output import (
    check_replaceable,
    checked_jobs,
    fail,
    figure_bytes,
    file_target,
    json_report,
    write_atomic,
    write_outputs,
)
from somo_sweep.errors import SomoError, StorageError, os_cause, shown

if TYPE_CHECKING:  # the heavy modules are imported when a command runs
    from collections.abc import Callable

    from somo_sweep.sweep.jobs import Job
    from somo_sweep.sweep.runner import RunSummary
    from somo_sweep.sweep.sampling import Batch
    from somo_sweep.sweep.study import Study

_err = Console(stderr=True)
_out = Console()
#: Default of ``--max-trials`` (the library's :data:`somo_sweep.sweep.study.MAX_TRIALS`).
MAX_TRIALS = 1_000_000
#: Rows a dry run prints.
DRY_ROWS = 10
#: Keys of every ``recheck --report`` file (earlier versions wrote it without the JSON mark).
RECHECK_KEYS = frozenset({"trials", "columns_compared", "identical", "mismatches"})

ALLOW_OUTSIDE = Annotated[
    bool,
    typer.Option(
        "--allow-outside", help="Let model files include files outside their own folder (file: ../x.yaml)."
    ),
]


def run(
    study: Annotated[Path, typer.Argument(help="Study file (YAML or JSON).")],
    jobs: Annotated[
        int,
        typer.Option("--jobs", "-j", help="Worker processes (loky); default: the CPUs this process may use."),
    ] = 0,
    dry_run: Annotated[
        bool, typer.Option("--dry-run", help="Print the job table; simulate nothing.")
    ] = False,
    backend: Annotated[str, typer.Option(help="loky (this machine) or dask (a cluster).")] = "loky",
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address, tcp://HOST:8786.")] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Results folder, anywhere (default: the study's, inside results/)."),
    ] = None,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="Draw summary plots at the end.")] = True,
    timeout: Annotated[float | None, typer.Option(help="Per-trial wall-time limit, s.")] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Delete results of a different (changed) study in --out.")
    ] = False,
    retry_errors: Annotated[
        bool, typer.Option("--retry-errors", help="Run again the trials stored as error (resume skips them).")
    ] = False,
    allow_errors: Annotated[
        bool, typer.Option("--allow-errors", help="Exit 0 even if trials ended in error (default: exit 1).")
    ] = False,
    max_trials: Annotated[
        int, typer.Option("--max-trials", help="Refuse a study with more trials than this.")
    ] = MAX_TRIALS,
    allow_outside: ALLOW_OUTSIDE = False,
    adaptive: Annotated[
        bool | None,
        typer.Option(
            "--adaptive/--exhaustive",
            help="Simulate a coarse sub-grid, then only where labels change; the other cells are "
            "stored as inferred (default: the study's sampling:, else exhaustive).",
        ),
    ] = None,
    robust: Annotated[
        int | None,
        typer.Option(
            "--robust",
            metavar="K",
            help="Run K perturbed replicas of the cells that matter (label boundaries, plus a 10 % audit "
            "of the rest) and store each cell's majority label, agreement and robust flag "
            "(default: the study's robustness:, else 0).",
        ),
    ] = None,
    chunk_rows: Annotated[int, typer.Option(help="Rows per Parquet part file.", hidden=True)] = 50,
) -> None:
    """Run a study: every trial missing from its results folder, in parallel, into Parquet.

    Exits 1 if a trial of the study ended in error (see --allow-errors, --retry-errors).
    """
    import joblib

    from somo_sweep.sweep.execution import start_workers, stop_workers
    from somo_sweep.sweep.jobs import build_jobs
    from somo_sweep.sweep.runner import run_study
    from somo_sweep.sweep.study import load_study, with_replicas, with_sampling

    if backend not in ("loky", "dask"):
        fail(SomoError(f"--backend must be loky or dask, got '{backend}'"))
    try:
        checked_jobs(jobs, allow_default=True)
    except SomoError as exc:
        fail(exc)
    if timeout is not None and not (math.isfinite(timeout) and timeout > 0):
        fail(SomoError(f"--timeout must be a number of seconds > 0, got {timeout:g}"))
    if max_trials < 1:
        fail(SomoError(f"--max-trials must be >= 1, got {max_trials}"))
    if backend == "dask" and not scheduler:
        fail(SomoError("--backend dask needs --scheduler ADDRESS (e.g. tcp://HOST:8786)"))
    if scheduler and backend != "dask":
        fail(SomoError(f"--scheduler is for --backend dask; with --backend {backend} the trials run here"))
    if chunk_rows < 1:
        fail(SomoError(f"--chunk-rows must be >= 1, got {chunk_rows}"))
    if out is not None and out.exists() and not out.is_dir():
        fail(SomoError(f"--out {out} is a file, not a folder"))
    try:
        st = load_study(study, out, max_trials, allow_outside)
        if adaptive is not None:
            st = with_sampling(st, adaptive)
        if robust is not None:
            st = with_replicas(st, robust)
        if dry_run:
            _print_dry_run(st)
            return
        n_jobs = jobs or joblib.cpu_count() or 1
        if backend == "loky":  # the workers start and import while the jobs are built
            start_workers(min(n_jobs, st.n_trials), st.task.name)
        if st.simulation is None:
            with _term_as_interrupt() as caught:
                try:
                    st = auto_step(st, n_jobs, backend, scheduler, timeout)
                except KeyboardInterrupt:
                    stop_workers()
                    _err.print(
                        "interrupted while choosing the time step: no trial of the study ran yet; run the "
                        "same command again to start over"
                    )
                    raise typer.Exit(128 + (caught[0] if caught else 2)) from None
        table = build_jobs(st)
    except SomoError as exc:
        stop_workers()
        fail(exc)
    except KeyboardInterrupt:
        stop_workers()
        typer.echo(
            "interrupted while building the job table, before any trial: nothing was written", err=True
        )
        raise typer.Exit(130) from None
    live: list[Progress] = []  # the progress bar, once the results folder is open

    def started(summary: RunSummary) -> None:
        for note in summary.notes:
            typer.echo(f"note: {note}", err=True)
        if summary.stored_errors:
            typer.echo(
                f"resuming {st.output}: {summary.skipped} of {summary.total} trials already stored, "
                f"{summary.stored_errors} of them as error; run with --retry-errors to run those again",
                err=True,
            )
        elif summary.skipped:
            typer.echo(
                f"resuming {st.output}: {summary.skipped} of {summary.total} trials already done",
                err=True,
            )
        progress = _progress()
        progress.start()
        live.append(progress)

    def new_round(batch: Batch) -> None:
        if batch.kind == "replicas":
            name = f"replicas {batch.number}: {batch.cells} cells x {st.robustness.replicas}"
        else:
            name = st.name if batch.number is None else f"round {batch.number}: {batch.cells} cells"
            if batch.number == 0:
                name += " (coarse)"
        live[0].add_task(name, total=len(batch.jobs), rate=0.0)

    def advanced(_: object) -> None:
        task = live[0].tasks[-1]
        live[0].advance(task.id)
        live[0].update(task.id, rate=(task.completed / task.elapsed) if task.elapsed else 0.0)

    def stop() -> None:
        while live:
            live.pop().stop()

    try:
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
            on_round=new_round,
        )
    except SomoError as exc:
        stop()
        fail(exc, code=1 if isinstance(exc, StorageError) else 2)
    except KeyboardInterrupt:  # while the results folder was opened, before the run's own handler
        stop()
        typer.echo(
            "interrupted while opening the results folder, before any trial: finished trial(s) kept; run the "
            "same command again to resume",
            err=True,
        )
        raise typer.Exit(130) from None
    finally:
        stop()
        stop_workers()  # started, but the run ended before its first trial (nothing to do, an error)
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
    if summary.errors and not allow_errors:
        between = (
            f", and {summary.inferred_errors} inferred cell(s) between them are marked error without running"
            if summary.inferred_errors
            else ""
        )
        typer.echo(
            f"{summary.errors} of {summary.total} trial(s) ended in error{between} (exit code 1); see "
            f"somo-sweep show {st.output}; --retry-errors runs them again, --allow-errors accepts them",
            err=True,
        )
        raise typer.Exit(1)


@contextmanager
def _term_as_interrupt() -> Iterator[list[int]]:
    """SIGTERM raises KeyboardInterrupt in the block, as Ctrl-C does (the signal is recorded)."""
    import signal

    caught: list[int] = []

    def handler(signum: int, frame: object) -> None:
        caught.append(signum)
        raise KeyboardInterrupt

    if signal.getsignal(signal.SIGTERM) is signal.SIG_IGN:  # started ignoring it: keep that
        yield caught
        return
    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield caught
    finally:
        signal.signal(signal.SIGTERM, old)


def auto_step(
    st: Study,
    n_jobs: int,
    backend: str,
    scheduler: str | None,
    timeout: float | None,
    stream: Callable[[str], None] | None = None,
) -> Study:
    """The study with its step chosen by label convergence (or the choice stored in its folder);
    what it does is written to ``stream`` (default: stderr)."""
    from dataclasses import replace

    from somo_sweep.sweep.convergence import choose_step, outcomes_of, stored_choice
    from somo_sweep.sweep.execution import execute
    from somo_sweep.sweep.folder import read_manifest

    say = stream or (lambda text: typer.echo(text, err=True))
    choice = None
    try:
        stored = (st.output / "manifest.json").is_file()
    except OSError as exc:  # a name no folder can have: said now, before any sample trial runs
        cause, advice = os_cause(exc)
        raise SomoError(
            f"cannot create the results folder {shown(str(st.output), 200)}: {cause}; nothing was written: "
            f"{advice}, then run the same command again"
        ) from None
    if stored:
        try:
            choice = stored_choice(read_manifest(st.output), st)
        except SomoError:  # a damaged manifest: the run rebuilds it; the step is chosen again
            choice = None
    if choice is not None:
        say(f"automatic step {choice.step_s * 1e3:g} ms (chosen earlier, from {st.output})")
    else:
        say(
            "no simulation: block: choosing the time step from this study's own cells (label convergence "
            "against half the step)"
        )

        def run_jobs(batch: list[Job]) -> Iterator[tuple[str, str, dict[str, str]]]:
            return outcomes_of(execute(batch, backend, n_jobs, scheduler, timeout))  # type: ignore[arg-type]

        def rung(step_s: float, runs: int) -> None:
            say(f"  trying {step_s * 1e3:g} ms: {runs} sample run(s)")

        choice = choose_step(st, run_jobs, on_rung=rung)
        for line in choice.describe():
            say(f"  {line}")
    return replace(st, auto_step_s=choice.step_s, convergence=choice.as_dict())


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.2f} trials/s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=_err,
    )


def _print_dry_run(st: Study) -> None:
    """Count, then the first rows, without building the other jobs."""
    from somo_sweep.sweep.jobs import first_jobs, jobs_frame
    from somo_sweep.sweep.sampling import describe

    typer.echo(
        f"{st.name}: task {st.task.name}, {st.n_trials} trials "
        f"({st.n_points} grid points x {st.repeats} repeat(s)), output {st.output}"
    )
    if st.sampling == "adaptive":
        typer.echo(describe(st))
    jobs = first_jobs(st, DRY_ROWS)
    if st.simulation is None:
        from somo_sweep.sim.numerics import step_ladder

        steps, why = step_ladder(st.resolve_model(next(iter(st.points())))[1])
        typer.echo(
            "automatic numerics (no simulation: block): the run chooses the step by label convergence "
            f"on a sample of these cells, trying {', '.join(f'{h * 1e3:g}' for h in steps)} ms (starting "
            f"guess set by {why}); the jobs below show the starting (modal) choice:"
        )
        shown: set[str] = set()
        for job in jobs:
            if job.numerics is not None and job.columns["model_hash"] not in shown:
                shown.add(job.columns["model_hash"])
                typer.echo(f"  model {job.columns['model_file']}:")
                for line in job.numerics.describe():
                    typer.echo(f"    {line}")
    else:
        sim = st.simulation
        given = "from the study file" if sim.time_step_s is not None else f"the {sim.engine} default"
        typer.echo(f"simulation: engine {sim.engine}, time step {sim.step_s * 1e3:g} ms ({given})")
    frame = jobs_frame(jobs)
    typer.echo(frame.to_string(index=False))
    if st.n_trials > DRY_ROWS:
        typer.echo(f"... {st.n_trials - DRY_ROWS} more")


def _damaged(path: Path, reason: str) -> None:
    from somo_sweep.sweep.folder import INFERRED, REPEATS, UNREADABLE

    if reason.startswith(UNREADABLE):
        typer.echo(
            f"warning: part file {path} {reason}: its trials are left out; give read access to it", err=True
        )
        return

    if path.name == INFERRED and path.parent.joinpath("manifest.json").exists():
        what = reason.removeprefix(REPEATS).strip() if reason.startswith(REPEATS) else f"skipped ({reason})"
        typer.echo(f"warning: {path}: {what}; the next adaptive run of this study rebuilds it", err=True)
        return
    if reason.startswith(REPEATS):  # readable, but a copy: its rows are counted once
        typer.echo(f"warning: part file {path} {reason}", err=True)
        return
    typer.echo(
        f"warning: skipped damaged part file {path} ({reason}); the next somo-sweep run of this study "
        "moves it to trials/quarantine/ and runs its trials again",
        err=True,
    )


def _save_plots(folder: Path) -> None:
    from somo_sweep.sweep.plots import summary_figure
    from somo_sweep.sweep.store import read_manifest, read_results, record_files

    df, manifest = read_results(folder, _damaged), read_manifest(folder)
    target = folder / "plots"
    if target.is_symlink():
        raise SomoError(f"{target} is a symbolic link; the plots go in the results folder itself: remove it")
    written = write_outputs(
        [
            (target / "summary.png", figure_bytes(summary_figure(df, manifest), "png", 120)),
            (target / "summary.svg", figure_bytes(summary_figure(df, manifest), "svg", 120)),
        ]
    )
    record_files(folder, written)
    _out.print(f"plots: {target / 'summary.png'} (and .svg)")


def show(results: Annotated[Path, typer.Argument(help="Results folder, e.g. results/<study>.")]) -> None:
    """Print a results folder's summary: counts by status and label, per-axis breakdown."""
    from somo_sweep.sweep.folder import pending_journal_rows
    from somo_sweep.sweep.lock import holder_now
    from somo_sweep.sweep.store import read_manifest, read_results
    from somo_sweep.sweep.summary import print_results

    try:
        df, manifest = read_results(results, _damaged), read_manifest(results)
        pending = pending_journal_rows(results, manifest["study_hash"], set(df["job_id"]))
        print_results(_out, df, manifest, holder_now(results), pending)
    except SomoError as exc:
        fail(exc)


def plot(results: Annotated[Path, typer.Argument(help="Results folder, e.g. results/<study>.")]) -> None:
    """Draw a results folder's summary plots (PNG and SVG in <folder>/plots)."""
    try:
        _save_plots(results)
    except SomoError as exc:
        fail(exc)


def tasks(
    show_all: Annotated[bool, typer.Option("--all", help="Also list the engine's selftest tasks.")] = False,
) -> None:
    """List the registered tasks (study files name them in task:)."""
    from somo_sweep.tasks import all_tasks

    for name, spec in all_tasks().items():
        if "selftest" in spec.tags and not show_all:
            continue
        tags = f" [{', '.join(spec.tags)}]" if spec.tags else ""
        typer.echo(f"{name}{tags}: {spec.description}")


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

    from somo_sweep.sweep.recheck import recheck as run_recheck
    from somo_sweep.sweep.study import load_study

    if max_trials < 1:
        fail(SomoError(f"--max-trials must be >= 1, got {max_trials}"))
    if not 0 <= seed < 2**63:
        fail(SomoError(f"--seed must be from 0 to 2**63 - 1, got {seed}"))
    target = file_target(report, "recheck.json")
    try:
        if target is not None:
            check_replaceable(target, [study], kind="json", older_keys=RECHECK_KEYS)
        result = run_recheck(load_study(study, out, max_trials, allow_outside), trials, seed, _damaged)
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
