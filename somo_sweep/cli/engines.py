"""``somo-sweep compare-engines``: run one study on PyBullet and on MuJoCo and compare cell by cell."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from somo_sweep.cli.output import (
    check_output,
    check_replaceable,
    checked_jobs,
    fail,
    json_report,
    say_notes,
    write_outputs,
)
from somo_sweep.cli.sweep import JOBS
from somo_sweep.errors import SomoError, StorageError
from somo_sweep.sim.settings import step_problem

if TYPE_CHECKING:
    from somo_sweep.sweep.study import Study
    from somo_sweep.sweep.views.compare_engines import EngineComparison

__all__ = ["compare_engines"]


_OUT = Annotated[
    Path | None,
    typer.Option("--out", help="Folder for both runs and the comparison (default: results/<study>_engines)."),
]
_MUJOCO_STEP = Annotated[
    float | None,
    typer.Option(
        "--mujoco-step", help="MuJoCo's time step, s (default: the study's if it runs on MuJoCo, else 4 ms)."
    ),
]
_PYBULLET_STEP = Annotated[
    float | None,
    typer.Option(
        "--pybullet-step",
        help="PyBullet's time step, s (default: the study's if it runs on PyBullet, else 0.5 ms).",
    ),
]
_ADAPTIVE = Annotated[
    bool | None,
    typer.Option(
        "--adaptive/--exhaustive",
        help="Sampling of both runs (default: the study's sampling:, else exhaustive).",
    ),
]
_ALLOW_OUTSIDE = Annotated[
    bool, typer.Option("--allow-outside", help="Let model files include files outside their own folder.")
]


def compare_engines(
    study: Annotated[Path, typer.Argument(help="Study file (YAML or JSON).")],
    out: _OUT = None,
    jobs: JOBS = 0,
    mujoco_step: _MUJOCO_STEP = None,
    pybullet_step: _PYBULLET_STEP = None,
    adaptive: _ADAPTIVE = None,
    allow_outside: _ALLOW_OUTSIDE = False,
) -> None:
    """Run a study on both engines (resumable) and report, per cell, where their labels agree.

    Each engine's results go to OUT/pybullet and OUT/mujoco; the comparison to OUT/engines.csv
    (one row per trial: each engine's labels, agree_* and, with robustness replicas, robust_*)
    and OUT/engines.json (the summary). A task without labels (the bench) is compared metric by
    metric, as a share of each metric's range.
    """
    from somo_sweep.sweep.run.runner import RunOptions, run_sweep
    from somo_sweep.sweep.study import RESULTS_ROOT, load_study
    from somo_sweep.sweep.views.compare_engines import compare_runs, on_engines

    for name, step in (("--mujoco-step", mujoco_step), ("--pybullet-step", pybullet_step)):
        if step is not None and (why := step_problem(step)) is not None:
            fail(SomoError(f"{name}: {why}, got {step:g} s"))
    from somo_sweep.sim.mujoco.support import missing  # no MuJoCo import

    try:
        if (why := missing()) is not None:  # before PyBullet's half of the run, not after it
            raise SomoError(why)
        checked_jobs(jobs, allow_default=True)
        base = load_study(study, None, allow_outside=allow_outside)
        say_notes(base.notices)
        folder = out if out is not None else RESULTS_ROOT / f"{base.name}_engines"
        _check_outputs(folder, study)
        runs = on_engines(base, folder, {"pybullet": pybullet_step, "mujoco": mujoco_step})
        for engine, st in runs.items():
            typer.echo(f"{engine}: {st.output}", err=True)
            summary = run_sweep(st, RunOptions(n_jobs=jobs, adaptive=adaptive))
            typer.echo(f"{engine}: {summary.run} trial(s) run, {summary.skipped} already stored", err=True)
            if summary.interrupted is not None:  # a stop asked for is the whole command's, not one engine's
                typer.echo(
                    f"interrupted during the {engine} run: its finished trials are kept; nothing was "
                    "compared; run the same command again to go on where it stopped",
                    err=True,
                )
                raise typer.Exit(128 + summary.interrupted)
        result = compare_runs(base, runs)
        _write(folder, study, runs, result)
    except SomoError as exc:
        fail(exc)
    except OSError as exc:
        fail(StorageError(f"{exc.filename or folder}: {exc.strerror or exc}"), code=1)
    for line in result.lines():
        typer.echo(line)
    typer.echo(f"wrote {folder / 'engines.csv'} and {folder / 'engines.json'}")


#: The first column of engines.csv: an existing file that starts otherwise is not ours.
_CSV_HEAD = "trial,"
#: Keys of every engines.json (as an earlier version wrote it, with its own mark).
_JSON_KEYS = frozenset({"study", "engines", "labels", "metrics"})


def _check_outputs(folder: Path, study: Path) -> None:
    """Refuse, before any trial runs, a folder ``run --out`` would not take and a user's own
    engines.csv or engines.json (:func:`~somo_sweep.sweep.views.compare_engines.check_comparison_folder`).

    Raises:
        SomoError: Naming what is in the way; nothing was written.
    """
    from somo_sweep.sweep.views.compare_engines import check_comparison_folder

    check_comparison_folder(folder)
    check_output(folder / "engines.csv", _CSV_HEAD, inputs=[study])
    check_replaceable(folder / "engines.json", [study], kind="json", older_keys=_JSON_KEYS)


def _write(folder: Path, study: Path, runs: dict[str, Study], result: EngineComparison) -> None:
    """The comparison as OUT/engines.csv (cell by cell) and OUT/engines.json (the summary), each
    replacing only an earlier copy of itself."""
    report = {
        "study": str(study),
        "engines": {
            e: st.simulation.model_dump(mode="json") if st.simulation else "auto" for e, st in runs.items()
        },
        "labels": result.labels,
        "metrics": result.metrics,
    }
    check_replaceable(folder / "engines.json", [study], kind="json", older_keys=_JSON_KEYS)
    outputs: list[tuple[Path, str | bytes]] = [
        (folder / "engines.csv", result.cells.to_csv(index=False)),
        (
            folder / "engines.json",
            json_report(json.loads(json.dumps(report, default=str)), "compare-engines"),
        ),
    ]
    write_outputs(outputs, inputs=[study])
