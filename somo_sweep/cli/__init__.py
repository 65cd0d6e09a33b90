"""The command line (the only package that writes files): ``somo-sweep …``."""

from somo_sweep.cli.app import app, main

__all__ = ["app", "main"]
