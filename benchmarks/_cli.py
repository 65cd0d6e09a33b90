"""What the benchmarks' command lines share: checked options, and a user error as one line.

Each benchmark is ``python -m benchmarks.NAME [options]`` from the repository root, its options
parsed by :mod:`argparse`. A bad option exits 2 with argparse's usage line; a
:class:`~somo_sweep.errors.SomoError` raised while the benchmark runs (a bad study, an output
folder that is a file) is printed as ``error: …`` on stderr and exits 2 too.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from somo_sweep.cli.output import checked_jobs, write_artifacts
from somo_sweep.errors import SomoError, StorageError
from somo_sweep.paper.artifacts import Artifacts

__all__ = ["echo", "finish", "int_in", "jobs_option", "user_errors"]


def int_in(low: int, high: int | None = None) -> Callable[[str], int]:
    """An argparse ``type``: a whole number from ``low`` to ``high`` (None: no upper bound)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number, got '{text}'") from None
        if value < low or (high is not None and value > high):
            allowed = f"from {low} to {high}" if high is not None else f">= {low}"
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {value}")
        return value

    return parse


def jobs_option(allow_default: bool = False) -> Callable[[str], int]:
    """An argparse ``type`` for ``--jobs``: the package's own check (at most a few per CPU)."""

    def parse(text: str) -> int:
        try:
            return checked_jobs(int(text), allow_default)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number, got '{text}'") from None
        except SomoError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix("--jobs ")) from None

    return parse


@contextmanager
def user_errors() -> Iterator[None]:
    """A :class:`SomoError` inside becomes ``error: …`` on stderr and exit code 2 (1 for a failed
    write), as the package's own commands do."""
    try:
        yield
    except SomoError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(1 if isinstance(exc, StorageError) else 2) from None


def echo(lines: Iterable[str]) -> None:
    """Print lines as they come (a benchmark's lines arrive over minutes)."""
    for line in lines:
        print(line, flush=True)


def finish(artifacts: Artifacts, out: Path) -> None:
    """Print the artifacts' lines, write their files into ``out`` and name each file written."""
    if out.exists() and not out.is_dir():
        raise SomoError(f"--out {out} is a file, not a folder")
    echo(artifacts.lines)
    echo(f"wrote {path}" for path in write_artifacts(artifacts, out))
