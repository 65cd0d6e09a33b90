"""The design benchmark: its stored numbers are what it computes from its stored grid, and the grid
answers the search's trials as the simulator does."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.design_oracle import Oracle, replay
from benchmarks.design_search import BENCH, evaluate, lines, main
from somo_sweep.design import load_design, run_design
from somo_sweep.sweep.run.options import RunOptions
from somo_sweep.sweep.store.folder import read_results

STORED = BENCH.parent / "design_bench.json"


@pytest.fixture(scope="module")
def cells() -> pd.DataFrame:
    return pd.read_csv(BENCH / "grid_cells.csv")


def test_the_stored_grid_is_every_cell_with_every_replica(cells: pd.DataFrame) -> None:
    assert len(cells) == 120 * 12 * 5
    runs = cells.groupby(list(cells.columns[:5]))["replica"].apply(lambda r: tuple(sorted(r)))
    assert len(runs) == 1440 and all(r == (0, 1, 2, 3, 4) for r in runs)


def test_the_stored_numbers_are_what_one_seed_computes(cells: pd.DataFrame) -> None:
    stored = json.loads(STORED.read_text())
    now = evaluate(cells, seeds=1)
    assert now["grid"] == stored["grid"] and now["budget"] == stored["budget"]
    assert now["design"][0] == stored["design"][0] and now["random"][0] == stored["random"][0]


@pytest.mark.slow
def test_the_stored_numbers_are_what_the_benchmark_computes(cells: pd.DataFrame) -> None:
    stored = json.loads(STORED.read_text())
    now = evaluate(cells, seeds=stored["target"]["seeds"])
    assert now == stored
    assert now["target"]["met"], lines(now)


def test_the_grid_answers_the_search_as_the_simulator_does(cells: pd.DataFrame, tmp_path: Path) -> None:
    """The first 40 simulations of the real search, on MuJoCo: each is the stored grid's run of the
    same design, object and replica, and the search against the grid asks for the same trials."""
    pytest.importorskip("mujoco")
    study = load_design(BENCH / "design.yaml", tmp_path / "out", budget=40)
    run_design(study, RunOptions(n_jobs=2))
    table = read_results(tmp_path / "out")
    oracle = Oracle(cells, study)
    label = f"label_{study.objective.label}"
    for row in table.to_dict("records"):
        status, labels = oracle.runs[oracle._key(row, int(row["replica"]))]
        assert (status, labels.get(study.objective.label)) == (row["status"], row[label]), row["trial"]
    search, _ = replay(study, oracle)
    assert search.requested == set(table["job_id"])


def test_the_command_recomputes_from_the_stored_grid(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    main(["--stored", "--seeds", "1", "--out", str(tmp_path)])
    said = capsys.readouterr().out
    assert "grid: 120 designs x 12 objects" in said and (tmp_path / "design_bench.png").exists()
    assert json.loads((tmp_path / "design_bench.json").read_text())["target"]["seeds"] == 1
