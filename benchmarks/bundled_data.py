"""Regenerate a bundled synthetic bench table (simulated, not measured).

The package ships two example tables in ``studies/tables/``, both made by simulation with a
known model: ``planar_finger_synthetic.csv`` (``synthetic``: no effect the plain model lacks) and
``planar_finger_bench_2.csv`` (``diagnosis-example``: one hidden effect for ``somo-sweep
diagnose`` to find). ``python -m benchmarks.bundled_data NAME [OUT]`` makes the table again from
its generator (:func:`somo_sweep.calibration.synthetic.example_csv`,
:func:`somo_sweep.diagnosis.example.example_csv`): printed, or written to OUT (a file, or a
folder that gets the bundled table's name). A file somo-sweep did not write is never replaced.
"""

from __future__ import annotations

import argparse

from benchmarks._cli import user_errors
from somo_sweep.cli.output import check_replaceable, file_target, write_atomic

__all__ = ["DATA_NAMES", "example_csv", "main"]

#: The bundled table each data set regenerates (its name in a folder given as OUT).
DATA_NAMES = {"synthetic": "planar_finger_synthetic.csv", "diagnosis-example": "planar_finger_bench_2.csv"}


def example_csv(which: str) -> str:
    """The CSV text of data set ``which`` (a key of :data:`DATA_NAMES`), made again."""
    if which == "synthetic":
        from somo_sweep.calibration.synthetic import example_csv as make
    else:
        from somo_sweep.diagnosis.example import example_csv as make
    return make()


def main(argv: list[str] | None = None) -> None:
    """Print the table, or write it to OUT."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.bundled_data",
        description="Regenerate a bundled synthetic bench table (simulated, not measured).",
    )
    ap.add_argument("which", choices=tuple(DATA_NAMES), help="the data set")
    ap.add_argument(
        "out",
        nargs="?",
        metavar="OUT",
        help="CSV file to write (default: print); a folder (out/, or one that exists) gets the bundled "
        "table's name in it",
    )
    args = ap.parse_args(argv)
    with user_errors():
        target = file_target(args.out, DATA_NAMES[args.which])
        if target is not None:
            check_replaceable(target)
        text = example_csv(args.which)
        if target is None:
            print(text, end="")
        else:
            print(f"wrote {write_atomic(target, text)}")


if __name__ == "__main__":
    main()
