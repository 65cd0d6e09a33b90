"""The study file's schema: which task to run on which model, the axes to sweep, and how.

A study file (YAML or JSON) looks like this; paths are relative to the study file::

    name: finger_pressure_sweep          # default: the file name; output goes to results/<name>
    task: bench                          # a registered task (``somo-sweep tasks`` lists them)
    model: models/ihm_finger.yaml        # the model file every trial starts from
    params:                              # fixed task parameters (the task's own schema)
      test: free_bending
    set:                                 # fixed overrides by key path (optional)
      model.manipulator.actuators[0].joints[0].motor_limit_n_m: 0.0
    sweep:                               # one axis per key path; the full grid by default
      task.pressure_kpa: {start: 0, stop: 200, step: 25}        # inclusive, round-off safe
      model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad: [0.15, 0.2186, 0.30]
      task.tip_load_n: {start: 0.0, stop: 0.2, num: 9}          # linspace
    link:                                # axes zipped together instead of crossed (same lengths;
      - [task.pressure_kpa, task.tip_load_n]   # a value may repeat, a combination may not)
    cells: tables/cells.csv              # or an inline list of rows: explicit parameter rows
                                         # (somo_sweep.sweep.study.cells), crossed with any sweep axes
    repeats: 1                           # trials per grid point, each with its own seed
    seed: 0                              # base seed; trial seeds derive from it and the point
    simulation: {time_step_s: 5.0e-4, scale: 20, solver_iterations: 50, gravity_m_s2: [0, 0, -9.81]}
                                         # without it: the step and inertia shaping are chosen from
                                         # each model's modes (somo_sweep.sim.numerics);
                                         # {engine: mujoco}: MuJoCo instead of PyBullet (its step: 4 ms)
    output: results/finger_pressure_sweep   # a folder inside results/ of the current directory
    sampling: grid                       # or active: batches where a model of the labels is unsure;
                                         # or adaptive: a coarse sub-grid, refined where labels change
    active: {target_agreement: 0.98}     # optional: the active sampler's settings (:class:`Active`)
    adaptive: {labels: [grasp], coarse_step: 4}   # optional: labels to follow (default: all), stride

In YAML flow style (``{...}``) quote keys holding ``[i]``; block style needs no quotes.
Key paths start with ``model.`` (any field of the model file, list items as ``[i]``)
or ``task.`` (a task parameter, nested with dots). The axis ``model`` (no path) sweeps
over model files. An axis is a list, ``{values: [...]}``, ``{start, stop, step}``
(inclusive) or ``{start, stop, num}`` (evenly spaced, inclusive). ``cells:`` gives rows of
values instead (:mod:`somo_sweep.sweep.study.cells`): the rows are one dimension, their keys zipped.
A field takes its value from one key: two keys of ``params``, ``set``, ``sweep`` or ``cells`` that
can reach the same field are refused (:mod:`somo_sweep.sweep.study.overlaps`).

Every trial's model and task parameters are validated when the study is loaded,
so a bad value fails before anything runs, naming the file, line and key path. The
number of trials is counted from the axis specs before any axis is expanded, and a
study above ``max_trials`` (:data:`MAX_TRIALS` by default) is refused. ``name`` and
``output`` may only place results inside :data:`RESULTS_ROOT`; an explicit output
folder (``--out``) may be anywhere.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, field_validator, model_validator

from somo_sweep.model.description import Spec
from somo_sweep.sim.settings import (
    ENGINE_SETTINGS,
    MUJOCO_DEFAULT_STEP_S,
    MujocoSettings,
    MujocoWarpSettings,
    WorldSettings,
    option_names,
    step_problem,
)
from somo_sweep.sweep.store.schema import MAX_REPLICAS

__all__ = [
    "MAX_REPLICAS",
    "MAX_TRIALS",
    "RESULTS_ROOT",
    "Active",
    "Adaptive",
    "Robustness",
    "Simulation",
    "StudyFile",
]

#: Most trials a study may have unless the caller allows more (``--max-trials``).
MAX_TRIALS = 1_000_000
#: Folder (relative to the current directory) that ``name`` and ``output`` must stay inside.
RESULTS_ROOT = Path("results")


class Simulation(Spec):
    """Simulation settings of every trial (SI).

    ``body_per_manipulator: true`` loads a hand with a fixed or driven palm as one PyBullet
    body per finger plus the palm, at a lower cost per step
    (:func:`somo_sweep.sim.planner.plan_assembly`). The hand moves the same, but knife-edge
    contact outcomes can come out the other way, so check a study's results before opting
    in (docs/model.md, "Simulation settings").

    ``friction_rows_every: 2`` solves the joints' Coulomb friction every other step; on the step
    between, a sliding joint keeps its friction torque and a stuck one gets its static demand
    (:attr:`~somo_sweep.sim.settings.PyBulletSettings.friction_rows_every`). 1 (default) solves it
    every step.

    ``engine: mujoco`` runs every trial on MuJoCo (optional extra ``somo-sweep[mujoco]``; docs/engines.md):
    springs implicit, no inertia shaping, SI throughout. ``time_step_s`` left out is then 4 ms
    (:data:`~somo_sweep.sim.settings.MUJOCO_DEFAULT_STEP_S`), and ``integrator``,
    ``contact_time_constant_s``, ``impratio`` and ``noslip_iterations`` tune it. Each engine
    refuses the other's own options set to anything but their defaults (``scale``,
    ``body_per_manipulator`` and ``friction_rows_every`` are PyBullet's).

    ``engine: mujoco_warp`` runs MuJoCo's scenes on MuJoCo Warp (optional extra
    ``somo-sweep[warp]``; docs/engines.md), with MuJoCo's options and its own: ``device``
    (``cpu`` or ``cuda``), ``contacts_per_world`` and ``constraints_per_world``.
    """

    text_numbers: ClassVar[bool] = False

    time_step_s: float | None = Field(None, gt=0)
    scale: float = Field(20.0, gt=0)
    solver_iterations: int = Field(50, ge=1)
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    body_per_manipulator: bool = False
    friction_rows_every: int = Field(1, ge=1, le=2)
    engine: Literal["pybullet", "mujoco", "mujoco_warp"] = "pybullet"
    integrator: Literal["discrete", "implicitfast"] = "discrete"
    contact_time_constant_s: float = Field(MujocoSettings.contact_time_constant_s, gt=0, le=1.0)
    impratio: float = Field(MujocoSettings.impratio, gt=0, le=1e4)
    noslip_iterations: int = Field(MujocoSettings.noslip_iterations, ge=0, le=1000)
    device: str = Field(MujocoWarpSettings.device, pattern=r"^(cpu|cuda|cuda:\d+)$")
    contacts_per_world: int = Field(MujocoWarpSettings.contacts_per_world, ge=1, le=100_000)
    constraints_per_world: int = Field(MujocoWarpSettings.constraints_per_world, ge=1, le=1_000_000)

    @field_validator("time_step_s")
    @classmethod
    def _a_stable_step(cls, value: float | None) -> float | None:
        """A step beyond any model's stability (1e9 s: every trial ends in error) is refused."""
        if value is not None and (why := step_problem(value)) is not None:
            raise ValueError(why)
        return value

    @model_validator(mode="after")
    def _options_of_the_engine(self) -> Simulation:
        """An option of the other engine, set to anything but its default, is refused by name."""
        own = option_names(self.engine)
        owners = {f: e for e in reversed(ENGINE_SETTINGS) for f in option_names(e) if f not in own}
        foreign = [f for f in self.model_fields_set if f in owners]
        unread = sorted(f for f in foreign if getattr(self, f) != type(self).model_fields[f].default)
        if unread:
            other = owners[unread[0]]
            raise ValueError(
                f"{', '.join(sorted(unread))}: engine {self.engine} does not read "
                f"{'it' if len(unread) == 1 else 'them'} ({'its' if len(unread) == 1 else 'their'} engine is "
                f"{other}); allowed: leave {'it' if len(unread) == 1 else 'them'} out, or engine: {other}"
            )
        return self

    @property
    def step_s(self) -> float:
        """The step: as given, else the engine's default (PyBullet 0.5 ms, MuJoCo 4 ms)."""
        if self.time_step_s is not None:
            return self.time_step_s
        return WorldSettings.time_step_s if self.engine == "pybullet" else MUJOCO_DEFAULT_STEP_S

    def world_settings(self) -> WorldSettings:
        """The :class:`~somo_sweep.sim.world.WorldSettings` these settings describe."""
        own = ENGINE_SETTINGS[self.engine]
        return WorldSettings(
            time_step_s=self.step_s,
            gravity_m_s2=self.gravity_m_s2,
            solver_iterations=self.solver_iterations,
            engine_settings=own(**{name: getattr(self, name) for name in option_names(self.engine)}),
        )


class Adaptive(Spec):
    """Settings of adaptive sampling (``sampling: adaptive`` or ``somo-sweep run --adaptive``).

    Attributes:
        labels: Labels whose changes are refined (``grasp`` or ``label_grasp``); default:
            every label the task gives. A trial's status is always followed too.
        coarse_step: Index steps between coarse cells along each refined axis (default: the
            largest power of two ≤ (values − 1) / 2 of each axis).
    """

    text_numbers: ClassVar[bool] = False

    labels: list[Annotated[str, Field(pattern=r"^[A-Za-z0-9_]+$")]] = Field(default_factory=list)
    coarse_step: int | None = Field(None, ge=1)


class Active(Spec):
    """Settings of active sampling (``sampling: active``; :mod:`somo_sweep.sweep.run.active`).

    Trials and robustness replicas go, batch after batch, where a model of the labels over the
    swept axes is unsure; the run stops when the estimated share of cells whose label is right
    reaches ``target_agreement``, and stores the cells it never simulated as inferred, each with
    its ``confidence``. Replicas (``robustness.replicas``) run one at a time and a label's stop at
    its first disagreement.

    Attributes:
        target_agreement: The estimated agreement at which the run stops (0 … 1].
        labels: Labels the model follows and the replicas check (default: every label).
        batch: Runs per batch (the open cells' next replicas, then new cells).
        initial: Cells of the first batch, drawn at random.
        exploration: Share of a batch's new cells drawn at random instead of the least sure.
        model: ``trees`` (extra trees, scikit-learn) or ``neighbours`` (the nearest simulated cells).
    """

    text_numbers: ClassVar[bool] = False

    target_agreement: float = Field(0.98, gt=0.0, le=1.0)
    labels: list[Annotated[str, Field(pattern=r"^[A-Za-z0-9_]+$")]] = Field(default_factory=list)
    batch: int = Field(20, ge=1, le=100_000)
    initial: int = Field(60, ge=1, le=1_000_000)
    exploration: float = Field(0.1, ge=0.0, le=1.0)
    model: Literal["trees", "neighbours"] = "trees"


class Robustness(Spec):
    """Robustness replicas (``robustness:`` or ``somo-sweep run --robust K``).

    Each chosen cell runs ``replicas`` more times, each time perturbed by the task
    (:attr:`~somo_sweep.tasks.registry.TaskSpec.perturb`: for ``pinch_grasp``, the object moved
    by up to ±0.5 mm in x and y and its friction scaled within ±5 %), the odd-numbered replicas at
    half the time step. A cell then has a majority label, the share of its runs that agree with
    it and a ``robust`` flag (every run agrees; :mod:`somo_sweep.sweep.run.robustness`).

    Attributes:
        replicas: Replicas per chosen cell (0: none).
        where: ``boundary`` (default): the cells whose label differs from a grid neighbour's, then
            the neighbours of any cell whose majority differs from its own trial, plus a seeded
            random audit of ``audit_fraction`` of the other simulated cells; ``all``: every
            simulated cell. With ``sampling: active``, ``boundary`` replicates the simulated cells
            whose class differs from a grid neighbour's, as the sampler goes.
        audit_fraction: Share of the non-boundary cells audited (at least one cell when > 0).
        labels: Labels that decide boundaries and robustness (default: every label).
    """

    text_numbers: ClassVar[bool] = False

    replicas: int = Field(0, ge=0, le=MAX_REPLICAS)
    where: Literal["boundary", "all"] = "boundary"
    audit_fraction: float = Field(0.1, ge=0.0, le=1.0)
    labels: list[Annotated[str, Field(pattern=r"^[A-Za-z0-9_]+$")]] = Field(default_factory=list)


class StudyFile(Spec):
    """The raw schema of a study file (see the module docstring)."""

    text_numbers: ClassVar[bool] = False

    name: str | None = Field(None, pattern=r"^[A-Za-z0-9_.-]+$", max_length=100)
    task: str
    model: str
    params: dict[str, Any] = Field(default_factory=dict)
    set: dict[str, Any] = Field(default_factory=dict)
    sweep: dict[str, Any] = Field(default_factory=dict)
    link: list[list[str]] = Field(default_factory=list)
    cells: Any = None
    repeats: int = Field(1, ge=1)
    seed: int = Field(0, ge=0)
    simulation: Simulation | None = None
    output: str | None = None
    sampling: Literal["grid", "adaptive", "active"] = "grid"
    adaptive: Adaptive = Adaptive()
    active: Active = Active()
    robustness: Robustness = Robustness()

    @model_validator(mode="after")
    def _no_audit_when_active(self) -> StudyFile:
        """``sampling: active`` draws its own random cells: an audit share would be ignored."""
        if self.sampling == "active" and "audit_fraction" in self.robustness.model_fields_set:
            raise ValueError(
                "robustness.audit_fraction: sampling: active audits no cell at random; its exploration "
                "share (active.exploration) draws new cells instead; allowed: leave audit_fraction out"
            )
        return self
