"""The names of a results folder's own files (the layout :mod:`~somo_sweep.sweep.store.result_store`
describes)."""

from __future__ import annotations

__all__ = ["INFERRED", "JOURNAL_GLOB", "MANIFEST", "PART_GLOB", "QUARANTINE"]

MANIFEST = "manifest.json"
#: The cells an adaptive run inferred instead of simulating (outside ``trials/``: never resumed from).
INFERRED = "inferred.parquet"
#: Part files of the trials table, in ``trials/``.
PART_GLOB = "part-*.parquet"
#: Rows of a run appended one by one as trials finish (hidden: Parquet readers skip them).
JOURNAL_GLOB = ".journal-*.jsonl"
#: Where damaged part files go, inside ``trials/``; their names get a ``_`` prefix so that
#: ``pd.read_parquet("…/trials")`` (which reads sub-folders) skips them.
QUARANTINE = "quarantine"
