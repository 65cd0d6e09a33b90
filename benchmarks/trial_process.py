"""A sweep's MuJoCo trials with a fork per trial and with a forked process kept for several, in turn
(``make bench-trial-process``).

The same ``--cells`` quick-grid cells on MuJoCo (its first ones: whole (DSR, width) columns, as a
sweep's workers take them) run through the sweep's local execution path
(:func:`~somo_sweep.sweep.run.execution.run_jobs`, ``--jobs`` workers) twice per repeat: *fork*,
one forked process per trial (``TRIALS_PER_PROCESS`` emptied), and *kept*, a forked process kept
for up to :func:`~somo_sweep.sweep.run.trial_process.trials_per_process` trials (the default),
in alternating order, after one untimed pass that starts the workers and compiles the scenes.
CPU is the whole process tree's (this process, its workers, their trial processes, reaped or
alive), wall the pass's; both per trial, with the ratio kept / fork. Every pass's outcomes are
compared with the first's, bit for bit. Prints only.

``python -m benchmarks.trial_process [--cells 64] [--jobs 2] [--repeats 2] [--per-process N]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from benchmarks._cli import echo, int_in, jobs_option, user_errors
from benchmarks.engines import _jobs
from somo_sweep.errors import SomoError
from somo_sweep.sim.settings import MUJOCO_DEFAULT_STEP_S
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.run import trial_process
from somo_sweep.sweep.run.execution import run_jobs
from somo_sweep.sweep.run.options import RunOptions

__all__ = ["main", "passes", "tree_cpu_s"]

WAYS = ("fork", "kept")


def tree_cpu_s() -> float:
    """CPU time of this process and every process under it, alive or reaped by one of them, s
    (Linux: ``/proc``)."""
    tick = os.sysconf("SC_CLK_TCK")
    total, todo = 0, [os.getpid()]
    while todo:
        pid = todo.pop()
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
            for task in Path(f"/proc/{pid}/task").iterdir():
                todo += [int(c) for c in (task / "children").read_text().split()]
        except OSError:  # ended meanwhile: its time is in its parent's children's
            continue
        total += sum(int(f) for f in fields[11:15])  # utime, stime, cutime, cstime
    return total / tick


@contextmanager
def _way(name: str, per_process: int | None = None) -> Iterator[None]:
    """``fork``: one trial per forked process; ``kept``: up to ``per_process`` MuJoCo trials
    (None: the package's default)."""
    saved = dict(trial_process.TRIALS_PER_PROCESS)
    if name == "fork":
        trial_process.TRIALS_PER_PROCESS.clear()
    elif per_process is not None:
        trial_process.TRIALS_PER_PROCESS["mujoco"] = per_process
    try:
        yield
    finally:
        trial_process.TRIALS_PER_PROCESS.clear()
        trial_process.TRIALS_PER_PROCESS.update(saved)


def _outcome_key(out: Any) -> tuple[Any, ...]:
    return (out.status, out.message, tuple(sorted(out.labels.items())), repr(sorted(out.metrics.items())))


def passes(
    jobs: list[Job], workers: int, repeats: int, per_process: int | None = None
) -> list[dict[str, Any]]:
    """Run ``jobs`` both ways ``repeats`` times in alternating order; one row per pass (``kept``:
    up to ``per_process`` trials a process, None: the package's default)."""
    rows: list[dict[str, Any]] = []
    first: dict[str, tuple[Any, ...]] = {}
    for _ in run_jobs(jobs, RunOptions(n_jobs=workers)):  # workers started, scenes compiled: untimed
        pass
    order = [WAYS if r % 2 == 0 else WAYS[::-1] for r in range(repeats)]
    for r, ways in enumerate(order):
        for name in ways:
            with _way(name, per_process):
                cpu, wall = tree_cpu_s(), time.perf_counter()
                outs = {job.job_id: out for job, out in run_jobs(jobs, RunOptions(n_jobs=workers))}
                wall, cpu = time.perf_counter() - wall, tree_cpu_s() - cpu
            keys = {i: _outcome_key(o) for i, o in outs.items()}
            first = first or keys
            rows.append(
                {
                    "repeat": r,
                    "way": name,
                    "cpu_per_trial_s": cpu / len(jobs),
                    "wall_per_trial_s": wall / len(jobs),
                    "ok": sum(o.status == "ok" for o in outs.values()),
                    "same_as_first": sum(keys[i] == first[i] for i in first),
                }
            )
    return rows


def lines(rows: list[dict[str, Any]], n: int, workers: int, most: int) -> Iterator[str]:
    """The passes, then the medians and the ratios kept / fork (``most``: trials a kept process ran
    at most)."""
    yield f"{n} MuJoCo quick-grid cells, {workers} worker(s); kept: up to {most} trials per forked process"
    for row in rows:
        yield (
            f"  repeat {row['repeat']} {row['way']:<4}: CPU {1e3 * row['cpu_per_trial_s']:6.1f} ms/trial, "
            f"wall {1e3 * row['wall_per_trial_s']:6.1f} ms/trial, ok {row['ok']}/{n}, "
            f"outcomes equal to the first pass's {row['same_as_first']}/{n}"
        )
    med = {
        (way, key): statistics.median(r[key] for r in rows if r["way"] == way)
        for way in WAYS
        for key in ("cpu_per_trial_s", "wall_per_trial_s")
    }
    for key, what in (("cpu_per_trial_s", "CPU"), ("wall_per_trial_s", "wall")):
        fork, kept = med["fork", key], med["kept", key]
        yield (
            f"{what} per trial (median): fork {1e3 * fork:.1f} ms, kept {1e3 * kept:.1f} ms, "
            f"kept / fork {kept / fork:.3f}"
        )


def parser() -> argparse.ArgumentParser:
    """The command line."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.trial_process", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument(
        "--cells", type=int_in(2, 192), default=64, help="quick-grid cells on MuJoCo (default 64)"
    )
    ap.add_argument("--jobs", type=jobs_option(), default=2, help="local workers (default 2)")
    ap.add_argument("--repeats", type=int_in(1), default=2, help="passes each way, alternating (default 2)")
    ap.add_argument(
        "--per-process",
        type=int_in(2),
        default=None,
        help="MuJoCo trials a kept process runs at most (default: the package's)",
    )
    return ap


def main(argv: list[str] | None = None) -> None:
    """Run both ways in turn and print the passes and the ratios."""
    from somo_sweep.sim.mujoco.support import missing  # no MuJoCo import

    args = parser().parse_args(argv)
    with user_errors():
        if (why := missing()) is not None:
            raise SomoError(why)
        jobs = _jobs("mujoco", MUJOCO_DEFAULT_STEP_S)[: args.cells]
        most = args.per_process or trial_process.trials_per_process("mujoco")
        echo(lines(passes(jobs, args.jobs, args.repeats, most), len(jobs), args.jobs, most))


if __name__ == "__main__":
    main()
