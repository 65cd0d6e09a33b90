"""Tasks that exercise the sweep engine itself (tag ``selftest``); they simulate nothing.

* ``selftest_sleep``: sleeps ``sleep_s`` and returns metrics computed from ``x`` and the seed.
* ``selftest_crash``: like ``selftest_sleep``, but the process running the trial dies when
  ``x`` is in ``crash_x`` (``how``: ``exit`` = ``os._exit(3)``, ``segfault``, ``kill`` = SIGKILL),
  or raises an exception (``how: raise``).
* ``selftest_unstable``: like ``selftest_sleep``, but reports a blow-up when ``x`` is in
  ``unstable_x`` (raises :class:`~somo_sweep.errors.UnstableSimulation`, as the core does),
  at any step or, with ``unstable_above_step_s`` > 0, only at steps above that one.

With ``region_radius_m`` set, every task also labels ``region`` ``inside`` or ``outside`` the
ball of that radius around the origin in (x, u, v): a known label boundary in up to three
dimensions, for the adaptive-sampling tests. Their robustness replicas (:func:`perturb`) move
``x`` by up to ``jitter`` (``x_offset``), so cells within ``jitter`` of a boundary can flip.

They let the robustness tests run in real loky and Dask worker processes in milliseconds.
"""

from __future__ import annotations

import ctypes
import os
import signal
import time
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from somo_sweep.errors import UnstableSimulation
from somo_sweep.tasks.registry import TaskParams, TaskResult, TaskSpec, register

if TYPE_CHECKING:  # annotations only: these tasks run no simulation
    from somo_sweep.model.load import Model
    from somo_sweep.sim.settings import WorldSettings

__all__ = ["METRICS", "SelftestParams"]

#: The metrics every selftest task returns, with their types (``y`` is missing for ``none_x``).
METRICS = {"y": "double", "noise": "double", "time_s": "double"}


class SelftestParams(TaskParams):
    """Parameters of the selftest tasks.

    Attributes:
        x: Input value (dimensionless).
        u: Second input, for labels over two or three axes (dimensionless).
        v: Third input (dimensionless).
        region_radius_m: If > 0, the label ``region`` is ``inside`` where x² + u² + v² is below
            its square, else ``outside`` (the inputs read as lengths here, m).
        sleep_s: Wall time to sleep per trial, s.
        crash_x: Values of ``x`` whose trial kills its process (``selftest_crash``).
        how: How to fail: ``exit``, ``segfault``, ``kill`` (the process dies) or ``raise``.
        unstable_x: Values of ``x`` reported unstable (``selftest_unstable``).
        unstable_above_step_s: If > 0, those trials blow up only at time steps above this, s.
        none_x: Values of ``x`` whose metric ``y`` is missing (None).
        done_dir: If set, a folder where every trial leaves an empty file (named by ``x`` and
            the seed) as it returns, so that fault-injection tests can count finished trials.
        notify_fifo: If set, a named pipe that gets one byte as each trial returns, so that a
            test can block until trials finish instead of polling (no reader: nothing sent).
        jitter: Largest shift of ``x`` a robustness replica draws (:func:`perturb`).
        x_offset: Shift of ``x`` in the labels (a replica's draw).
        coarse_above_s: If > 0, the label ``step`` is ``coarse`` at time steps above this, s,
            else ``fine``: a label that converges only below a known step.
        label_the_step: Label ``dt`` with the time step itself: a label that never converges.
    """

    x: float = 0.0
    u: float = 0.0
    v: float = 0.0
    region_radius_m: float = Field(0.0, ge=0)
    sleep_s: float = Field(0.0, ge=0)
    crash_x: list[float] = Field(default_factory=list)
    how: Literal["exit", "segfault", "kill", "raise"] = "exit"
    unstable_x: list[float] = Field(default_factory=list)
    unstable_above_step_s: float = Field(0.0, ge=0)
    none_x: list[float] = Field(default_factory=list)
    done_dir: str = ""
    notify_fifo: str = ""
    jitter: float = Field(0.0, ge=0)
    x_offset: float = 0.0
    coarse_above_s: float = Field(0.0, ge=0)
    label_the_step: bool = False


def _notify(fifo: str) -> None:
    try:
        fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
    except OSError:  # no reader (ENXIO) or not there: nobody is waiting
        return
    try:
        os.write(fd, b".")
    finally:
        os.close(fd)


def _result(params: SelftestParams, seed: int, step_s: float = 0.0) -> TaskResult:
    time.sleep(params.sleep_s)
    noise = np.random.default_rng(seed).normal()  # a NumPy scalar, as tasks often return
    if params.done_dir:
        Path(params.done_dir, f"{params.x}-{seed}").touch()
    if params.notify_fifo:
        _notify(params.notify_fifo)
    return TaskResult(
        metrics={
            "y": None if params.x in params.none_x else params.x**2,
            "noise": noise,
            "time_s": params.sleep_s,
        },
        labels=_labels(params, step_s),
    )


def _labels(params: SelftestParams, step_s: float = 0.0) -> dict[str, str]:
    x = params.x + params.x_offset
    labels = {"sign": "positive" if x > 0 else "non_positive"}
    if params.coarse_above_s > 0:
        labels["step"] = "coarse" if step_s > params.coarse_above_s else "fine"
    if params.label_the_step:
        labels["dt"] = f"{step_s:.6g}"
    if params.region_radius_m > 0:
        inside = x**2 + params.u**2 + params.v**2 < params.region_radius_m**2
        labels["region"] = "inside" if inside else "outside"
    return labels


def _sleep(model: Model, params: SelftestParams, settings: WorldSettings, seed: int) -> TaskResult:
    return _result(params, seed, settings.time_step_s)


def _crash(model: Model, params: SelftestParams, settings: WorldSettings, seed: int) -> TaskResult:
    if params.x in params.crash_x:
        if params.how == "raise":
            raise RuntimeError(f"selftest failure at x={params.x}")
        if params.how == "segfault":
            ctypes.string_at(0)
        elif params.how == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        os._exit(3)
    return _result(params, seed)


def _unstable(model: Model, params: SelftestParams, settings: WorldSettings, seed: int) -> TaskResult:
    too_large = params.unstable_above_step_s == 0 or settings.time_step_s > params.unstable_above_step_s
    if params.x in params.unstable_x and too_large:
        raise UnstableSimulation("speed_cap", 0.123, "(selftest)")
    return _result(params, seed, settings.time_step_s)


def perturb(params: SelftestParams, rng: np.random.Generator) -> SelftestParams:
    """A robustness replica: ``x_offset`` moved by a uniform draw within ±``jitter``."""
    shift = float(rng.uniform(-params.jitter, params.jitter))
    return params.model_copy(update={"x_offset": params.x_offset + shift})


for _name, _fn, _text in (
    ("selftest_sleep", "_sleep", "Sleeps and returns y = x² (engine tests)."),
    ("selftest_crash", "_crash", "Kills its process for chosen x (engine tests)."),
    ("selftest_unstable", "_unstable", "Reports a blow-up for chosen x (engine tests)."),
):
    register(
        TaskSpec(
            _name,
            f"{__name__}:{_fn}",
            SelftestParams,
            _text,
            ("selftest",),
            METRICS,
            perturb=perturb,
            perturbation="x moved by up to ±jitter",
            labels=("sign", "step", "dt", "region"),
        )
    )
