"""``somo-sweep design``: search for the design to build (:mod:`somo_sweep.design`), write its answer.

Into the results folder's ``design/``: ``ranking.csv`` (one row per design, best first, its key
paths as columns), ``summary.json``, each finalist's label map over the objects
(``finalist_N_design_D.png``), the Pareto front with a trade-off (``pareto.png``) and
``best_design.yaml``, a plain grid study of the best design to rerun and share.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, cast

import typer
from rich import box
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from somo_sweep.cli.output import fail, figure_bytes, json_report, write_outputs
from somo_sweep.cli.results import ALLOW_OUTSIDE
from somo_sweep.cli.sweep import JOBS
from somo_sweep.errors import Interrupted, SomoError

if TYPE_CHECKING:
    import pandas as pd

    from somo_sweep.design import DesignRun, DesignStudy
    from somo_sweep.design.search import Progress as SearchProgress
    from somo_sweep.sweep.run.execution import Backend
    from somo_sweep.sweep.run.options import RunEvents, RunOptions
    from somo_sweep.sweep.run.sampling import Batch

__all__ = ["design"]

_err = Console(stderr=True)


def _out() -> Console:
    """The standard output's console, made at each use (its width is the terminal's now)."""
    return Console()


#: Designs the command prints (the ranking file holds them all).
SHOWN = 8

_SEED = Annotated[int | None, typer.Option("--seed", min=0, help="Seed overriding the study's seed:.")]
_BUDGET = Annotated[
    int | None,
    typer.Option("--budget", min=1, help="Simulations (trials and replicas) overriding design.budget."),
]


def design(
    study: Annotated[Path, typer.Argument(help="Design study file (YAML or JSON) with a design: block.")],
    jobs: JOBS = 0,
    dry_run: Annotated[
        bool, typer.Option("--dry-run", help="Print the search's plan; simulate nothing.")
    ] = False,
    backend: Annotated[str, typer.Option(help="loky (this machine) or dask (a cluster).")] = "loky",
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address, tcp://HOST:8786.")] = None,
    out: Annotated[Path | None, typer.Option("--out", help="Results folder, anywhere.")] = None,
    seed: _SEED = None,
    budget: _BUDGET = None,
    timeout: Annotated[float | None, typer.Option(help="Per-trial wall-time limit, s.")] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Delete results of a different (changed) search in --out.")
    ] = False,
    allow_outside: ALLOW_OUTSIDE = False,
) -> None:
    """Search for the design whose robust label holds on the most objects; rank the designs.

    Resumable: run the same command again after Ctrl-C (or a larger --budget) to go on.
    """
    from somo_sweep.design import load_design
    from somo_sweep.sweep.run.options import RunOptions

    options = RunOptions(jobs, cast("Backend", backend), scheduler, timeout, overwrite)
    try:
        options.check()
        if out is not None and out.exists() and not out.is_dir():
            raise SomoError(f"--out {out} is a file, not a folder")
        loaded = load_design(study, out, budget, seed, allow_outside)
    except SomoError as exc:
        fail(exc)
    if dry_run:
        _print_plan(loaded)
        return
    done = _search(loaded, options)
    _answer(loaded, done)


def _search(study: DesignStudy, options: RunOptions) -> DesignRun:
    """Run the search with a progress line per round; an error or an interrupt ends the command."""
    from somo_sweep.design import run_design

    view = _View(study)
    try:
        return run_design(study, options, view.events(), view.progress)
    except SomoError as exc:
        view.stop()
        fail(exc)
    except (Interrupted, KeyboardInterrupt):
        view.stop()
        typer.echo(
            "interrupted before the first simulation: nothing was lost; run the same command again", err=True
        )
        raise typer.Exit(130) from None
    finally:
        view.stop()


class _View:
    """A bar per round, described by where the search is and its best design so far."""

    def __init__(self, study: DesignStudy):
        self.study = study
        self.live: list[Progress] = []
        self.line = ""

    def events(self) -> RunEvents:
        from somo_sweep.sweep.run.options import RunEvents

        return RunEvents(None, self.started, self.new_round, self.advanced)

    def started(self, summary: object) -> None:
        for note in getattr(summary, "notes", []):
            typer.echo(f"note: {note}", err=True)
        progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(bar_width=20),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=_err,
        )
        progress.start()
        self.live.append(progress)

    def progress(self, where: SearchProgress) -> None:
        study = self.study
        rung, size = where.rung
        what = "replicas" if where.kind == "replicas" else "trials"
        line = (
            f"batch {where.batch} rung {rung} ({size} objects): {where.designs} design(s), {what}; "
            f"{where.spent}/{where.budget} simulations"
        )
        if where.best is not None:
            values, tally = where.best
            shown = ", ".join(f"{k.rsplit('.', 1)[-1]} {_short(v)}" for k, v in values.items())
            line += f"; best so far: {shown}: {tally.robust}/{study.n_objects} robust {study.objective.value}"
        self.line = line

    def new_round(self, batch: Batch) -> None:
        if self.live:
            self.live[0].add_task(self.line, total=len(batch.jobs))

    def advanced(self, _: object) -> None:
        if self.live and self.live[0].tasks:
            self.live[0].advance(self.live[0].tasks[-1].id)

    def stop(self) -> None:
        while self.live:
            self.live.pop().stop()


def _short(value: object) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _answer(study: DesignStudy, done: DesignRun) -> None:
    """Rank the folder's designs, write the answer's files, print it; exit as the run ended."""
    from somo_sweep.design import rank_designs
    from somo_sweep.sweep.store.folder import read_results

    summary, folder = done.summary, study.base.output
    try:
        table = read_results(folder)
        ranking = rank_designs(table, study)
        written = _write(study, table, ranking, done.search.record())
    except SomoError as exc:
        fail(exc)
    _print_answer(study, ranking, done, written)
    if summary.interrupted is not None:
        _err.print(
            f"interrupted: {summary.run} trial(s) and {summary.replicas_run} replica(s) finished in this run "
            "are kept; the ranking above holds what the folder has; run the same command again to go on"
        )
        raise typer.Exit(128 + summary.interrupted)


def _write(
    study: DesignStudy, table: pd.DataFrame, ranking: pd.DataFrame, record: dict[str, object]
) -> list[Path]:
    """The answer's files in ``<folder>/design`` (each checked first: a file of the user's stays)."""
    from somo_sweep.design.report import best_study_text, finalists, label_map, pareto_figure, summary
    from somo_sweep.sweep.store.manifest import record_files

    target = study.base.output / "design"
    if target.is_symlink() or (target.exists() and not target.is_dir()):
        raise SomoError(f"{target} is not a folder; the design's answer goes there: move it away")
    outputs: list[tuple[Path, str | bytes]] = [
        (target / "ranking.csv", ranking.to_csv(index=False)),
        (target / "summary.json", json_report(summary(ranking, study, record), "design")),
    ]
    best = finalists(ranking, study)
    for i, (_, row) in enumerate(best.iterrows(), start=1):
        fig = label_map(table, row, study)
        outputs.append((target / f"finalist_{i}_design_{int(row['design'])}.png", figure_bytes(fig)))
    if study.trade_off is not None and ranking["complete"].any():
        outputs.append((target / "pareto.png", figure_bytes(pareto_figure(ranking, study))))
    if len(best):
        outputs.append((target / "best_design.yaml", best_study_text(best.iloc[0], study, target)))
    written = write_outputs(outputs, [study.source])
    record_files(study.base.output, written)
    return written


def _print_answer(study: DesignStudy, ranking: pd.DataFrame, done: DesignRun, written: list[Path]) -> None:
    """The best designs as a table, the best one in words, the files written."""
    n = study.n_objects
    rows = []
    for _, row in ranking.head(SHOWN).iterrows():
        judged = n if row["complete"] else int(row["objects_judged"])
        rows.append(
            [
                str(row["rank"]),
                str(row["design"]),
                *(_short(row[k]) for k in study.keys),
                f"{int(row['robust_objects'])}/{judged}",
                f"{row['share_low_95']:.2f}-{row['share_high_95']:.2f}",
                str(row["simulations"]),
                "yes" if row["complete"] else "no",
            ]
        )
    # A key path's last part names the variable: its words wrap in the header, the values do not.
    names = ["rank", "design", *(k.rsplit(".", 1)[-1].replace("_", " ") for k in study.keys)]
    names += ["robust", "95 %", "sims", "done"]
    table = Table(
        title=f"designs, best first ({len(ranking)} judged, all in design/ranking.csv; done: judged on "
        "every object)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        collapse_padding=True,
    )
    for i, name in enumerate(names):
        width = max([len(w) for w in name.split()] + [len(r[i]) for r in rows])
        table.add_column(name, justify="right", width=width)
    for cells in rows:
        table.add_row(*cells)
    _out().print(table)
    record = done.search.record()
    for note in record["notes"]:
        _out().print(f"note: {note}")
    if done.search.designs.infeasible:
        first = done.search.designs.infeasible[0]
        _out().print(
            f"{len(done.search.designs.infeasible)} design(s) asked were infeasible, e.g.: {first.why}"
        )
    complete = ranking[ranking["complete"].astype(bool)]
    if len(complete):
        row = complete.iloc[0]
        values = ", ".join(f"{k} = {_short(row[k])}" for k in study.keys)
        _out().print(
            f"best design: {values}: robust {study.objective.label} = {study.objective.value} on "
            f"{int(row['robust_objects'])} of {n} objects (95 % interval {row['share_low_95']:.2f}-"
            f"{row['share_high_95']:.2f}), {row['simulations']} simulations"
        )
    else:
        _out().print("no design was judged on every object yet: raise --budget, or run again to go on")
    _out().print(
        f"{record['simulations']} of {study.budget} simulations spent; written: "
        + ", ".join(str(p) for p in written)
    )


def _print_plan(study: DesignStudy) -> None:
    """What the search will do, without simulating: variables, objects, rungs, the budget."""
    lines = [f"{study.base.name}: task {study.base.task.name}, results in {study.base.output}"]
    for v in study.variables:
        size = "continuous" if v.n_values is None else f"{v.n_values} values"
        lines.append(f"  variable {v.key}: {json.dumps(v.spec())} ({size})")
    strata = f", stratified by {study.stratify}" if study.stratify else ""
    lines.append(f"  objects: {' x '.join(study.objects)} = {study.n_objects}{strata}")
    lines.append(
        f"  objective: the robust share of {study.objective.label} = {study.objective.value} over the "
        f"objects (a cell counts when its trial and its {study.replicas} replicas agree)"
    )
    if study.trade_off is not None:
        what = study.trade_off.metric or study.trade_off.variable
        lines.append(f"  trade-off: {what} ({study.trade_off.direction}); NSGA-II")
    else:
        lines.append("  optimiser: TPE (seeded)")
    lines.append(
        f"  {study.batch} designs per batch, judged on rungs of {', '.join(map(str, study.rungs))} objects "
        f"(the best 1/{study.reduction} go on); budget {study.budget} simulations, replicas included"
    )
    typer.echo("\n".join(lines))
