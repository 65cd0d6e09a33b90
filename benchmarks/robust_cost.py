"""What trustworthy labels cost: one trial and the quick study, before and after, in one run.

Two measurements, each with both sides run by this process one after the other, so the ratio
holds under whatever load the machine has:

* **One trial** (the bench point: DSR 0.2, 40-mm box, c = 100 mm): CPU time under the numerics
  the pinch studies used before labels were checked for robustness (:data:`BEFORE`: 4 ms, the
  links' inertia shaped 400-fold) and under the chosen ones
  (:data:`~benchmarks.setups.CHOSEN`), alternating, ``rounds`` times each.
* **The quick study** (192 cells): run plain at :data:`BEFORE`, then at the chosen numerics with
  robustness replicas (K = 4 on label-boundary cells plus the 10 % audit), each through the sweep
  engine into its own folder; summed trial time and wall time.

``python -m benchmarks.robust_cost`` prints both and writes them as JSON into ``--out``
(``robust_cost.json``); ``make bench-robust``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import tempfile
from dataclasses import dataclass
from pathlib import Path
from time import perf_counter
from typing import TYPE_CHECKING, Any

from benchmarks._cli import echo, int_in, jobs_option, user_errors
from benchmarks.setups import BEFORE, CHOSEN, QUICK_STUDY, Setup, alternating_trial_seconds
from somo_sweep.cli.output import write_outputs
from somo_sweep.errors import SomoError

if TYPE_CHECKING:
    from somo_sweep.sweep.study import Study

__all__ = ["CostReport", "StudyCost", "cost_lines", "cost_runs", "main", "study_for"]


@dataclass(frozen=True)
class StudyCost:
    """One run of the quick study: how, trials and replicas run, summed trial time and wall time
    (s), and the machine's 1-minute load average at its start and end (wall times grow with it)."""

    name: str
    trials: int
    replicas: int
    trial_time_s: float
    wall_s: float
    load: tuple[float, float] = (float("nan"), float("nan"))


@dataclass(frozen=True)
class CostReport:
    """Both measurements.

    Attributes:
        trial_cpu_s: (before, chosen) CPU time of one trial, per round.
        studies: The plain quick study before, then the robust one at the chosen numerics.
        before: Description of the earlier numerics; ``chosen`` of the chosen ones.
    """

    trial_cpu_s: list[tuple[float, float]]
    studies: list[StudyCost]
    before: str
    chosen: str

    @property
    def trial_ratio(self) -> float:
        """Median over rounds of chosen / before CPU time of one trial."""
        return statistics.median(b / a for a, b in self.trial_cpu_s)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-able record."""
        return {
            "before": self.before,
            "chosen": self.chosen,
            "trial_cpu_s": [list(p) for p in self.trial_cpu_s],
            "trial_ratio": self.trial_ratio,
            "studies": [dataclasses.asdict(s) for s in self.studies],
        }


def _setup_overrides(setup: Setup) -> tuple[dict[str, Any], dict[str, Any]]:
    """(study overrides, simulation fields) that make a pinch study run ``setup``."""
    n = setup.numerics
    over = {"task.numerics.added_inertia_kg_m2": n.added_inertia_kg_m2}
    sim = {
        "time_step_s": setup.time_step_s,
        "solver_iterations": setup.solver_iterations,
        "body_per_manipulator": setup.body_per_manipulator,
        "friction_rows_every": setup.friction_rows_every,
    }
    return over, sim


def study_for(study_path: Path, setup: Setup, folder: Path, replicas: int) -> Study:
    """The study at ``study_path`` made to run ``setup`` with exactly ``replicas`` robustness
    replicas (0: none, whatever the file asks for)."""
    from somo_sweep.sweep.study import Simulation, derive_study, load_study, with_replicas

    base = load_study(study_path, folder)
    over, sim = _setup_overrides(setup)
    study = derive_study(base, over, base.name, folder)
    study = dataclasses.replace(study, simulation=Simulation(**sim))
    return with_replicas(study, replicas)


def _run(study_path: Path, setup: Setup, folder: Path, replicas: int, n_jobs: int, name: str) -> StudyCost:
    from somo_sweep.sweep.run.runner import RunOptions, run_sweep
    from somo_sweep.sweep.store.result_store import read_results

    study = study_for(study_path, setup, folder, replicas)
    load = _load()
    start = perf_counter()
    summary = run_sweep(study, RunOptions(n_jobs=n_jobs))
    wall = perf_counter() - start
    table = read_results(folder)
    return StudyCost(
        name, summary.run, summary.replicas_run, float(table["wall_time_s"].sum()), wall, (load, _load())
    )


def _load() -> float:
    """The 1-minute load average (NaN where the system has none)."""
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def cost_runs(
    folder: Path,
    rounds: int = 3,
    replicas: int = 4,
    n_jobs: int = 2,
    study_path: Path = QUICK_STUDY,
    chosen: Setup = CHOSEN,
) -> CostReport:
    """Time one trial both ways, then run the study plain before and robust at ``chosen``.

    Args:
        folder: Where the two results folders go (``before/``, ``robust/``); fresh folders are
            timed fresh, existing ones resume (and then time only what was left).
        rounds: Alternating rounds of the one-trial timing.
        replicas: K of the robust run.
        n_jobs: Workers of both study runs.
        study_path: The study (default: the quick Fig. 6 study).
        chosen: The numerics after.
    """
    pairs = [(a, b) for a, b in alternating_trial_seconds([BEFORE, chosen], rounds)]
    studies = [
        _run(study_path, BEFORE, folder / "before", 0, n_jobs, "plain, before"),
        _run(study_path, chosen, folder / "robust", replicas, n_jobs, f"robust (K = {replicas}), chosen"),
    ]
    return CostReport(pairs, studies, BEFORE.describe(), chosen.describe())


def cost_lines(report: CostReport) -> list[str]:
    """The report for people."""
    before, robust = report.studies
    lines = [
        f"before: {report.before}",
        f"chosen: {report.chosen}",
        "one trial, CPU s (before, chosen): "
        + ", ".join(f"{a:.2f} / {b:.2f}" for a, b in report.trial_cpu_s)
        + f"; chosen / before = {report.trial_ratio:.2f}x (median of the rounds)",
    ]
    for s in report.studies:
        lines.append(
            f"quick study, {s.name}: {s.trials} trials + {s.replicas} replicas, summed trial time "
            f"{s.trial_time_s:.0f} s, wall {s.wall_s:.0f} s (load average {s.load[0]:.1f} at the start, "
            f"{s.load[1]:.1f} at the end)"
        )
    if before.trial_time_s > 0 and before.wall_s > 0:
        trial_ratio = robust.trial_time_s / before.trial_time_s
        lines.append(
            f"robust quick study / plain quick study before: {trial_ratio:.2f}x summed trial time, "
            f"{robust.wall_s / before.wall_s:.2f}x wall"
        )
    return lines


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.robust_cost``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.robust_cost",
        description="What robust labels cost: one trial, and the quick study plain before vs robust "
        "(K = 4) now.",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=Path("results/reference"),
        help="folder for robust_cost.json (default results/reference; the study runs go to a temporary one)",
    )
    ap.add_argument(
        "--rounds", type=int_in(1), default=3, help="alternating rounds of the one-trial timing (default 3)"
    )
    ap.add_argument(
        "--jobs", "-j", type=jobs_option(), default=2, help="workers of the two study runs (default 2)"
    )
    ap.add_argument(
        "--work", type=Path, help="keep the two results folders here (before/, robust/; default: temporary)"
    )
    return ap


def main(argv: list[str] | None = None) -> None:
    """Run both measurements, print them and write ``robust_cost.json``."""
    args = parser().parse_args(argv)
    with user_errors():
        if args.work is not None and (args.work / "before").exists():
            raise SomoError(
                f"--work {args.work} already holds a run (before/): the benchmark times fresh runs"
            )
        with tempfile.TemporaryDirectory(prefix="somo-sweep-robust-cost-") as tmp:
            report = cost_runs(args.work or Path(tmp), rounds=args.rounds, n_jobs=args.jobs)
        echo(cost_lines(report))
        text = json.dumps(report.as_dict(), indent=2) + "\n"
        (path,) = write_outputs([(args.out / "robust_cost.json", text)])
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
