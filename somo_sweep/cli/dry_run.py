"""What ``somo-sweep run --dry-run`` prints: the study's trials, how the run samples and steps
them, the first rows of its job table, then the runs and (optionally) their time; nothing is
written."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

if TYPE_CHECKING:  # the heavy modules are imported when a dry run prints
    from somo_sweep.sweep.run.estimate import DryRun

__all__ = ["DRY_ROWS", "print_dry_run"]

#: Rows a dry run prints.
DRY_ROWS = 10


def print_dry_run(plan: DryRun, workers: int, estimate: bool = True) -> None:
    """Count, then the first rows (the other jobs are not built); then the runs and (with
    ``estimate``) their time, from one trial timed."""
    from somo_sweep.sweep.jobs.table import jobs_frame

    st = plan.study
    typer.echo(
        f"{st.name}: task {st.task.name}, {st.n_trials} trials "
        f"({st.n_points} grid points x {st.repeats} repeat(s)), output {st.output}"
    )
    if st.robustness.replicas and st.sampling != "active":  # an active plan says where its replicas go
        spec = st.robustness
        chosen = (
            "every simulated cell"
            if spec.where == "all"
            else (f"the cells on a label boundary, and an audit of {spec.audit_fraction:.0%} of the others")
        )
        typer.echo(f"robustness: {spec.replicas} replicas of {chosen}")
    if plan.sampling is not None:
        typer.echo(plan.sampling)
    if plan.steps is not None:
        steps, why = plan.steps
        typer.echo(
            "automatic numerics (no simulation: block): the run chooses the step by label convergence "
            f"on a sample of these cells, trying {', '.join(f'{h * 1e3:g}' for h in steps)} ms (starting "
            f"guess set by {why}); the jobs below show the starting (modal) choice:"
        )
        shown: set[str] = set()
        for job in plan.jobs:
            if job.numerics is not None and job.columns["model_hash"] not in shown:
                shown.add(job.columns["model_hash"])
                typer.echo(f"  model {job.columns['model_file']}:")
                for line in job.numerics.describe():
                    typer.echo(f"    {line}")
    else:
        sim = st.simulation
        assert sim is not None
        given = "from the study file" if sim.time_step_s is not None else f"the {sim.engine} default"
        typer.echo(f"simulation: engine {sim.engine}, time step {sim.step_s * 1e3:g} ms ({given})")
    typer.echo(jobs_frame(plan.jobs).to_string(index=False))
    if st.n_trials > DRY_ROWS:
        typer.echo(f"... {st.n_trials - DRY_ROWS} more")
    if estimate:
        typer.echo("timing trial 0 of the study (no result is written) ...", err=True)
    for line in plan.estimate(workers, estimate).lines():
        typer.echo(line)
