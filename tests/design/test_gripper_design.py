"""A design search of the worked example's gripper on MuJoCo (seconds): the answer's files, the best
design's grid study run again giving the same trials and share, the usual readers on the folder,
distal segment ratios moved onto the fingers' links, and a trade-off's Pareto front."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
import yaml
from design_studies import gripper_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.sweep.run.robustness import fold
from somo_sweep.sweep.store.folder import read_results

pytest.importorskip("mujoco")
DSR = "task.distal_segment_ratio"
PRESSURE = "task.pressure_kpa"


@pytest.fixture(scope="module")
def searched(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The gripper search run once through the command line: its folder and results folder."""
    folder = tmp_path_factory.mktemp("grip")
    path = gripper_study(folder, budget=40)
    res = CliRunner().invoke(app, ["design", str(path), "--out", str(folder / "out"), "--jobs", "2"])
    assert res.exit_code == 0, res.output
    assert "best design: task.distal_segment_ratio = " in " ".join(res.output.split())
    return folder, folder / "out"


def test_the_answer_is_a_ranking_by_key_path_a_summary_maps_and_a_study(searched: tuple[Path, Path]) -> None:
    _, out = searched
    ranking = pd.read_csv(out / "design" / "ranking.csv")
    assert list(ranking.columns[:4]) == ["rank", "design", DSR, PRESSURE]
    assert {"robust_share", "share_low_95", "share_high_95", "simulations", "complete"} <= set(
        ranking.columns
    )
    # Ratios between the 12-link finger's boundaries were moved onto them (3/12 and 4/12).
    assert set(ranking[DSR]) <= {0.25, 0.333333333333}
    summary = json.loads((out / "design" / "summary.json").read_text())
    assert summary["written_by"] == "somo-sweep design" and summary["simulations"] == len(read_results(out))
    assert summary["simulations"] <= 40
    maps = sorted((out / "design").glob("finalist_*_design_*.png"))
    assert 1 <= len(maps) <= 2 and maps[0].read_bytes().startswith(b"\x89PNG")


def test_the_best_design_study_reruns_the_trials_the_search_ran(searched: tuple[Path, Path]) -> None:
    folder, out = searched
    best = out / "design" / "best_design.yaml"
    study = yaml.safe_load(best.read_text())
    assert study["robustness"] == {"replicas": 1, "where": "all", "labels": ["grasp"]}
    rerun = folder / "rerun"
    res = CliRunner().invoke(app, ["run", str(best), "--out", str(rerun), "--jobs", "2", "--no-plots"])
    assert res.exit_code == 0, res.output
    again = read_results(rerun)
    searched_ids = set(read_results(out)["job_id"])
    plain = again[again["replica"] == 0]
    assert set(plain["job_id"]) <= searched_ids  # the same trials: same ids, same seeds
    cells = fold(again, labels=["label_grasp"], planned=1)
    robust = int(((cells["label_grasp"] == "pinch") & cells["robust"].fillna(False).astype(bool)).sum())
    top = pd.read_csv(out / "design" / "ranking.csv").iloc[0]
    assert robust == top["robust_objects"]


@pytest.mark.parametrize("command", [["show"], ["plot"], ["classify", "--rule", "paper"]])
def test_the_usual_readers_read_a_design_folder(searched: tuple[Path, Path], command: list[str]) -> None:
    _, out = searched
    res = CliRunner().invoke(app, [command[0], str(out), *command[1:]])
    assert res.exit_code == 0, res.output


def test_a_trade_off_searches_a_pareto_front(tmp_path: Path) -> None:
    edit = (
        "objective: {label: grasp, value: pinch}=>objective: {label: grasp, value: pinch}\n"
        "  trade_off: {variable: task.pressure_kpa, direction: minimize}"
    )
    path = gripper_study(tmp_path, budget=40, edit=edit)
    res = CliRunner().invoke(app, ["design", str(path), "--out", str(tmp_path / "out"), "--jobs", "2"])
    assert res.exit_code == 0, res.output
    ranking = pd.read_csv(tmp_path / "out" / "design" / "ranking.csv")
    assert "pareto" in ranking.columns and ranking["pareto"].any()
    assert (tmp_path / "out" / "design" / "pareto.png").read_bytes().startswith(b"\x89PNG")
