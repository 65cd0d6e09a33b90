"""``somo-sweep tasks``: the registered tasks a study may name, or one task's parameters (defaults
and meanings) and metric columns."""

from __future__ import annotations

from typing import Annotated

import typer

from somo_sweep.cli.output import fail
from somo_sweep.errors import SomoError

__all__ = ["tasks"]


def tasks(
    name: Annotated[
        str | None, typer.Argument(help="A task: list its parameters (defaults, meanings) and metrics.")
    ] = None,
    show_all: Annotated[bool, typer.Option("--all", help="Also list the engine's selftest tasks.")] = False,
) -> None:
    """List the registered tasks (study files name them in task:), or one task's parameters."""
    from somo_sweep.tasks import all_tasks

    if name is not None:
        _describe_task(name)
        return
    for name, spec in all_tasks().items():
        if "selftest" in spec.tags and not show_all:
            continue
        tags = f" [{', '.join(spec.tags)}]" if spec.tags else ""
        typer.echo(f"{name}{tags}: {spec.description}")


def _describe_task(name: str) -> None:
    """Print one task's parameters (``task.<key> = default``, then the meaning) and metric columns."""
    import textwrap

    from somo_sweep.errors import did_you_mean
    from somo_sweep.tasks import all_tasks
    from somo_sweep.tasks.describe import parameters

    known = all_tasks()
    if name not in known:
        fail(
            SomoError(f"unknown task '{name}'{did_you_mean(name, list(known))}; allowed: {', '.join(known)}")
        )
    spec = known[name]
    typer.echo("\n".join(textwrap.wrap(f"{name}: {spec.description}", 80)))
    typer.echo("parameters (task.<key>: default; set them in params: or sweep them):")
    section = ""
    for p in parameters(spec):
        if p.section != section:
            section = p.section
            typer.echo("\n" + "\n".join(textwrap.wrap(f"task.{section.replace('``', '')}", 80)))
        typer.echo(f"  {p.key}: {p.default}")
        for line in textwrap.wrap(p.meaning.replace("``", ""), 74):
            typer.echo(f"      {line}")
    if spec.metrics:
        typer.echo("metrics (one column each; docs/outputs.md says what each means):")
        for line in textwrap.wrap(", ".join([*spec.metrics, *spec.numbered_metrics]), 76):
            typer.echo(f"  {line}")
