"""The cross-check against the original SoMo code: its own pinch trial and ours, cell by cell.

``run_original_cells`` runs in the original's own environment (README.md beside this file sets
it up); ``compare_cells``, ``merge_cells`` and ``merge_steps`` in this repository's. Nothing here
imports the package at import time, so the original's interpreter can run ``run_original_cells``
as ``python -m benchmarks.original_fig6.run_original_cells`` from the repository root.
"""
