"""Pinch-grasp commands: ``classify`` a finished sweep, draw ``fig6``, ``render`` a trial."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from somo_sweep.cli import app, fail
from somo_sweep.errors import SomoError

__all__ = ["classify", "fig6", "render"]


def _read(results: Path) -> object:
    """The results table of a study folder (the sweep engine's Parquet dataset)."""
    from somo_sweep.grasp_results import read_results

    return read_results(results)


@app.command()
def classify(
    results: Annotated[Path, typer.Argument(help="Results folder of a pinch_grasp study (results/<study>).")],
    rule: Annotated[str, typer.Option(help="contacts (hold-phase contacts, default) or paper.")] = "contacts",
    max_proximal_fraction: Annotated[
        float | None, typer.Option(help="contacts rule: largest proximal share of force for a pinch.")
    ] = None,
) -> None:
    """Relabel a finished sweep from its stored metrics (no re-run); writes grasp_labels_<rule>.csv."""
    from somo_sweep.grasp_results import relabel

    options = {} if max_proximal_fraction is None else {"max_proximal_fraction": max_proximal_fraction}
    try:
        counts, path = relabel(results, rule, **options)
    except SomoError as exc:
        fail(exc)
    for label, n in counts.items():
        typer.echo(f"{label:>10s}  {n}")
    typer.echo(f"labels written to {path}")


@app.command()
def fig6(
    results: Annotated[Path, typer.Argument(help="Results folder of a pinch_grasp study.")],
    rule: Annotated[str, typer.Option(help="Grasp rule: contacts or paper.")] = "contacts",
    max_dsr: Annotated[float, typer.Option(help="Largest DSR drawn.")] = 0.5,
    out: Annotated[Path | None, typer.Option(help="Output folder (default: the results folder).")] = None,
) -> None:
    """Draw paper Fig. 6 (PNG + SVG), its summary table, and print the smallest all-width pinch DSR."""
    from somo_sweep.fig6 import grasp_table, write_fig6
    from somo_sweep.grasp_results import read_results

    try:
        table = grasp_table(read_results(results), rule)
        info = write_fig6(table, out or results, stem=f"fig6_{rule}", max_dsr=max_dsr)
        if out is not None and out.resolve() != results.resolve():
            # The headline is stored with the results too, wherever the figure goes.
            (results / f"fig6_{rule}.json").write_text(json.dumps(info, indent=2) + "\n")
    except SomoError as exc:
        fail(exc)
    best = info["smallest_all_width_pinch_dsr"]
    typer.echo(f"{info['trials']} trials, labels ({rule} rule): {info['labels']}")
    typer.echo(
        "no DSR pinch-grasps every width" if best is None else f"smallest all-width pinch DSR: {best:.2f}"
    )
    for path in info["files"]:
        typer.echo(f"wrote {path}")


@app.command()
def render(
    study: Annotated[Path, typer.Argument(help="Study file of a pinch_grasp sweep.")],
    trial: Annotated[str, typer.Option(help="Trial: its job id, or its 0-based index in the study's grid.")],
    at_s: Annotated[str, typer.Option(help="Comma-separated snapshot times, s.")] = "4.0",
    out: Annotated[Path, typer.Option(help="Folder for the PNG files.")] = Path("results/renders"),
) -> None:
    """Render finger-shape snapshots of one trial headless (TinyRenderer) as PNG files."""
    from somo_sweep.grasp_results import render_trial

    try:
        times = [float(v) for v in at_s.split(",") if v.strip()]
    except ValueError:
        fail(SomoError(f"--at-s must be comma-separated numbers, got '{at_s}'"))
    try:
        paths, label = render_trial(study, trial, times, out)
    except SomoError as exc:
        fail(exc)
    typer.echo(f"trial {trial}: {label}")
    for path in paths:
        typer.echo(f"wrote {path}")
