"""``somo-sweep recheck``: stored trials re-run in another process layout reproduce their rows."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_sweep import selftest_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.recheck import recheck

runner = CliRunner()


def _finished(tmp_path: Path) -> Path:
    path = selftest_study(tmp_path, n=6)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=2))
    return path


def test_rerun_trials_match_their_stored_rows_cell_for_cell(tmp_path: Path) -> None:
    path = _finished(tmp_path)
    report = recheck(load_study(path, tmp_path / "out"), n_trials=4, seed=3)
    assert report.identical, report.mismatches
    assert len(report.trials) == 4 and len(set(report.trials)) == 4
    # the seeded noise metric, the label and the parameters are among the compared cells
    assert report.columns_compared >= 4 * 8
    res = runner.invoke(app, ["recheck", str(path), "--out", str(tmp_path / "out"), "-n", "6"])
    assert res.exit_code == 0, res.output
    assert "6 identical, 0 different" in res.output


def test_a_changed_stored_metric_is_reported_and_fails(tmp_path: Path) -> None:
    path = _finished(tmp_path)
    part = next((tmp_path / "out" / "trials").glob("*.parquet"))
    table = pq.read_table(part)
    df = table.to_pandas()
    df.loc[df.index, "noise"] = df["noise"] + 1e-12  # one ulp-sized change is still a change
    pq.write_table(pa.Table.from_pandas(df, schema=table.schema, preserve_index=False), part)
    args = ["recheck", str(path), "--out", str(tmp_path / "out"), "-n", "6"]
    res = runner.invoke(app, [*args, "--report", str(tmp_path / "r.json")])
    assert res.exit_code == 1, res.output
    assert "noise: stored" in res.output
    mismatches = pd.read_json(tmp_path / "r.json", typ="series")["mismatches"]
    assert {m["column"] for m in mismatches} == {"noise"}


def test_rows_written_before_the_retry_columns_recheck_identical(tmp_path: Path) -> None:
    """A folder from before ``retried_half_step``/``time_step_used_s`` (null there) is not different;
    a stored value in them is still compared."""
    path = _finished(tmp_path)
    parts = sorted((tmp_path / "out" / "trials").glob("*.parquet"))
    for part in parts:
        table = pq.read_table(part)
        df = table.to_pandas()
        df["retried_half_step"] = None
        df["time_step_used_s"] = float("nan")
        pq.write_table(pa.Table.from_pandas(df, schema=table.schema, preserve_index=False), part)
    assert recheck(load_study(path, tmp_path / "out"), n_trials=6, seed=3).identical
    table = pq.read_table(parts[0])
    df = table.to_pandas()
    df["retried_half_step"] = True
    pq.write_table(pa.Table.from_pandas(df, schema=table.schema, preserve_index=False), parts[0])
    report = recheck(load_study(path, tmp_path / "out"), n_trials=6, seed=3)
    assert {m.column for m in report.mismatches} == {"retried_half_step"}


def test_results_of_another_study_version_are_refused(tmp_path: Path) -> None:
    path = _finished(tmp_path)
    path.write_text(path.read_text().replace("sleep_s: 0.0", "sleep_s: 0.001"))
    with pytest.raises(SomoError, match="another version"):
        recheck(load_study(path, tmp_path / "out"))
