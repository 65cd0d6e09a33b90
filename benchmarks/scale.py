"""Memory and resume time of one sweep at 2 000 and at 20 000 trials (``make bench-scale``).

The study is the bench task's tip-load protocol on the IHM finger over a 4-axis grid: 25
pressures x 10 tip loads x 8 grasp-joint stiffnesses x N / 2 000 link masses, at a fixed 0.5 ms
step (a trial is about 25 ms of CPU). Each size runs as ``somo-sweep run --jobs J`` in a process
of its own, whose peak resident memory (``VmHWM``, Linux) is read while it runs; the largest is
then run again, stopped with SIGINT once half its trials are stored, and resumed: the resumed
run's time from its start to its first finished trial (its first row in the folder, in its
journal or a part file) bounds from above when its first new trial started. The ratio of the
largest study's peak to the smallest's says whether the sweep's memory grows with its trials.

``python -m benchmarks.scale [--trials 2000,20000] [--jobs 2] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import pyarrow.parquet as pq

from benchmarks._cli import echo, jobs_option, user_errors
from somo_sweep.cli.output import write_atomic
from somo_sweep.errors import SomoError
from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.store.folder import JOURNAL_GLOB, PART_GLOB

__all__ = [
    "TRIALS_PER_MASS",
    "ScaleRun",
    "main",
    "measure_run",
    "scale_lines",
    "scale_study",
]

#: Trials per link-mass value of the grid (25 pressures x 10 loads x 8 stiffnesses).
TRIALS_PER_MASS = 2000
_POLL_S = 0.1


def scale_study(n_trials: int) -> str:
    """The YAML text of the study of ``n_trials`` trials (a multiple of :data:`TRIALS_PER_MASS`).

    Raises:
        SomoError: ``n_trials`` is not a positive multiple of :data:`TRIALS_PER_MASS`.
    """
    masses, rest = divmod(n_trials, TRIALS_PER_MASS)
    if masses < 1 or rest:
        raise SomoError(f"--trials: each size must be a multiple of {TRIALS_PER_MASS}, got {n_trials}")
    values = ", ".join(f"{0.0020 + 0.0002 * i:.4f}" for i in range(masses))
    return "\n".join(
        [
            f"name: scale_{n_trials}",
            "task: bench",
            f"model: {bundled_path('models', 'ihm_finger.yaml')}",
            "params: {test: tip_load}",
            "sweep:",
            "  task.pressure_kpa: {start: 0, stop: 240, step: 10}",
            "  task.tip_load_n: {start: 0.0, stop: 0.09, step: 0.01}",
            "  model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad:",
            "    {start: 0.15, stop: 0.29, step: 0.02}",
            f"  model.manipulator.actuators[0].link.mass_kg: [{values}]",
            "seed: 0",
            "simulation: {time_step_s: 5.0e-4, scale: 20}",
            "",
        ]
    )


@dataclass(frozen=True)
class ScaleRun:
    """One measured ``somo-sweep run``.

    Attributes:
        trials: Trials of the study.
        wall_s: Wall time of the run, s.
        peak_rss_mb: Peak resident memory of the sweep's process (not its workers), MiB; NaN
            where ``/proc`` is missing.
        first_row_s: From the start of the process to the first row it stored (journal or part
            file), s; None if it stored none.
        first_row_cpu_s: CPU time the sweep's process had used by then, s (its workers not
            counted; NaN where ``/proc`` is missing): on a loaded machine the wall time to the
            first row stretches, this does not.
        stored: Trials stored in the folder when the run ended.
        returncode: The run's exit code (130 when stopped with SIGINT).
    """

    trials: int
    wall_s: float
    peak_rss_mb: float
    first_row_s: float | None
    first_row_cpu_s: float | None
    stored: int
    returncode: int


def _stored_files(folder: Path) -> list[Path]:
    trials = folder / "trials"
    return [*trials.glob(PART_GLOB), *trials.glob(JOURNAL_GLOB)] if trials.is_dir() else []


def _rows_in(files: list[Path]) -> int:
    rows = 0
    for path in files:
        with contextlib.suppress(OSError):  # replaced or deleted while being read: the next poll
            if path.name.endswith(".parquet"):
                rows += pq.read_metadata(path).num_rows
            else:
                rows += path.read_bytes().count(b"\n")
    return rows


def _stored_rows(folder: Path) -> int:
    return _rows_in(_stored_files(folder))


def _cpu_s(pid: int) -> float | None:
    """CPU time (user + system) of a process and of the children it has waited for, s (Linux)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return sum(int(f) for f in fields[11:15]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def _peak_kib(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except (OSError, ValueError):
        return None
    return None


def measure_run(
    study: Path, folder: Path, n_trials: int, jobs: int = 2, stop_at: int | None = None
) -> ScaleRun:
    """Run ``somo-sweep run STUDY --jobs J --out FOLDER`` and measure it (see the module docstring).

    Args:
        study: The study file.
        folder: Its results folder.
        n_trials: Trials of the study.
        jobs: Worker processes.
        stop_at: Send SIGINT once this many trials are stored (parts and journal), if given.
    """
    cmd = [sys.executable, "-m", "somo_sweep", "run", str(study), "--jobs", str(jobs), "--no-plots"]
    cmd += ["--out", str(folder), "--allow-errors"]
    # A row of this run shows as a file that was not there before: a journal line or, once the
    # journal is written out (a short run may do both between two polls), a part file. Rows of a
    # killed run's journals are written into a new part first: only rows beyond those count.
    before = set(_stored_files(folder))
    recoverable = _rows_in([p for p in before if not p.name.endswith(".parquet")])
    start = time.perf_counter()
    # The run starts with SIGINT at its default, as a shell starts a command: launched in the
    # background (`make bench-scale &`), this process has it ignored, and the run would keep that.
    proc = subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, preexec_fn=_sigint_as_in_a_shell
    )
    peak, first, first_cpu, sent = 0, None, None, False
    while proc.poll() is None:
        peak = max(peak, _peak_kib(proc.pid) or 0)
        if first is None and _rows_in([p for p in _stored_files(folder) if p not in before]) > recoverable:
            first, first_cpu = time.perf_counter() - start, _cpu_s(proc.pid)
        if stop_at is not None and not sent and _stored_rows(folder) >= stop_at:
            proc.send_signal(signal.SIGINT)
            sent = True
        time.sleep(_POLL_S if first is None else 5 * _POLL_S)
    wall = time.perf_counter() - start
    peak_mb = peak / 1024 if peak and os.path.exists("/proc") else float("nan")
    return ScaleRun(n_trials, wall, peak_mb, first, first_cpu, _stored_rows(folder), proc.returncode)


def scale_lines(runs: list[ScaleRun], interrupted: ScaleRun, resumed: ScaleRun, jobs: int) -> list[str]:
    """Printable lines: each size's wall time and peak memory, the ratio, the resume's start."""
    lines = [f"sweep at scale: bench tip-load grid, --jobs {jobs}, peak memory of the sweep's own process:"]
    for r in runs:
        lines.append(
            f"  {r.trials:7d} trials: {r.wall_s:7.1f} s ({r.trials / r.wall_s:.1f} trials/s), "
            f"peak {r.peak_rss_mb:.1f} MiB, exit code {r.returncode}"
        )
    small, large = min(runs, key=lambda r: r.trials), max(runs, key=lambda r: r.trials)
    ratio = large.peak_rss_mb / small.peak_rss_mb
    lines.append(f"  peak memory at {large.trials} / at {small.trials} trials = {ratio:.2f}")
    first = resumed.first_row_s
    cpu = "" if resumed.first_row_cpu_s is None else f" ({resumed.first_row_cpu_s:.1f} s of the sweep's CPU)"
    shown = "never" if first is None else f"{first:.1f} s{cpu}"
    lines.append(
        f"  {interrupted.trials} trials stopped (SIGINT) with {interrupted.stored} stored, then resumed: "
        f"first new trial finished {shown} after the start; "
        f"the resumed run took {resumed.wall_s:.1f} s, peak {resumed.peak_rss_mb:.1f} MiB, "
        f"{resumed.stored} stored"
    )
    return lines


def _sigint_as_in_a_shell() -> None:
    """In the child before exec: SIGINT at its default and unblocked."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _sizes(text: str) -> list[int]:
    """``--trials``: the study sizes, each checked by :func:`scale_study`."""
    try:
        sizes = sorted({int(t) for t in text.split(",")})
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be whole numbers separated by commas, got '{text}'") from None
    try:
        for n in sizes:
            scale_study(n)
    except SomoError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--trials: ")) from None
    return sizes


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.scale``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.scale",
        description="Sweep memory and resume time at scale: peak memory of `somo-sweep run` at each size, "
        "then the largest stopped at half its trials and resumed (time to its first new trial).",
    )
    ap.add_argument(
        "--trials",
        type=_sizes,
        default=[2000, 20000],
        help="study sizes, comma-separated multiples of 2000; the largest is resumed (default 2000,20000)",
    )
    ap.add_argument("--jobs", type=jobs_option(), default=2, help="worker processes (default 2)")
    ap.add_argument("--out", type=Path, help="folder for the studies and results (default: a temporary one)")
    return ap


def main(argv: list[str] | None = None) -> None:
    """Run every size, then stop and resume the largest; print what each run measured."""
    args = parser().parse_args(argv)
    sizes, out, n_jobs = args.trials, args.out, args.jobs
    with user_errors():
        if out is not None and (out.is_file() or (out.is_dir() and any(out.iterdir()))):
            raise SomoError(f"--out {out} must be a new or empty folder (each run must start from nothing)")
        with tempfile.TemporaryDirectory(prefix="somo-sweep-scale-") as tmp:
            folder = out or Path(tmp)
            folder.mkdir(parents=True, exist_ok=True)
            runs = []
            for n in sizes:
                study = write_atomic(folder / f"scale_{n}.yaml", scale_study(n))
                runs.append(measure_run(study, folder / f"run_{n}", n, n_jobs))
                echo([f"{n} trials: {runs[-1].wall_s:.1f} s, peak {runs[-1].peak_rss_mb:.1f} MiB"])
            largest = sizes[-1]
            study = folder / f"scale_{largest}.yaml"
            stopped = measure_run(study, folder / "resume", largest, n_jobs, stop_at=largest // 2)
            resumed = measure_run(study, folder / "resume", largest, n_jobs)
            echo(scale_lines(runs, stopped, resumed, n_jobs))


if __name__ == "__main__":
    main()
