"""``somo-sweep new …``: starter folders to copy from (``new grasp-study DIR``)."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from somo_sweep.cli.output import check_replaceable, fail, write_checked
from somo_sweep.errors import DescriptionError, SomoError

if TYPE_CHECKING:
    from somo_sweep.model.load import Model

__all__ = ["app"]

app = typer.Typer(no_args_is_help=True, help="Write a starter folder: a grasp study of your own gripper.")


@app.command("grasp-study")
def grasp_study(
    folder: Annotated[Path, typer.Argument(help="Folder to write the starter into (made if missing).")],
    finger: Annotated[
        Path | None,
        typer.Option(
            help="Your finger's model file (as designed or calibrated; a bundled model's name works "
            "too); default: a 12-link, 70-mm finger."
        ),
    ] = None,
    fingers: Annotated[
        int,
        typer.Option(
            help="Fingers of the gripper, 2 to 8: two as in the paper's gripper, three or more evenly "
            "around the palm's axis (docs/tasks.md, 'Your own gripper')."
        ),
    ] = 2,
) -> None:
    """Write finger.yaml, gripper.yaml, bench.csv, study.yaml and design.yaml: a grasp study and a
    design study that run as written.

    Then: fill bench.csv with your measurements, `somo-sweep calibrate FOLDER/bench.csv --model
    FOLDER/finger.yaml -o FOLDER/finger.yaml` (calibrates the finger in place), `somo-sweep run
    FOLDER/study.yaml` (its grasp map), `somo-sweep design FOLDER/design.yaml` (which finger to
    build). Existing files are never replaced: nothing is written if any of them is there; a
    finger the study's checks would refuse is refused here, with `run`'s words.
    """
    from somo_sweep.sim.mujoco.support import unsupported  # the starter's engine; no MuJoCo import
    from somo_sweep.tasks.pinch_grasp.starter import STARTER_FILES, grasp_study_files

    def mujoco_needs(model: Model) -> list[str]:
        return [f"{path}: {why}" for path, why in unsupported(model)]

    try:
        files = grasp_study_files(finger, fingers, mujoco_needs)
        _check_folder(folder, STARTER_FILES)
    except (SomoError, DescriptionError) as exc:
        fail(exc)
    except OSError as exc:  # a path no file can have (a name too long, a loop of links)
        fail(SomoError(f"cannot write the starter into {folder}: {exc.strerror or exc}; nothing was written"))
    try:
        written = write_checked([(folder / name, files[name]) for name in STARTER_FILES])
    except SomoError as exc:  # the disk failed us (full, gone): exit 1, what was written is named
        fail(exc)
    for path in written:
        typer.echo(f"wrote {path}")
    study, design = (shlex.quote(str(folder / name)) for name in ("study.yaml", "design.yaml"))
    typer.echo(f"next: somo-sweep run {study}   (then somo-sweep plot on its results folder)")
    typer.echo(f"  or: somo-sweep design {design}   (which distal segment ratio and stiffness to build)")


def _check_folder(folder: Path, names: tuple[str, ...]) -> None:
    """Refuse a folder that is a file (or under one), holds any of the starter's files, or is read-only.

    Raises:
        SomoError: Naming what is in the way; nothing is written.
    """
    for parent in [folder, *folder.parents]:
        if parent.exists() and not parent.is_dir():
            raise SomoError(f"{parent} is a file, not a folder; nothing was written: give a folder")
    there = [name for name in names if (folder / name).exists() or (folder / name).is_symlink()]
    if there:
        raise SomoError(
            f"{folder} already holds {', '.join(there)}; nothing was written: give a new or empty "
            "folder, or move those files away first"
        )
    for name in names:  # a folder we may not write in (read-only), found before any file is written
        check_replaceable(folder / name)
