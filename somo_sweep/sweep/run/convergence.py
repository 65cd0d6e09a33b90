"""Automatic numerics from convergence: the largest step whose labels hold at half of it.

A study without ``simulation:`` gets its time step (and the least inertia shaping that makes that
step stable, :func:`~somo_sweep.sim.numerics.numerics_for_step`) from its own trials, not from
a rule on modes. The candidates are :func:`~somo_sweep.sim.numerics.step_ladder`'s: the modal
starting guess (the lowest mode resolved), then halves of it, down to the step at which the model
needs no shaping at all. For each candidate h, a seeded sample of the study's own cells runs at h,
at h/2, and at h/2 perturbed by the task (its robustness perturbation,
:attr:`~somo_sweep.tasks.registry.TaskSpec.perturb`). A sample cell is *robust* when its h/2 run
and its perturbed h/2 run agree (status and every label); h is chosen when every run finished
``ok`` and every robust sample cell has the same outcome at h as at h/2. Otherwise the next, half
as large, is tried; its h runs are the last candidate's h/2 runs. A task without a perturbation
counts every sample cell as robust. If even the last candidate fails, it is taken anyway (the
model itself, no shaping) and the choice says so. A task whose trials give no labels has nothing
to converge: its step is the modal rule's (:func:`~somo_sweep.sim.numerics.choose_numerics`,
the lowest modes moved by at most 1 %), after one sample run at the guess shows it.

The choice is a pure function of the study and the code: the sample and every trial are seeded,
so a resumed run makes the same choice, and :func:`stored_choice` finds it in the results folder
instead of simulating the sample again. The study's job maker (its code version, its resolved
grid points) is built once and gives every candidate's jobs (:meth:`JobMaker.at_step
<somo_sweep.sweep.jobs.job.JobMaker.at_step>`); the folder's manifest is read once.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from somo_sweep.errors import ManifestError, SomoError, os_cause, shown
from somo_sweep.sweep.jobs.code import code_version
from somo_sweep.sweep.jobs.job import Job, JobMaker, replica_jobs
from somo_sweep.sweep.store.folder import MANIFEST, read_manifest
from somo_sweep.sweep.study.derive import with_auto_step
from somo_sweep.sweep.study.loaded import Study

__all__ = [
    "SAMPLE_CELLS",
    "Rung",
    "StepChoice",
    "StepEvents",
    "auto_step",
    "choose_step",
    "folder_choice",
    "ladder",
    "outcomes_of",
    "stored_choice",
    "with_stored_step",
]

#: Cells of a study sampled per candidate step (fewer if the study has fewer).
SAMPLE_CELLS = 8
#: Seed offset of the sample (the study's seed plus this), so it differs from the robustness audit.
_SAMPLE_SEED = 0x53544550

Outcome = tuple[str, dict[str, str]]
#: Runs jobs and yields (job id, status, labels) as they finish.
RunJobs = Callable[[list[Job]], Iterable[tuple[str, str, dict[str, str]]]]


@dataclass(frozen=True)
class Rung:
    """One candidate step and what its sample gave.

    Attributes:
        step_s: The candidate step, s.
        cells: Sample cells (trial numbers).
        robust: Sample cells whose half-step run and perturbed half-step run agree.
        agree: Of those, the cells whose outcome at the step equals the one at half of it.
        not_ok: Runs of this candidate that did not finish ``ok`` (blow-ups, errors).
        differing: Trial numbers of robust cells that differ between the step and half of it.
        passed: The step is converged on the sample.
    """

    step_s: float
    cells: list[int]
    robust: int
    agree: int
    not_ok: int
    differing: list[int]
    passed: bool

    def describe(self) -> str:
        """One line: the step, its verdict and why."""
        verdict = "converged" if self.passed else "not converged"
        differ = f"; differ: trials {', '.join(map(str, self.differing))}" if self.differing else ""
        failed = f"; {self.not_ok} run(s) not ok" if self.not_ok else ""
        return (
            f"{self.step_s * 1e3:g} ms: {verdict}: {self.agree} of {self.robust} robust sample cells "
            f"(of {len(self.cells)}) agree with {self.step_s * 5e2:g} ms{failed}{differ}"
        )


@dataclass(frozen=True)
class StepChoice:
    """The automatic step of a study and how it was reached.

    Attributes:
        step_s: The chosen step, s.
        guess_s: The modal starting guess, s, and ``guess_reason`` what set it.
        rungs: Every candidate tried, largest first.
        reason: Why the chosen step, in words.
        code_version: The trial code the sample ran (a stored choice of other code is not reused).
        sample: The sample cells (trial numbers).
    """

    step_s: float
    guess_s: float
    guess_reason: str
    rungs: list[Rung] = field(default_factory=list)
    reason: str = ""
    code_version: str = ""
    sample: list[int] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-able record (for the manifest)."""
        return asdict(self)

    def describe(self) -> list[str]:
        """Lines for people: the guess, each candidate, the choice."""
        return [
            f"starting guess {self.guess_s * 1e3:g} ms ({self.guess_reason})",
            *(f"  {r.describe()}" for r in self.rungs),
            f"chosen: {self.step_s * 1e3:g} ms ({self.reason})",
        ]


def _sample(study: Study, n: int) -> list[int]:
    rng = np.random.default_rng([study.seed, _SAMPLE_SEED])
    total = study.n_trials
    return sorted(int(t) for t in rng.choice(total, size=min(n, total), replace=False))


def ladder(maker: JobMaker) -> tuple[list[float], str]:
    """The candidate steps of a study without ``simulation:``, s, largest first, and what set the
    first (:func:`~somo_sweep.sim.numerics.step_ladder` of the first grid point's model of the
    study whose job maker is ``maker``)."""
    from somo_sweep.sim.numerics import step_ladder

    return step_ladder(maker.first_model())


def _rung(
    step_s: float, trials: list[int], full: list[Outcome], half: list[Outcome], shaken: list[Outcome] | None
) -> Rung:
    """A candidate's verdict from its sample's outcomes at the step, at half of it, and at half of it
    perturbed (None: the task has no perturbation, every sample cell counts as robust)."""
    c = shaken if shaken is not None else half
    robust = [i for i in range(len(trials)) if _key(half[i]) == _key(c[i])]
    differing = [trials[i] for i in robust if _key(full[i]) != _key(half[i])]
    not_ok = sum(o[0] != "ok" for o in (*full, *half, *(shaken or ())))
    passed = not_ok == 0 and bool(robust) and not differing
    return Rung(step_s, trials, len(robust), len(robust) - len(differing), not_ok, differing, passed)


def _key(outcome: Outcome) -> str:
    status, labels = outcome
    return status if status != "ok" else json.dumps(sorted(labels.items()))


def choose_step(
    study: Study,
    maker: JobMaker,
    run_jobs: RunJobs,
    sample_cells: int = SAMPLE_CELLS,
    on_rung: Callable[[float, int], None] | None = None,
) -> StepChoice:
    """Choose the step of a study without ``simulation:`` by label convergence (module docstring).

    Args:
        study: The study.
        maker: Its job maker (:meth:`Study.trial_plan <somo_sweep.sweep.study.loaded.Study.trial_plan>`).
        run_jobs: Runs a list of jobs and yields (job id, status, labels) as each finishes.
        sample_cells: Cells sampled.
        on_rung: Called with (candidate step, runs to do) before each candidate's runs.
    """
    from somo_sweep.sim.numerics import step_ladder

    trials, perturb = _sample(study, sample_cells), study.task.perturb
    code, model = maker.code, maker.first_model()
    steps, why = step_ladder(model)
    done: dict[str, Outcome] = {}

    def outcomes(jobs: list[Job]) -> list[Outcome]:
        todo = [j for j in jobs if j.job_id not in done]
        for job_id, status, labels in run_jobs(todo) if todo else ():
            done[job_id] = (status, dict(labels))
        return [done[j.job_id] for j in jobs]

    rungs: list[Rung] = []
    labelled = False
    for step in steps:
        at_step, at_half = maker.at_step(step), maker.at_step(step / 2)
        full, half = [at_step.job(t) for t in trials], [at_half.job(t) for t in trials]
        shaken = [replica_jobs(j, 2, perturb)[1] for j in half] if perturb is not None else []
        if on_rung:
            wanted = [j for j in full + half + shaken if j.job_id not in done]
            on_rung(step, len(wanted))
        a = outcomes(full)
        labelled = labelled or any(labels for status, labels in a if status == "ok")
        if not labelled:
            break
        rung = _rung(step, trials, a, outcomes(half), outcomes(shaken) if shaken else None)
        rungs.append(rung)
        if rung.passed:
            reason = f"the largest candidate whose robust sample labels equal those at {step * 5e2:g} ms"
            return StepChoice(step, steps[0], why, rungs, reason, code, trials)
    if not labelled:
        # Nothing to converge: the modal rule (lowest modes moved by at most 1 %) decides.
        from somo_sweep.sim.numerics import choose_numerics

        modal = choose_numerics(model)
        reason = f"the task gives no labels to converge; the modal rule: {modal.reason}"
        return StepChoice(modal.time_step_s, steps[0], why, rungs, reason, code, trials)
    last = steps[-1]
    reason = (
        "no candidate converged on the sample; the smallest, at which the model needs no shaping, is "
        "taken: its labels there are the model's own"
    )
    return StepChoice(last, steps[0], why, rungs, reason, code, trials)


def stored_choice(manifest: dict[str, Any], study: Study, code: str) -> StepChoice | None:
    """The choice recorded in a results folder's manifest for this study, or None.

    Taken only when it was made by the same trial code (``code``, the study's code version:
    :attr:`JobMaker.code <somo_sweep.sweep.jobs.job.JobMaker.code>`) on the same sample of cells (a
    changed study is refused by the results folder anyway: its trials have other ids).
    """
    try:
        record = manifest["study"]["simulation"]["convergence"]
        rungs = [Rung(**r) for r in record["rungs"]]
        choice = StepChoice(
            float(record["step_s"]),
            float(record["guess_s"]),
            str(record["guess_reason"]),
            rungs,
            str(record["reason"]),
            str(record["code_version"]),
            [int(t) for t in record["sample"]],
        )
    except (KeyError, TypeError, ValueError):
        return None
    if choice.code_version != code:
        return None
    if not choice.sample or choice.sample != _sample(study, len(choice.sample)):
        return None
    return choice if math.isfinite(choice.step_s) and choice.step_s > 0 else None


def with_stored_step(study: Study, manifest: dict[str, Any] | None = None) -> Study:
    """``study`` with the step its results folder recorded, if it has no ``simulation:`` and the
    folder holds a choice for it (else unchanged: its jobs then show the modal starting guess).

    Args:
        study: The study.
        manifest: Its results folder's manifest, if read already (else it is read here).
    """
    if study.simulation is not None or study.auto_step_s is not None:
        return study
    code = code_version(study.task.run_path.partition(":")[0])
    try:
        choice = stored_choice(manifest if manifest is not None else read_manifest(study.output), study, code)
    except (SomoError, OSError):
        return study
    if choice is None:
        return study
    return with_auto_step(study, choice.step_s, choice.as_dict())


@dataclass(frozen=True)
class StepEvents:
    """What :func:`auto_step` reports as it goes (each optional), for a caller to show.

    Attributes:
        reused: Called with the choice the results folder recorded, when it is taken.
        choosing: Called before the sample runs start (no choice recorded).
        rung: Called with (candidate step in s, runs to do) before each candidate's runs.
        chosen: Called with the choice made.
    """

    reused: Callable[[StepChoice], None] | None = None
    choosing: Callable[[], None] | None = None
    rung: Callable[[float, int], None] | None = None
    chosen: Callable[[StepChoice], None] | None = None


def folder_choice(study: Study, code: str) -> StepChoice | None:
    """The choice the study's results folder recorded for it (:func:`stored_choice`; ``code``: the
    study's code version), or None.

    A damaged manifest holds none (the run rebuilds it, and the step is chosen again).

    Raises:
        SomoError: The results folder's name is one no folder can have (said before any sample
            trial runs; nothing is written).
    """
    try:
        stored = (study.output / MANIFEST).is_file()
    except OSError as exc:
        cause, advice = os_cause(exc)
        raise SomoError(
            f"cannot create the results folder {shown(str(study.output), 200)}: {cause}; nothing was "
            f"written: {advice}, then run the same command again"
        ) from None
    if not stored:
        return None
    try:
        return stored_choice(read_manifest(study.output), study, code)
    except ManifestError:
        return None


def auto_step(
    study: Study, maker: JobMaker, run_jobs: RunJobs, events: StepEvents | None = None
) -> StepChoice:
    """The step of ``study`` (without ``simulation:``): the one its results folder recorded, else
    chosen now by label convergence on a sample of its cells (:func:`choose_step`).

    This is the one place a run's automatic step is chosen.

    Args:
        study: The study.
        maker: Its job maker (its code version, its grid points).
        run_jobs: Runs a list of jobs and yields (job id, status, labels) as each finishes.
        events: What to tell the caller as it goes.

    Raises:
        SomoError: The results folder's name is one no folder can have.
    """
    events = events or StepEvents()
    choice = folder_choice(study, maker.code)
    if choice is not None:
        if events.reused:
            events.reused(choice)
        return choice
    if events.choosing:
        events.choosing()
    choice = choose_step(study, maker, run_jobs, on_rung=events.rung)
    if events.chosen:
        events.chosen(choice)
    return choice


def outcomes_of(results: Iterator[Any]) -> Iterator[tuple[str, str, dict[str, str]]]:
    """(job id, status, labels) of the engine's outcomes; a run that blew up and was rerun by the
    engine at half its step counts as ``unstable`` here: its own step did not hold."""
    for out in results:
        status = "unstable" if out.retried_half_step else out.status
        yield out.job_id, status, dict(out.labels)
