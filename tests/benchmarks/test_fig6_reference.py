"""The robust Fig. 6 reference and the active-sampling replay: their stored numbers are what the
benchmarks compute from the stored runs, and the replay runs the study's own settings."""

from __future__ import annotations

import json
from dataclasses import asdict, replace
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.active_sampling import CONFIGS, FIG6_FAST, Oracle, replay
from benchmarks.fig6_reference import REFERENCE, RULES, STUDY, cells, headlines
from somo_sweep.sweep.run.active_plan import sampler_settings
from somo_sweep.sweep.study import load_study

REPLAY = REFERENCE.parent / "active_sampling.json"


@pytest.fixture(scope="module")
def runs() -> pd.DataFrame:
    return pd.read_csv(REFERENCE / "runs.csv")


def test_the_reference_is_every_cell_with_all_its_replicas(runs: pd.DataFrame) -> None:
    assert len(runs) == 2310 * 5 and (runs["status"] == "ok").all()
    per_cell = runs.groupby("trial")["replica"].apply(lambda r: tuple(sorted(r)))
    assert len(per_cell) == 2310 and set(per_cell) == {(0, 1, 2, 3, 4)}


def test_the_stored_headlines_are_what_the_answer_gives_on_the_stored_runs(runs: pd.DataFrame) -> None:
    stored = json.loads((REFERENCE / "headline.json").read_text())
    assert headlines(runs) == stored
    assert stored["contacts"]["smallest_all_width_pinch_dsr"] == 0.0
    assert stored["paper"]["smallest_all_width_pinch_dsr"] == 0.05


def test_a_cell_is_robust_only_when_its_five_runs_agree(runs: pd.DataFrame) -> None:
    table = cells(runs, "contacts")
    spread = runs.groupby("trial")[RULES["contacts"]].nunique()
    assert (table.set_index("trial")["robust"].astype(bool) == (spread == 1)).all()
    assert (table.loc[~table["robust"].astype(bool), "robust_label"] == "not_robust").all()


def test_the_replay_runs_the_settings_of_the_fig6_study(tmp_path: Path) -> None:
    study = load_study(STUDY, tmp_path / "out")
    assert sampler_settings(study) == replace(FIG6_FAST, seed=study.seed)
    assert CONFIGS[0].settings == FIG6_FAST and CONFIGS[0].follow == ("contacts", "paper")


def test_the_stored_replay_of_seed_0_is_what_the_replay_gives(runs: pd.DataFrame) -> None:
    stored = json.loads(REPLAY.read_text())["fig6_fast"]["seeds"][0]
    now = asdict(replay(Oracle(runs), CONFIGS[0], 0, {r: cells(runs, r) for r in RULES}))
    now.pop("seconds"), stored.pop("seconds")
    assert now == stored


@pytest.mark.slow
@pytest.mark.timeout(1800)  # the whole benchmark: 8 configurations x 10 seeds, 5-10 min
def test_the_stored_replay_is_what_the_benchmark_computes(runs: pd.DataFrame) -> None:
    stored = json.loads(REPLAY.read_text())
    oracle, reference = Oracle(runs), {r: cells(runs, r) for r in RULES}
    for config in CONFIGS:
        for row in stored[config.name]["seeds"]:
            now = asdict(replay(oracle, config, row["seed"], reference))
            now.pop("seconds"), row.pop("seconds")
            assert now == row, (config.name, row["seed"])
