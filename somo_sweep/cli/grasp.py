"""Pinch-grasp commands: ``classify`` a finished sweep, ``render`` a trial (Fig. 6 is ``paper fig6``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from somo_sweep.cli.output import fail, record_in_results, say_notes, write_artifacts, write_outputs
from somo_sweep.errors import SomoError, printable, shown

__all__ = ["classify", "render"]


def _read(results: Path) -> object:
    """The results table of a study folder (the sweep engine's Parquet dataset)."""
    from somo_sweep.paper.grasp_trials import read_results

    return read_results(results)


def classify(
    results: Annotated[Path, typer.Argument(help="Results folder of a pinch_grasp study (results/<study>).")],
    rule: Annotated[str, typer.Option(help="contacts (hold-phase contacts, default) or paper.")] = "contacts",
    max_proximal_fraction: Annotated[
        float | None, typer.Option(help="contacts rule: largest proximal share of force for a pinch.")
    ] = None,
) -> None:
    """Relabel a finished sweep from its stored metrics (no re-run); writes grasp_labels_RULE.csv."""
    from somo_sweep.paper.grasp_trials import relabel

    options = {} if max_proximal_fraction is None else {"max_proximal_fraction": max_proximal_fraction}
    try:
        counts, table = relabel(results, rule, **options)
        (path,) = write_outputs([(results / f"grasp_labels_{rule}.csv", table.to_csv(index=False))])
    except SomoError as exc:
        fail(exc)
    record_in_results([path])
    for label, n in counts.items():
        typer.echo(f"{printable(shown(str(label), 200)):>10s}  {n}")  # a status is stored text
    if "robust" in table.columns:
        checked = table[table["replicas"] > 0]
        shaky = int(checked["robust"].eq(False).fillna(False).astype(bool).sum())
        sure = int(checked["robust"].eq(True).fillna(False).astype(bool).sum())
        awaiting = int((table["replicas_awaited"] > 0).sum())
        waits = f", {awaiting} await replicas (not counted as robust or not yet)" if awaiting else ""
        typer.echo(
            f"robustness: {len(checked)} cell(s) with replicas, {sure} robust under rule {rule}, "
            f"{shaky} not{waits} (counts above are majorities; per cell: grasp_{rule}_majority, "
            f"grasp_{rule}_agreement, replicas_awaited, robust)"
        )
    if table.attrs.get("replicas_unfinished"):
        typer.echo(f"note: {table.attrs['replicas_unfinished']}")
    if table.attrs.get("trials_missing"):
        typer.echo(f"note: {table.attrs['trials_missing']}")
    legacy = table.attrs.get("rows_without_final_counts", 0)
    if legacy:
        typer.echo(
            f"note: {legacy} trials were stored before the final step's per-part contact counts "
            "(final_contact_count_base ...): they are relabelled from their stored mean link where it "
            "decides the label, 'unknown' where it does not; re-run them (somo-sweep run) for exact labels"
        )
    typer.echo(f"labels written to {path}")


def render(
    study: Annotated[Path, typer.Argument(help="Study file of a pinch_grasp sweep.")],
    trial: Annotated[str, typer.Option(help="Trial: its job id, or its 0-based index in the study's grid.")],
    at_s: Annotated[str, typer.Option(help="Comma-separated snapshot times, s.")] = "4.0",
    out: Annotated[Path, typer.Option(help="Folder for the PNG files.")] = Path("results/renders"),
    engine: Annotated[
        str | None,
        typer.Option(
            help="Run the trial on pybullet or mujoco (with its own numerics); default: the study's."
        ),
    ] = None,
    results: Annotated[
        Path | None,
        typer.Option(
            help="Results folder the sweep ran into (its --out), for the step it chose; default: the study's."
        ),
    ] = None,
) -> None:
    """Render finger-shape snapshots of one trial headless as PNG files (PyBullet: TinyRenderer;
    MuJoCo: its renderer on EGL or OSMesa). The trial runs as its sweep ran it (a blow-up is rerun
    at half the step). Exits 1 when the trial blew up or failed before any snapshot, 2 when it
    ended early before every time asked (nothing is written then)."""
    from somo_sweep.paper.grasp_render import render_trial

    try:
        times = [float(v) for v in at_s.split(",") if v.strip()]
    except ValueError:
        fail(SomoError(f"--at-s must be comma-separated numbers, got '{at_s}'"))
    if out.exists() and not out.is_dir():  # before the trial is simulated
        fail(SomoError(f"--out {out} is a file, not a folder"))
    try:
        rendered = render_trial(study, trial, times, engine, say_notes, results)
        if not rendered.images.images:
            code = 2 if rendered.status == "ok" else 1  # times past an early end; a failed simulation
            fail(SomoError(f"trial {trial}: {rendered.label}; no image written"), code)
        paths = write_artifacts(rendered.images, out)
    except SomoError as exc:
        fail(exc)
    typer.echo(f"trial {trial}: {rendered.label}")
    for path in paths:
        typer.echo(f"wrote {path}")
