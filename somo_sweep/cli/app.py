"""The ``somo-sweep`` command line: one Typer app, every command registered here.

Command modules hold plain functions (parse options, call one library function,
map errors to exit codes); this module alone assembles them, so there is no
import-for-side-effect and no cycle between the app and its commands.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path
from typing import Annotated, Any

import typer

from somo_sweep.cli import (
    answer,
    calibrate,
    design,
    diagnose,
    engines,
    grasp,
    model,
    new,
    paper,
    results,
    sweep,
    tasks,
)
from somo_sweep.cli.help import HelpGroup, plain_help
from somo_sweep.cli.output import state
from somo_sweep.errors import SHOWN_CHARS, os_cause, printable, shown

__all__ = ["app", "main"]

app = typer.Typer(
    no_args_is_help=True,
    help="Simulate soft continuum robots in PyBullet or MuJoCo: describe, measure, calibrate, sweep.",
    rich_markup_mode="rich",
    cls=HelpGroup,
    add_completion=True,  # --install-completion / --show-completion for bash, zsh, fish
)


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            typer.echo(f"somo-sweep {version('somo-sweep')}")
        except PackageNotFoundError:
            typer.echo("somo-sweep (not installed)")
        raise typer.Exit()


@app.callback()
def _main(
    debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks on errors.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print only results and errors.")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Print more detail.")] = False,
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit."),
    ] = False,
) -> None:
    state["debug"] = debug
    state["verbosity"] = 0 if quiet else 2 if verbose else 1


app.command()(model.check)
app.command()(model.measure)
app.command()(sweep.run)
app.command()(design.design)
app.command()(results.show)
app.command()(results.plot)
app.command()(answer.answer)
app.command()(tasks.tasks)
app.command()(results.recheck)
app.command()(engines.compare_engines)
app.command()(calibrate.calibrate)
app.command()(diagnose.diagnose)
app.command()(grasp.classify)
app.command()(grasp.render)
app.add_typer(new.app, name="new", cls=HelpGroup)
app.add_typer(paper.app, name="paper", cls=HelpGroup)
plain_help(app)


#: The options of ``somo-sweep`` itself (:func:`_main`), which users also type after the command.
GLOBAL_FLAGS = frozenset({"--debug", "--quiet", "-q", "--verbose", "-v"})


def global_flags_first(args: list[str]) -> list[str]:
    """``args`` with the global flags typed after the command moved in front of it.

    ``somo-sweep calibrate m.csv -q`` then means ``somo-sweep -q calibrate m.csv`` instead of
    "No such option: -q" (no command has options of these names). Nothing after ``--`` moves.
    """
    if "--" in args:
        cut = args.index("--")
        head, tail = args[:cut], args[cut:]
    else:
        head, tail = args, []
    flags = [a for a in head if a in GLOBAL_FLAGS]
    return flags + [a for a in head if a not in GLOBAL_FLAGS] + tail


def empty_value(args: list[str]) -> str | None:
    """What was left empty in ``args`` (``--out ""``, ``--out=`` or an empty argument), or None.

    Typer reads an empty path as ``.``, so ``--out "$UNSET"`` would quietly mean this folder; no
    option or argument of ours takes an empty value.
    """
    for i, arg in enumerate(args):
        if arg == "":
            before = args[i - 1] if i and args[i - 1].startswith("-") and "=" not in args[i - 1] else None
            return f"{before} was given an empty value" if before else "an argument is empty"
        if arg.startswith("--") and arg.endswith("=") and "=" not in arg[:-1]:
            return f"{arg[:-1]} was given an empty value"
    return None


def allowed_value(args: list[str]) -> str:
    """What the option left empty in ``args`` takes (``an integer from 0 to 16``), from its
    command's own declaration; ``any non-empty value`` when that cannot be told."""
    command: Any = typer.main.get_command(app)
    option = None
    for i, arg in enumerate(args):
        name = arg.split("=", 1)[0]
        if name in getattr(command, "commands", {}):
            command = command.commands[name]
        elif arg == "" and i and args[i - 1].startswith("-"):
            option = args[i - 1]
            break
        elif arg.startswith("--") and arg.endswith("="):
            option = name
            break
    param = next((p for p in getattr(command, "params", []) if option in p.opts), None)
    descriptor = getattr(param, "type_descriptor", None)
    kinds: dict[Any, str] = {int: "an integer", float: "a number", Path: "a path"}
    kind = kinds.get(getattr(descriptor, "annotation", None))
    if kind is None:
        return "any non-empty value"
    low, high = getattr(param, "min", None), getattr(param, "max", None)
    if low is not None and high is not None:
        return f"{kind} from {low:g} to {high:g}"
    return kind


def not_utf8(args: list[str]) -> str | None:
    """The first argument holding bytes that are not UTF-8 (a folder named in Latin-1), shown, or None.

    Python keeps such bytes as lone surrogates; pyarrow cannot open a path holding them and
    failed with a traceback deep in ``show``, ``plot`` and ``paper fig6``.
    """
    for arg in args:
        try:
            arg.encode("utf-8")
        except UnicodeEncodeError:
            raw = arg.encode("utf-8", "surrogateescape")
            return printable(shown(raw.decode("utf-8", "backslashreplace"), 4 * SHOWN_CHARS))
    return None


_python_format = warnings.formatwarning


def _one_line_for_ours(
    message: Warning | str, category: type[Warning], filename: str, lineno: int, line: str | None = None
) -> str:
    """A skipped part file (:class:`~somo_sweep.sweep.store.folder.DamagedPartWarning`) as one line,
    without Python's source line; every other warning as Python shows it."""
    if category.__name__ == "DamagedPartWarning":
        return f"warning: {message}\n"
    return _python_format(message, category, filename, lineno, line)


#: The warning of loky's resource tracker (a process of its own) when the sweep it served was
#: killed: it names the semaphores and folders the workers left, then removes them.
_TRACKER_NOTE = "ignore:resource_tracker:UserWarning"


def _quiet_resource_tracker() -> None:
    """Keep loky's resource tracker from printing its "leaked semlock objects" list after a killed
    run (SIGKILL, out of memory): it cleans them up itself, so nothing has leaked and there is
    nothing to do, and the next run already says the run was killed. The tracker outlives the
    sweep's process, so its warning cannot be reworded here: it is filtered in the environment
    it starts with (the sweep's own warnings are unchanged)."""
    given = os.environ.get("PYTHONWARNINGS", "")
    if _TRACKER_NOTE not in given.split(","):
        os.environ["PYTHONWARNINGS"] = f"{given},{_TRACKER_NOTE}" if given else _TRACKER_NOTE


def _matplotlib_cache() -> None:
    """Matplotlib's font cache in somo-sweep's cache folder (``<cache>/matplotlib``, beside the URDF
    cache), not a folder of its own in the home directory, unless the user chose one
    (``MPLCONFIGDIR``) or that folder cannot be made (Matplotlib then uses its default)."""
    if os.environ.get("MPLCONFIGDIR"):
        return
    from somo_sweep.sim.urdf_cache import cache_dir

    folder = cache_dir().parent / "matplotlib"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return
    if os.access(folder, os.W_OK | os.X_OK):
        os.environ["MPLCONFIGDIR"] = str(folder)


def main() -> None:
    """Console-script entry point (figures drawn off-screen).

    An operating-system error no command foresaw (a name longer than the file system allows,
    no permission, a full disk) ends the run with one line naming the file, not a traceback
    (``--debug`` shows it); what was already written stays, as for any other error.
    """
    os.environ.setdefault("MPLBACKEND", "Agg")
    _matplotlib_cache()
    _quiet_resource_tracker()
    warnings.formatwarning = _one_line_for_ours
    args = global_flags_first(sys.argv[1:])
    if (empty := empty_value(args)) is not None:
        print(f"error: {empty} (an unset shell variable?); allowed: {allowed_value(args)}", file=sys.stderr)
        raise SystemExit(2)
    if (bad := not_utf8(args)) is not None:
        print(
            f"error: '{bad}' holds bytes that are not UTF-8 text; allowed: UTF-8 names (rename the file or "
            "folder, e.g. with convmv)",
            file=sys.stderr,
        )
        raise SystemExit(2)
    try:
        app(args=args, prog_name="somo-sweep")
    except OSError as exc:
        if state["debug"]:
            raise
        cause, advice = os_cause(exc)
        name = f"{shown(str(exc.filename), 4 * SHOWN_CHARS)}: " if exc.filename else ""
        print(f"error: {name}{cause}; {advice}, then run the same command again", file=sys.stderr)
        raise SystemExit(2) from None
