"""How ``--help`` shows parameters: flags as bare flags, arguments in capitals.

Typer prints a value type after every option, flags included (``--dry-run <bool>``,
although a flag takes no value), and writes required arguments as ``{study}`` in the
usage line. :func:`plain_help` gives every command of an app a command class that
shows flags without a type and arguments as ``STUDY`` / ``[STUDY]``.
"""

from __future__ import annotations

from typing import Any

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

__all__ = ["HelpCommand", "HelpGroup", "plain_help"]


def _plain(params: list[Any]) -> list[Any]:
    for param in params:
        if isinstance(param, TyperOption) and param.is_flag and param.metavar is None:
            param.metavar = ""  # shown instead of the type: nothing
    return params


def _usage(command: Any, ctx: Any) -> list[str]:
    pieces = [command.options_metavar] if command.options_metavar else []
    for param in command.get_params(ctx):
        if isinstance(param, TyperArgument):
            name = (param.metavar or param.name or "").upper()
            name = name if param.required else f"[{name}]"
            pieces.append(f"{name}..." if param.nargs != 1 else name)
    return pieces


class HelpCommand(TyperCommand):
    """A command whose help shows flags as flags and arguments in capitals."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain(super().get_params(ctx))

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        return _usage(self, ctx)


class HelpGroup(TyperGroup):
    """A command group whose help shows flags as flags."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain(super().get_params(ctx))

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        return [*_usage(self, ctx), self.subcommand_metavar]


def plain_help(app: typer.Typer) -> None:
    """Use :class:`HelpCommand` / :class:`HelpGroup` for every command and group of ``app``."""
    for info in app.registered_commands:
        if info.cls in (None, TyperCommand):  # Typer's default, filled in by app.command()
            info.cls = HelpCommand
    for group in app.registered_groups:
        if group.cls in (None, TyperGroup):
            group.cls = HelpGroup
        if group.typer_instance is not None:
            plain_help(group.typer_instance)
