"""``somo-sweep answer``: a design question on a results folder's robust map
(:mod:`somo_sweep.sweep.views.answers`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from somo_sweep.cli.output import fail, file_target, record_in_results, write_outputs
from somo_sweep.errors import SomoError

__all__ = ["answer"]

_AXES = Annotated[list[str] | None, typer.Option(metavar="AXIS")]


def answer(
    results: Annotated[Path, typer.Argument(help="Results folder, e.g. results/<study>.")],
    smallest: Annotated[
        str | None, typer.Option(metavar="AXIS", help="The axis whose smallest value is asked for.")
    ] = None,
    largest: Annotated[
        str | None, typer.Option(metavar="AXIS", help="The axis whose largest value is asked for.")
    ] = None,
    every: Annotated[
        list[str] | None,
        typer.Option(metavar="AXIS", help="An object axis: the label must hold at each of its values."),
    ] = None,
    some: Annotated[
        list[str] | None,
        typer.Option(metavar="AXIS", help="An axis you may choose: the label must hold at some value of it."),
    ] = None,
    label: Annotated[
        str, typer.Option(help="The label asked for: NAME=VALUE (grasp=pinch) or a value alone.")
    ] = "pinch",
    csv: Annotated[
        str | None,
        typer.Option(
            metavar="<path>", help="Also write the answers as CSV here (a folder gets answers.csv)."
        ),
    ] = None,
) -> None:
    """For each value of the other swept axes: the smallest (or largest) value of one axis at which
    a label holds robustly at every object.

    Counts a cell only when its robustness replicas agree (or, unreplicated, when every neighbour
    has its label); says when the answer is provisional (cells awaiting replicas, trials missing).
    """
    from somo_sweep.cli.results import damaged
    from somo_sweep.sweep.views.answers import ask
    from somo_sweep.sweep.views.questions import question_for
    from somo_sweep.sweep.views.results import open_results

    if (smallest is None) == (largest is None):
        fail(SomoError("give one of --smallest AXIS or --largest AXIS"))
    target = file_target(csv, "answers.csv")
    try:
        opened = open_results(results, damaged)
        if opened.trials.empty:
            raise SomoError(f"{results}: no finished trials yet; nothing to answer from")
        axis = smallest if smallest is not None else largest
        assert axis is not None
        question = question_for(opened.trials, axis, every or [], some or [], label, largest is not None)
        result = ask(opened, question)
        if target is not None:
            (path,) = write_outputs([(target, result.table.to_csv(index=False))], inputs=[results])
            record_in_results([path])
    except SomoError as exc:
        fail(exc)
    for line in result.lines():
        typer.echo(line)
    if target is not None:
        typer.echo(f"wrote {path}")
