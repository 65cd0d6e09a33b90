"""``somo-sweep paper …``: every figure of the SoMo paper (Figs. 3, 5-8, the Fig. 6 ablation and comparison,
the palm study).

Each command calls one ``build`` function of :mod:`somo_sweep.paper` (which returns
figures, numbers and tables) and writes what it returns into ``--out``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from somo_sweep.cli.output import (
    check_output,
    checked_jobs,
    fail,
    record_in_results,
    say_notes,
    write_artifacts,
    write_atomic,
)
from somo_sweep.errors import SomoError

if TYPE_CHECKING:
    import pandas as pd

    from somo_sweep.paper.ablation import AblationFile, Configuration
    from somo_sweep.paper.artifacts import Artifacts

__all__ = ["app"]

app = typer.Typer(
    no_args_is_help=True,
    help="Reproduce the SoMo paper's figures: Figs. 3 and 5-8, the Fig. 6 ablation and comparison, "
    "the palm study.",
)

OUT = Annotated[Path, typer.Option("--out", help="Folder for the figure files.")]
QUICK = Annotated[bool, typer.Option("--quick", help="A short version (seconds to a minute).")]
DEFAULT_OUT = Path("results/figures")


def _finish(artifacts: Artifacts, out: Path) -> None:
    if out.exists() and not out.is_dir():
        fail(SomoError(f"--out {out} is a file, not a folder"))
    for line in artifacts.lines:
        typer.echo(line)
    try:
        written = write_artifacts(artifacts, out)
    except SomoError as exc:
        fail(exc)
    record_in_results(written)
    for path in written:
        typer.echo(f"wrote {path}")


def _jobs(jobs: int, allow_default: bool = False) -> int:
    """``--jobs`` checked (:func:`checked_jobs`), or the error and exit 2."""
    try:
        return checked_jobs(jobs, allow_default)
    except SomoError as exc:
        fail(exc)


@app.command()
def fig3(out: OUT = DEFAULT_OUT, jobs: Annotated[int, typer.Option(help="Worker processes.")] = 2) -> None:
    """Fig. 3: blocked force vs pressure, eq. (8)/(9) and the simulator-in-the-loop fit vs published."""
    from somo_sweep.paper.fig3 import build

    _finish(build(n_jobs=_jobs(jobs)), out)


@app.command()
def fig5(
    out: OUT = DEFAULT_OUT,
    quick: QUICK = False,
    fit_cycles: Annotated[int, typer.Option(help="Gait cycles the side weight is fitted on.")] = 3,
    jobs: Annotated[int, typer.Option(help="Worker processes for the finger calibration.")] = 2,
) -> None:
    """Fig. 5: the in-hand gait against the hardware recording (about 10 min; --quick: one cycle)."""
    from somo_sweep.paper.fig5 import build

    try:
        artifacts = build(quick=quick, fit_cycles=fit_cycles, n_jobs=_jobs(jobs))
    except SomoError as exc:
        fail(exc)
    _finish(artifacts, out)


@app.command()
def fig6(
    results: Annotated[Path, typer.Argument(help="Results folder of a pinch_grasp study.")],
    rule: Annotated[str, typer.Option(help="Grasp rule: contacts or paper.")] = "contacts",
    max_dsr: Annotated[float, typer.Option(help="Largest DSR drawn.")] = 0.5,
    out: Annotated[
        Path | None,
        typer.Option(
            help="Output folder (default: the results folder; the headline fig6_RULE.json is also kept "
            "in the results folder)."
        ),
    ] = None,
    audit: Annotated[
        Path | None,
        typer.Option(
            help="A compare-engines folder of audit cells (pybullet/ and mujoco/): the engines' "
            "agreement on cells robust on both goes into the JSON and is printed."
        ),
    ] = None,
) -> None:
    """Fig. 6: pinch / power / no grasp over centering and width per DSR; the smallest all-width pinch DSR."""
    from somo_sweep.paper.fig6 import build, grasp_table
    from somo_sweep.paper.grasp_trials import open_grasp_results

    stem = f"fig6_{rule}"
    try:
        opened = open_grasp_results(results)
    except SomoError as exc:
        fail(exc)
    trials, state, expected = opened.trials, opened.replicas, opened.manifest.get("n_trials")
    try:
        table = grasp_table(trials, rule, state)
        n_trials = expected if isinstance(expected, int) else None
        artifacts = build(table, stem=stem, max_dsr=max_dsr, state=state, expected=n_trials)
    except SomoError as exc:
        fail(SomoError(f"{results}: {exc}"))
    if audit is not None:
        info = _engine_audit(audit, rule, trials)
        artifacts.json[f"{stem}.json"]["engine_audit"] = info
        for line in _audit_lines(info):
            typer.echo(line)
    if (missing := opened.missing(len(table))) is not None:
        typer.echo(f"note: {missing}: the figure and its headlines are of those only")
    target = out or results
    if target.resolve() != results.resolve():
        # The headline is stored with the results too, wherever the figure goes.
        headline = json.dumps(artifacts.json[f"{stem}.json"], indent=2) + "\n"
        try:
            check_output(results / f"{stem}.json", headline)
        except SomoError as exc:
            fail(exc)
    _finish(artifacts, target)
    if target.resolve() != results.resolve():
        record_in_results([write_atomic(results / f"{stem}.json", headline)])


def _engine_audit(folder: Path, rule: str, results: pd.DataFrame) -> dict[str, object]:
    """The engine audit of ``folder`` (a compare-engines output) under ``rule``, refused unless its
    cells are cells of ``results``; exits on bad input."""
    from somo_sweep.paper.engine_audit import ENGINES, audit_mismatch, engine_audit
    from somo_sweep.paper.grasp_trials import read_results

    try:
        pybullet, mujoco = (read_results(folder / engine) for engine in ENGINES)
        for engine, table in (("PyBullet", pybullet), ("MuJoCo", mujoco)):
            if (why := audit_mismatch(results, table, engine)) is not None:
                raise SomoError(why)
        info = engine_audit(pybullet, mujoco, rule=rule)
    except SomoError as exc:
        fail(SomoError(f"--audit {folder}: {exc}"))
    return {"folder": str(folder), **info}


def _audit_lines(info: dict[str, object]) -> list[str]:
    """The audit in a few lines: the agreement, then each disagreement and what decides it."""
    share = info["agreement"]
    shown = f"{share:.1%}" if isinstance(share, float) else "no cell"
    lines = [
        f"engine audit ({info['rule']} rule): PyBullet and MuJoCo agree on {info['agree']} of the "
        f"{info['robust_on_both']} cells robust on both ({shown}; {info['cells']} cells audited)"
    ]
    for d in info["disagreements"]:  # type: ignore[attr-defined]
        lines.append(
            f"  DSR {d['distal_segment_ratio']:g}, width {d['object_width_m'] * 1e3:g} mm, c "
            f"{d['centering_position_m'] * 1e3:g} mm: PyBullet {d['pybullet']}, MuJoCo {d['mujoco']}; "
            f"{d['decided_by']}"
        )
    return lines


@app.command("fig6-ablation")
def fig6_ablation(
    quick: Annotated[bool, typer.Option("--quick", help="The quick grid (same as --grid quick).")] = False,
    grid: Annotated[str, typer.Option(help="Grid of the ablation file: full or quick.")] = "full",
    ablation: Annotated[
        Path | None,
        typer.Option(help="Ablation file (default: the bundled studies/pinch_grasp_ablation.yaml)."),
    ] = None,
    results_root: Annotated[
        Path, typer.Option(help="Folder holding the configurations' results folders.")
    ] = Path("results"),
    out: Annotated[
        Path | None,
        typer.Option(help="Output folder (default: results/reference; with --quick results/figures/quick)."),
    ] = None,
    jobs: Annotated[int, typer.Option("--jobs", "-j", help="Worker processes (default: every CPU).")] = 0,
    adaptive: Annotated[
        bool, typer.Option("--adaptive/--exhaustive", help="Sample each configuration adaptively.")
    ] = True,
    run: Annotated[
        bool, typer.Option("--run/--no-run", help="Run missing trials first (--no-run: tables only).")
    ] = True,
    paper_style: Annotated[
        bool, typer.Option("--paper-style", help="Side-by-side figure: add rows drawn the paper's way.")
    ] = False,
) -> None:
    """Fig. 6 ablation: ours vs the original's choices, one factor at a time (table, figure, side by side).

    Runs every configuration's missing trials (resumable), then writes fig6_ablation.csv, .md and
    .png and fig6_compare.png.
    """
    from somo_sweep.paper.ablation import ABLATION_FILE, configurations, load_ablation

    grid = "quick" if quick else grid
    target = out or (Path("results/figures/quick") if grid == "quick" else Path("results/reference"))
    try:
        spec, folder = load_ablation(ablation or ABLATION_FILE)
        configs = configurations(spec, folder, grid, results_root)
        say_notes([*spec.notices, *(note for c in configs for note in c.study.notices)])
        if run:
            stopped = _run_ablation(configs, _jobs(jobs, allow_default=True), adaptive)
            if stopped is not None:
                typer.echo(
                    "interrupted: finished trials kept; run the same command again to resume", err=True
                )
                raise typer.Exit(128 + stopped)
        artifacts = _ablation_artifacts(spec, configs, grid, paper_style)
    except SomoError as exc:
        fail(exc)
    _finish(artifacts, target)


def _ablation_artifacts(
    spec: AblationFile, configs: list[Configuration], grid: str, paper_style: bool
) -> Artifacts:
    """The ablation's table and figure, and the side-by-side figure, from the stored results."""
    from somo_sweep.paper.ablation import compare_sides, read_configurations
    from somo_sweep.paper.fig6_ablation import RULES, build
    from somo_sweep.paper.fig6_compare import build as build_compare

    results = read_configurations(configs, RULES)
    rules: dict[str, str] = {"ours": spec.rules.ours, "original": spec.rules.original}
    artifacts = build(results, list(spec.factors), rules, title=f"{spec.name} ({grid} grid)")
    compare = build_compare(compare_sides(results, spec), paper_style=paper_style)
    artifacts.figures.update(compare.figures)
    artifacts.lines += compare.lines
    return artifacts


def _run_ablation(configs: list[Configuration], jobs: int, adaptive: bool) -> int | None:
    """Run the configurations with a line each; returns the signal number if interrupted."""
    from rich.console import Console

    from somo_sweep.cli.summary import print_run_summary
    from somo_sweep.paper.ablation import run_configurations

    console = Console()
    shared = {c.name: c.same_as for c in configs if c.same_as}

    def started(config: Configuration) -> None:
        also = [n for n, first in shared.items() if first == config.name]
        same = f" (= {', '.join(also)})" if also else ""
        typer.echo(f"configuration {config.name}{same}: {len(config.table.jobs)} cells -> {config.folder}")

    summaries = run_configurations(configs, jobs or None, adaptive, on_config=started)
    for summary in summaries:
        print_run_summary(console, summary)
    errors = sum(s.errors for s in summaries)
    if errors:
        typer.echo(f"warning: {errors} trial(s) ended in error; they are drawn as 'error'", err=True)
    return next((s.interrupted for s in summaries if s.interrupted is not None), None)


@app.command("fig6-compare")
def fig6_compare(
    a: Annotated[Path, typer.Argument(help="Results folder of the first configuration (ours).")],
    b: Annotated[Path, typer.Argument(help="Results folder of the second (the original's).")],
    rule_a: Annotated[str, typer.Option(help="Grasp rule of A: contacts or paper.")] = "contacts",
    rule_b: Annotated[str, typer.Option(help="Grasp rule of B: contacts or paper.")] = "paper",
    name_a: Annotated[str, typer.Option(help="Name of A in the figure.")] = "ours",
    name_b: Annotated[str, typer.Option(help="Name of B in the figure.")] = "original",
    max_dsr: Annotated[float, typer.Option(help="Largest DSR drawn.")] = 0.5,
    paper_style: Annotated[
        bool, typer.Option("--paper-style", help="Add rows drawn the paper's way (grasped trials, contours).")
    ] = False,
    out: OUT = DEFAULT_OUT,
) -> None:
    """Fig. 6 side by side: two results folders panel by panel on the paper's axes, each with its headline."""
    from somo_sweep.paper.fig6 import grasp_table
    from somo_sweep.paper.fig6_compare import Side, build
    from somo_sweep.paper.grasp_trials import read_results

    sides = []
    for name, rule, folder in ((name_a, rule_a, a), (name_b, rule_b, b)):
        try:
            table = read_results(folder)
        except SomoError as exc:
            fail(exc)
        try:
            sides.append(Side(name, rule, grasp_table(table, rule)))
        except SomoError as exc:  # the table's problem, named by its folder
            fail(SomoError(f"{folder}: {exc}"))
    try:
        artifacts = build(sides, max_dsr=max_dsr, paper_style=paper_style)
    except SomoError as exc:
        fail(exc)
    _finish(artifacts, out)


@app.command()
def fig7(out: OUT = DEFAULT_OUT, quick: QUICK = False) -> None:
    """Fig. 7: a continuum arm wraps a ball and drops it through a hoop (frames, GIF, half-step check)."""
    from somo_sweep.paper.fig7 import build

    _finish(build(quick=quick), out)


@app.command()
def fig8(out: OUT = DEFAULT_OUT, quick: QUICK = False) -> None:
    """Fig. 8: a snake with isotropic vs anisotropic friction (10 s each; --quick: 3 s)."""
    from somo_sweep.paper.fig8 import build

    _finish(build(quick=quick), out)


@app.command()
def palm(
    results: Annotated[Path, typer.Argument(help="Results folder of a palm-design study.")],
    out: OUT = DEFAULT_OUT,
) -> None:
    """Palm design study (Sec. V-B): rotation per cycle and drop rate over palm height x diameter."""
    from somo_sweep.paper.palm import build
    from somo_sweep.sweep.store.result_store import read_results

    try:
        table = read_results(results)
    except SomoError as exc:
        fail(exc)
    try:
        artifacts = build(table, name=results.resolve().name or "palm_design")
    except SomoError as exc:
        fail(SomoError(f"{results}: {exc}"))
    _finish(artifacts, out)
