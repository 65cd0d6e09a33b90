"""``python -m somo_sweep`` runs the command line."""

from somo_sweep.cli import main

main()
