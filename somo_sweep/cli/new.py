"""``somo-sweep new …``: starter folders to copy from (``new grasp-study DIR``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from somo_sweep.cli.output import fail, write_checked
from somo_sweep.errors import DescriptionError, SomoError

__all__ = ["app"]

app = typer.Typer(no_args_is_help=True, help="Write a starter folder: a grasp study of your own gripper.")


@app.command("grasp-study")
def grasp_study(
    folder: Annotated[Path, typer.Argument(help="Folder to write the starter into (made if missing).")],
    finger: Annotated[
        Path | None,
        typer.Option(help="Your finger's model file (as designed or calibrated); default: a 12-link finger."),
    ] = None,
) -> None:
    """Write finger.yaml, gripper.yaml, bench.csv and study.yaml: a grasp study that runs as written.

    Then: fill bench.csv with your measurements, `somo-sweep calibrate FOLDER/bench.csv --model
    FOLDER/finger.yaml -o FOLDER/finger.yaml`, `somo-sweep run FOLDER/study.yaml`. Existing files
    are never replaced: nothing is written if any of the four is there.
    """
    from somo_sweep.tasks.pinch_grasp.starter import STARTER_FILES, grasp_study_files

    try:
        files = grasp_study_files(finger)
        there = [name for name in STARTER_FILES if (folder / name).exists() or (folder / name).is_symlink()]
        if there:
            raise SomoError(
                f"{folder} already holds {', '.join(there)}; nothing was written: give a new or empty "
                "folder, or move those files away first"
            )
        if folder.exists() and not folder.is_dir():
            raise SomoError(f"{folder} is a file, not a folder; nothing was written: give a folder")
        written = write_checked([(folder / name, files[name]) for name in STARTER_FILES])
    except (SomoError, DescriptionError) as exc:
        fail(exc)
    except OSError as exc:
        fail(SomoError(f"cannot write the starter into {folder}: {exc.strerror or exc}"), 1)
    for path in written:
        typer.echo(f"wrote {path}")
    typer.echo(f"next: somo-sweep run {folder / 'study.yaml'}   (then somo-sweep plot on its results folder)")
