"""How often a run goes back to a module it has left: the sweep's data path, module by module.

``python -m benchmarks.room_returns [--trials N] [--all] [--json PATH]`` runs ``somo-sweep run``
(with its summary plots) on a small study of the engine's selftest task, in this process, and
records every call into a module of the sweep (``sweep/`` and ``cli/``; ``--all``: every
``somo_sweep`` module, the study's loading and a trial's own modules too). Calls into one module
one after the other are one *stay* there; a stay in a module entered before is a *return*. It
prints the modules entered, the stays, the returns, and each module's returns, most first. What
is measured is the sweep's own path (study, jobs, results folder, rows, plots): how often the
data goes back to a module it has left. The same command on two versions of the package
compares their paths (run it from outside the repository with ``PYTHONPATH`` set to a copy of
the other version).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import sys
import tempfile
import textwrap
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any

from benchmarks._cli import echo, int_in, user_errors

__all__ = ["Trip", "main", "traced_run"]


@dataclass
class Trip:
    """The modules a traced run entered, in order, one entry per stay.

    Attributes:
        stays: Each stay's module (its path inside the package).
    """

    stays: list[str] = field(default_factory=list)

    def enter(self, module: str) -> None:
        """A call into ``module``: a new stay unless the last one was there."""
        if not self.stays or self.stays[-1] != module:
            self.stays.append(module)

    @property
    def rooms(self) -> int:
        """Modules entered."""
        return len(set(self.stays))

    @property
    def returns(self) -> int:
        """Stays in a module entered before."""
        return len(self.stays) - self.rooms

    def by_module(self) -> list[tuple[str, int]]:
        """Each module's returns (its stays less one), most first, those with none left out."""
        counts = Counter(self.stays)
        return sorted(((m, n - 1) for m, n in counts.items() if n > 1), key=lambda mn: (-mn[1], mn[0]))

    def as_dict(self) -> dict[str, Any]:
        """The trip as a JSON-able record."""
        return {
            "rooms": self.rooms,
            "stays": len(self.stays),
            "returns": self.returns,
            "returns_by_module": dict(self.by_module()),
        }


#: The sweep's own modules, by their path inside the package.
SWEEP = ("sweep/", "cli/")


@contextlib.contextmanager
def _traced(trip: Trip, every: bool) -> Iterator[None]:
    """Record every call into a module of the sweep (``every``: any ``somo_sweep`` module) made by
    this thread into ``trip``."""
    import somo_sweep

    package = Path(somo_sweep.__file__).resolve().parent
    root = f"{package}/"

    def profile(frame: FrameType, event: str, arg: object) -> None:
        if event == "call":
            name = frame.f_code.co_filename
            if name.startswith(root):
                module = name.removeprefix(root)
                if every or module.startswith(SWEEP):
                    trip.enter(module)

    sys.setprofile(profile)
    try:
        yield
    finally:
        sys.setprofile(None)


def _study(folder: Path, trials: int) -> Path:
    """A study of ``trials`` trials of the selftest task in ``folder``, its model beside it."""
    from somo_sweep.model.tables import bundled_path

    shutil.copytree(bundled_path("models"), folder / "models")
    path = folder / "study.yaml"
    path.write_text(
        textwrap.dedent(
            f"""\
            name: st
            task: selftest_sleep
            model: models/ihm_finger.yaml
            params: {{sleep_s: 0.0}}
            sweep:
              task.x: {{start: 1, stop: {trials}, step: 1}}
            simulation: {{time_step_s: 1.0e-3}}
            """
        )
    )
    return path


def traced_run(trials: int, every: bool = False) -> Trip:
    """The trip of ``somo-sweep run STUDY --jobs 1`` (plots drawn) on a selftest study of ``trials``
    trials, in a folder of its own that is removed after (``every``: through every module)."""
    from typer.main import get_command

    from somo_sweep.cli.app import app

    command = get_command(app)
    trip = Trip()
    with tempfile.TemporaryDirectory() as tmp:
        study = _study(Path(tmp), trials)
        args = ["run", str(study), "--out", f"{tmp}/out", "--jobs", "1"]
        said = io.StringIO()
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said), _traced(trip, every):
            try:
                command.main(args, prog_name="somo-sweep", standalone_mode=False)
            except SystemExit as exc:  # the command's own exit (0: done)
                if exc.code:
                    raise RuntimeError(f"the run exited {exc.code}: {said.getvalue()[-500:]}") from None
    return trip


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring)."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.room_returns", description=__doc__)
    parser.add_argument("--trials", type=int_in(1, 1000), default=8, help="Trials of the study (default 8).")
    parser.add_argument(
        "--all", action="store_true", help="Count every somo_sweep module, not the sweep's only."
    )
    parser.add_argument("--json", type=Path, help="Also write the counts as JSON here.")
    args = parser.parse_args(argv)
    with user_errors():
        trip = traced_run(args.trials, args.all)
    if args.json is not None:
        args.json.write_text(json.dumps(trip.as_dict(), indent=2) + "\n", encoding="utf-8")
    stays = len(trip.stays)
    echo([f"{trip.rooms} modules entered, {stays} stays, {trip.returns} returns to a module left before"])
    echo(f"  {module}: {n}" for module, n in trip.by_module())
    return 0


if __name__ == "__main__":
    sys.exit(main())
