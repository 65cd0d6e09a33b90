"""Small design studies for the tests: a ball around the origin (the selftest task, milliseconds a
trial) and the worked example's gripper on MuJoCo (a fraction of a second a trial).

The ball: ``selftest_sleep`` labels ``region`` ``inside`` where x² + u² + v² < r², its replicas move
x by up to ``jitter``. The design variables are u (where the design sits across the ball) and r
(choices); the objects are x × v. The best designs are those near u = 0 with the largest radius;
cells within ``jitter`` of the ball's surface are not robust.
"""

from __future__ import annotations

import os
import select
import shutil
import textwrap
import time
from pathlib import Path

from conftest import MODELS

ROOT = Path(__file__).resolve().parents[2]
#: The design benchmark's gripper: the worked example's, its finger calibrated from the bench CSV.
GRIPPER = ROOT / "results" / "reference" / "design_bench"

BALL = """\
name: ball_design
task: selftest_sleep
model: models/ihm_finger.yaml
params: {sleep_s: 0.0, jitter: 0.06}
seed: 3
simulation: {time_step_s: 1.0e-3}
design:
  variables:
    task.u: {low: -1.0, high: 1.0}
    task.region_radius_m: {choices: [0.7, 0.9, 1.1]}
  objects:
    task.x: [-0.6, -0.3, 0.0, 0.3, 0.6, 0.9]
    task.v: [0.0, 0.4]
  objective: {label: region, value: inside}
  replicas: 3
  budget: BUDGET
  search: {designs_per_batch: 6, stratify: task.v}
"""

GRIPPER_DESIGN = """\
name: grip_design
task: pinch_grasp
model: gripper.yaml
seed: 0
simulation: {engine: mujoco, time_step_s: 4.0e-3}
design:
  variables:
    task.distal_segment_ratio: {low: 0.2, high: 0.35}
    task.pressure_kpa: {choices: [150, 200]}
  objects:
    task.object_width_m: [0.020, 0.040]
    task.centering_position_m: [0.112, 0.126]
  objective: {label: grasp, value: pinch}
  replicas: 1
  budget: BUDGET
  search: {designs_per_batch: 3, finalists: 2}
"""


def ball_study(folder: Path, budget: int = 120, edit: str = "") -> Path:
    """The ball design study in ``folder`` (next to a copy of the bundled models); ``edit`` is a
    ``old=>new`` replacement of its text (a broken study)."""
    if not (folder / "models").exists():
        shutil.copytree(MODELS, folder / "models")
    text = BALL.replace("BUDGET", str(budget))
    if edit:
        old, new = edit.split("=>")
        assert old in text, old
        text = text.replace(old, new)
    path = folder / "ball.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def gripper_study(folder: Path, budget: int = 40, edit: str = "") -> Path:
    """The gripper design study in ``folder`` (next to copies of the gripper and its finger)."""
    for name in ("gripper.yaml", "finger.yaml"):
        shutil.copy(GRIPPER / name, folder / name)
    text = GRIPPER_DESIGN.replace("BUDGET", str(budget))
    if edit:
        old, new = edit.split("=>")
        assert old in text, old
        text = text.replace(old, new)
    path = folder / "grip.yaml"
    path.write_text(text)
    return path


class FinishedTrials:
    """Blocks until selftest trials have returned: each writes one byte into a named pipe (the
    test keeps a writer open itself, so the pipe never reads as closed between trials)."""

    def __init__(self, fifo: Path, timeout_s: float = 60.0):
        self.fifo, self.timeout_s, self.count = fifo, timeout_s, 0

    def __enter__(self) -> FinishedTrials:
        self.read_fd = os.open(self.fifo, os.O_RDONLY | os.O_NONBLOCK)
        self.keep_fd = os.open(self.fifo, os.O_WRONLY | os.O_NONBLOCK)
        return self

    def __exit__(self, *exc: object) -> None:
        os.close(self.keep_fd)
        os.close(self.read_fd)

    def wait(self, count: int) -> None:
        """Until ``count`` trials have returned in all."""
        deadline = time.monotonic() + self.timeout_s
        while self.count < count:
            ready, _, _ = select.select([self.read_fd], [], [], max(deadline - time.monotonic(), 0.0))
            assert ready, f"only {self.count} of {count} trials finished in {self.timeout_s} s"
            self.count += len(os.read(self.read_fd, 1024))
