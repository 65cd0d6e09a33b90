"""A study's bookkeeping stays flat in its number of trials: the job table holds ids, not jobs.

No physics here: 2 000 and 20 000 trials of a selftest task (10 points, the rest repeats), the
job table built, the trials not yet stored picked out (half of them, as on resume) and the
first of them built. The peak of what Python allocates on the way must grow by bytes a
trial, not by jobs (the table held every job before: about 440 bytes a trial here, far more
with distinct models). The sweep process's own peak at 2 000 and 20 000 real trials is measured
by ``python -m benchmarks.scale`` (``make bench-scale``).
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
from test_sweep import make_study

from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.study import load_study


def _peak_bytes(folder: Path, n_trials: int) -> int:
    body = f"task: selftest_sleep\nmodel: models/ihm_finger.yaml\nrepeats: {n_trials // 10}\n"
    study = load_study(make_study(folder, body + "sweep:\n  task.x: {start: 1, stop: 10, step: 1}\n"))
    tracemalloc.start()
    try:
        table = build_jobs(study)
        stored = table.ids[::2].copy()  # half the trials are in the results folder
        todo = table.select(np.flatnonzero(~table.among(stored)))
        first = [job.job_id for job in todo[:20]]
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(todo) == n_trials // 2 and first[0] == table.ids[1].decode()
    return peak


def test_the_job_table_and_resume_cost_bytes_a_trial(tmp_path: Path) -> None:
    build_jobs(load_study(make_study(tmp_path, "task: selftest_sleep\nmodel: models/ihm_finger.yaml\n")))
    small = _peak_bytes(tmp_path / "small", 2_000)
    large = _peak_bytes(tmp_path / "large", 20_000)
    per_trial = (large - small) / 18_000
    assert per_trial < 100, f"{per_trial:.0f} bytes a trial"
