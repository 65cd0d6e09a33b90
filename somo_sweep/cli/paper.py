"""``somo-sweep paper …``: every figure of the SoMo paper, plus the benchmark and the bundled data.

Each command calls one ``build`` function of :mod:`somo_sweep.paper` (which returns
figures, numbers and tables) and writes what it returns into ``--out``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from somo_sweep.cli.output import (
    check_output,
    check_replaceable,
    checked_jobs,
    fail,
    file_target,
    write_artifacts,
    write_atomic,
    write_outputs,
)
from somo_sweep.errors import SomoError

if TYPE_CHECKING:
    from somo_sweep.paper.ablation import Configuration
    from somo_sweep.paper.artifacts import Artifacts

__all__ = ["app"]

#: Largest object shift ``paper numerics --perturb-m`` takes, m (well below the grid's 5 mm).
MAX_PERTURB_M = 1e-3

app = typer.Typer(no_args_is_help=True, help="Reproduce the SoMo paper's figures (Figs. 3, 5-8, palm study).")

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
) -> None:
    """Fig. 6: pinch / power / no grasp over centering and width per DSR; the smallest all-width pinch DSR."""
    from somo_sweep.paper.fig6 import build, grasp_table
    from somo_sweep.paper.grasp_trials import read_results
    from somo_sweep.sweep.folder import read_manifest

    stem = f"fig6_{rule}"
    try:
        trials = read_results(results)
        expected = read_manifest(results).get("n_trials")
    except SomoError as exc:
        fail(exc)
    try:
        artifacts = build(grasp_table(trials, rule), stem=stem, max_dsr=max_dsr)
    except SomoError as exc:
        fail(SomoError(f"{results}: {exc}"))
    if isinstance(expected, int) and len(trials) < expected:
        typer.echo(
            f"note: {len(trials)} of the study's {expected} trials are stored (a run unfinished or "
            "still going): the figure and its headline are of those only"
        )
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
        write_atomic(results / f"{stem}.json", headline)


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
    from somo_sweep.paper.ablation import (
        ABLATION_FILE,
        compare_sides,
        configurations,
        load_ablation,
        read_configurations,
    )
    from somo_sweep.paper.fig6_ablation import RULES, build
    from somo_sweep.paper.fig6_compare import build as build_compare

    grid = "quick" if quick else grid
    target = out or (Path("results/figures/quick") if grid == "quick" else Path("results/reference"))
    try:
        spec, folder = load_ablation(ablation or ABLATION_FILE)
        configs = configurations(spec, folder, grid, results_root)
        if run:
            stopped = _run_ablation(configs, _jobs(jobs, allow_default=True), adaptive)
            if stopped is not None:
                typer.echo(
                    "interrupted: finished trials kept; run the same command again to resume", err=True
                )
                raise typer.Exit(128 + stopped)
        results = read_configurations(configs, RULES)
        rules: dict[str, str] = {"ours": spec.rules.ours, "original": spec.rules.original}
        artifacts = build(results, list(spec.factors), rules, title=f"{spec.name} ({grid} grid)")
        compare = build_compare(compare_sides(results, spec), paper_style=paper_style)
    except SomoError as exc:
        fail(exc)
    artifacts.figures.update(compare.figures)
    artifacts.lines += compare.lines
    _finish(artifacts, target)


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
    from somo_sweep.sweep.store import read_results

    try:
        table = read_results(results)
    except SomoError as exc:
        fail(exc)
    try:
        artifacts = build(table, name=results.resolve().name or "palm_design")
    except SomoError as exc:
        fail(SomoError(f"{results}: {exc}"))
    _finish(artifacts, out)


@app.command("robust-cost")
def robust_cost(
    out: Annotated[
        Path, typer.Option("--out", help="Folder for the JSON record (the study runs go to a temporary one).")
    ] = Path("results/reference"),
    rounds: Annotated[int, typer.Option(help="Alternating rounds of the one-trial timing.")] = 3,
    jobs: Annotated[int, typer.Option("--jobs", "-j", help="Workers of the two study runs.")] = 2,
    work: Annotated[
        Path | None,
        typer.Option(help="Keep the two results folders here (before/, robust/; default: temporary)."),
    ] = None,
) -> None:
    """What robust labels cost: one trial, and the quick study plain before vs robust (K = 4) now."""
    import json
    import tempfile

    from somo_sweep.paper.robust_cost import cost_lines, cost_runs

    if rounds < 1 or jobs < 1:
        fail(SomoError(f"--rounds and --jobs must be >= 1, got {rounds} and {jobs}"))
    if work is not None and (work / "before").exists():
        fail(SomoError(f"--work {work} already holds a run (before/): the benchmark times fresh runs"))
    with tempfile.TemporaryDirectory(prefix="somo-sweep-robust-cost-") as tmp:
        try:
            report = cost_runs(work or Path(tmp), rounds=rounds, n_jobs=jobs)
        except SomoError as exc:
            fail(exc)
    for line in cost_lines(report):
        typer.echo(line)
    try:
        (path,) = write_outputs([(out / "robust_cost.json", json.dumps(report.as_dict(), indent=2) + "\n")])
    except SomoError as exc:
        fail(exc)
    typer.echo(f"wrote {path}")


@app.command()
def speed(
    repeats: Annotated[int, typer.Option(help="Timed runs per measurement.", min=1, max=100)] = 3,
    convergence: Annotated[
        bool, typer.Option("--convergence", help="The time-step convergence table.")
    ] = False,
    statics: Annotated[bool, typer.Option("--statics", help="Only the bench-statics benchmark.")] = False,
    scaling: Annotated[
        bool,
        typer.Option(
            "--scaling/--no-scaling",
            help="Time the 24-trial demo sweep (0.5 ms) at 1 and 2 workers, and at 2 workers joblib against "
            "a 2-worker Dask LocalCluster in turn (joblib, Dask, Dask, joblib), on the demo study and on the "
            "192 cells of the quick study at the ablation's 4-ms numerics.",
        ),
    ] = True,
    quick_study: Annotated[
        bool,
        typer.Option(
            "--quick-study/--no-quick-study",
            help="Time the quick study's 192 cells at 4 ms too (pinch_grasp_quick_ablation_ours.yaml).",
        ),
    ] = True,
) -> None:
    """The benchmark (make bench): grasp steps, one trial vs the original's numerics, bench statics,
    sweep scaling (parallel efficiency, Dask vs joblib)."""
    import tempfile

    from somo_sweep.paper.speed import convergence_lines, speed_lines
    from somo_sweep.paper.statics_speed import statics_lines

    if convergence:
        lines = convergence_lines()
    elif statics:
        lines = statics_lines()
    else:
        lines = [*speed_lines(repeats), *statics_lines()]
    for line in lines:
        typer.echo(line)
    if scaling and not (convergence or statics):
        from somo_sweep.paper.scaling import (
            DEMO_STUDY,
            QUICK_STUDY,
            dask_lines,
            dask_runs,
            numerics_note,
            quick_note,
            scaling_lines,
            scaling_runs,
        )

        with tempfile.TemporaryDirectory(prefix="somo-sweep-scaling-") as tmp:
            for line in scaling_lines(scaling_runs(Path(tmp) / "demo"), note=numerics_note(DEMO_STUDY)):
                typer.echo(line)
            if quick_study:
                runs = dask_runs(Path(tmp) / "quick", QUICK_STUDY)
                for line in dask_lines(runs, QUICK_STUDY.stem, quick_note()):
                    typer.echo(line)


@app.command()
def scale(
    trials: Annotated[
        str, typer.Option(help="Study sizes, comma-separated multiples of 2000 (the largest is resumed).")
    ] = "2000,20000",
    jobs: Annotated[int, typer.Option(help="Worker processes.")] = 2,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Folder for the studies and results (default: a temporary one)."),
    ] = None,
) -> None:
    """Sweep memory and resume time at scale: peak memory of `somo-sweep run` at each size, then the
    largest stopped at half its trials and resumed (time to its first new trial)."""
    import tempfile

    from somo_sweep.paper.scale import measure_run, scale_lines, scale_study

    n_jobs = _jobs(jobs)
    try:
        sizes = sorted({int(t) for t in trials.split(",")})
        studies = {n: scale_study(n) for n in sizes}
    except ValueError:
        fail(SomoError(f"--trials must be whole numbers separated by commas, got '{trials}'"))
    except SomoError as exc:
        fail(exc)
    if out is not None and (out.is_file() or (out.is_dir() and any(out.iterdir()))):
        fail(SomoError(f"--out {out} must be a new or empty folder (each run must start from nothing)"))
    with tempfile.TemporaryDirectory(prefix="somo-sweep-scale-") as tmp:
        folder = out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        runs = []
        for n, text in studies.items():
            study = folder / f"scale_{n}.yaml"
            write_atomic(study, text)
            runs.append(measure_run(study, folder / f"run_{n}", n, n_jobs))
            typer.echo(f"{n} trials: {runs[-1].wall_s:.1f} s, peak {runs[-1].peak_rss_mb:.1f} MiB")
        largest = sizes[-1]
        study = folder / f"scale_{largest}.yaml"
        stopped = measure_run(study, folder / "resume", largest, n_jobs, stop_at=largest // 2)
        resumed = measure_run(study, folder / "resume", largest, n_jobs)
        for line in scale_lines(runs, stopped, resumed, n_jobs):
            typer.echo(line)


@app.command()
def engines(
    every: Annotated[
        int, typer.Option(help="Time every N-th cell of the quick grid (192 cells).", min=1)
    ] = 8,
    mujoco_step: Annotated[float, typer.Option(help="MuJoCo's time step, s.")] = 4e-3,
    convergence: Annotated[
        bool,
        typer.Option(
            "--convergence", help="Also run the whole quick grid on MuJoCo at the step and half of it."
        ),
    ] = False,
    jobs: Annotated[int, typer.Option("--jobs", "-j", help="Workers for --convergence.")] = 2,
    out: Annotated[Path, typer.Option(help="Folder for engine_speed.json and the per-trial table.")] = Path(
        "results/figures"
    ),
) -> None:
    """The engine benchmark (make bench-engines): one pinch trial on PyBullet and MuJoCo, side by side."""
    from somo_sweep.paper.engine_speed import build
    from somo_sweep.sim.mujoco.support import missing  # no MuJoCo import

    if not (math.isfinite(mujoco_step) and mujoco_step > 0):
        fail(SomoError(f"--mujoco-step must be a time step in s, > 0, got {mujoco_step:g}"))
    if (why := missing()) is not None:
        fail(SomoError(why))
    try:
        artifacts = build(every, mujoco_step, convergence, _jobs(jobs))
    except SomoError as exc:
        fail(exc)
    _finish(artifacts, out)


@app.command()
def numerics(
    compare: Annotated[
        str | None, typer.Option(help="half-step or reference: label agreement on a study's grid.")
    ] = None,
    repeats: Annotated[int, typer.Option(help="Timed runs.", min=1, max=100)] = 3,
    jobs: Annotated[int, typer.Option(help="Worker processes.")] = 2,
    save: Annotated[
        str | None,
        typer.Option(
            metavar="<path>",
            help="Write every trial's result to this JSON file; a folder (out/, or one that exists) gets "
            "numerics_runs.json in it.",
        ),
    ] = None,
    study: Annotated[Path | None, typer.Option(help="pinch_grasp study whose grid to compare on.")] = None,
    a: Annotated[
        str | None,
        typer.Option(
            help="Setup A: DT_S,ITERATIONS,INERTIA_KG_M2[,DAMPING_N_M_S_PER_RAD]"
            "[,one-body][,friction-every-2][,residual=R] (default: the study's)."
        ),
    ] = None,
    b: Annotated[
        str | None,
        typer.Option(help="Setup B to compare A with (same format as --a; --compare not needed)."),
    ] = None,
    auto_family: Annotated[
        bool,
        typer.Option(
            "--auto-family",
            help="Check the automatic numerics on a family of fingers against a 4x finer step.",
        ),
    ] = False,
    points: Annotated[int, typer.Option(help="--auto-family: grasp trials per finger (1-3).")] = 3,
    corners: Annotated[
        bool,
        typer.Option(
            "--corners",
            help="--auto-family: also the four corners (stiffness x0.1/x10 with link mass x0.2/x5; long).",
        ),
    ] = False,
    perturb_m: Annotated[
        float,
        typer.Option(
            "--perturb-m",
            help="Also run every point with the object moved this far (m, 0-0.001) both ways; "
            "agreement is then also given over the points whose label survives the shift.",
        ),
    ] = 0.0,
) -> None:
    """Pinch-grasp numerics: time the chosen setup, or compare it with its half step or the fine reference."""
    if not (0.0 <= perturb_m <= MAX_PERTURB_M):  # also refuses NaN
        fail(SomoError(f"--perturb-m must be 0 to {MAX_PERTURB_M:g} m, got {perturb_m:g}"))
    if auto_family:
        from somo_sweep.paper.auto_numerics import (
            FAMILY,
            FAMILY_CORNERS,
            FAMILY_POINTS,
            FingerCheck,
            check_family,
            family_lines,
        )

        if not 1 <= points <= len(FAMILY_POINTS):
            fail(SomoError(f"--points must be 1 to {len(FAMILY_POINTS)}, got {points}"))
        family = FAMILY + FAMILY_CORNERS if corners else FAMILY

        def progress_line(check: FingerCheck) -> None:
            typer.echo(
                f"finger stiffness x{check.stiffness_factor:g}, link mass x{check.mass_factor:g}: "
                f"{check.agree}/{len(check.auto)} labels agree",
                err=True,
            )

        checks = check_family(family, FAMILY_POINTS[:points], n_jobs=_jobs(jobs), on_finger=progress_line)
        for line in family_lines(checks):
            typer.echo(line)
        return
    if corners:
        fail(SomoError("--corners belongs to --auto-family"))
    from somo_sweep.paper.numerics import (
        CHOSEN,
        QUICK_STUDY,
        REFERENCE,
        Setup,
        parse_setup,
        quick_points,
        trial_timing_lines,
    )
    from somo_sweep.paper.numerics import compare as run_compare

    def parse(text: str, option: str) -> Setup:
        try:
            return parse_setup(text)
        except ValueError:
            fail(
                SomoError(
                    f"{option} must be DT_S,ITERATIONS,INERTIA_KG_M2[,DAMPING][,one-body][,friction-every-2]"
                    f"[,residual=R] (0 < DT_S < 1, ITERATIONS >= 1, INERTIA and DAMPING finite and >= 0, R "
                    f"finite and > 0; one-body: the gripper as one body instead of the palm and each finger "
                    f"apart; friction-every-2: the joints' Coulomb friction solved every other step; "
                    f"residual=R: Bullet's solver stops once an iteration's squared corrections sum "
                    f"below R), got '{text}'"
                )
            )

    setup = parse(a, "--a") if a else CHOSEN
    if b is not None:
        other = parse(b, "--b")
    elif compare is None:
        for line in trial_timing_lines(repeats, setup):
            typer.echo(line)
        return
    elif compare == "reference":
        other = REFERENCE
    elif compare == "half-step":
        other = dataclasses.replace(setup, time_step_s=setup.time_step_s / 2)
    else:
        fail(SomoError(f"--compare must be half-step or reference, got '{compare}'"))
    target = file_target(save, "numerics_runs.json")
    if target is not None:
        try:
            check_replaceable(target, kind="any-json")
        except SomoError as exc:
            fail(exc)
    typer.echo(f"A: {setup.describe()}\nB: {other.describe()}")
    result = run_compare(quick_points(study or QUICK_STUDY), setup, other, _jobs(jobs), perturb_m)
    runs = result.pop("runs")
    if target is not None:
        write_atomic(target, json.dumps(runs, default=str))
    typer.echo(json.dumps(result, indent=1, default=str))


#: The bundled table each data set regenerates (its name in a folder given as OUT).
DATA_NAMES = {"synthetic": "planar_finger_synthetic.csv", "diagnosis-example": "planar_finger_bench_2.csv"}


@app.command()
def data(
    which: Annotated[str, typer.Argument(help="synthetic or diagnosis-example.")],
    out: Annotated[
        str | None,
        typer.Argument(
            metavar="OUT",
            help="CSV file to write (default: print); a folder (out/, or one that exists) gets the bundled "
            "table's name in it.",
        ),
    ] = None,
) -> None:
    """Regenerate a bundled synthetic bench table (simulated, not measured)."""
    if which == "synthetic":
        from somo_sweep.calibration.synthetic import example_csv
    elif which == "diagnosis-example":
        from somo_sweep.diagnosis.example import example_csv
    else:
        fail(SomoError(f"unknown data set '{which}'; allowed: synthetic, diagnosis-example"))
    target = file_target(out, DATA_NAMES[which])
    if target is not None:
        try:
            check_replaceable(target)
        except SomoError as exc:
            fail(exc)
    text = example_csv()
    if target is None:
        typer.echo(text, nl=False)
    else:
        typer.echo(f"wrote {write_atomic(target, text)}")
