"""The designer's question of a three-finger gripper, answered by one command: `new grasp-study
--fingers 3` writes a design study next to the grasp study, and `somo-sweep design` on it gives
the answer (the best distal segment ratio and stiffness), its robustness (a share of the boxes
with its interval) and the finalists' label maps."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from somo_sweep.cli.app import app

pytest.importorskip("mujoco")
DSR, SCALE = "task.distal_segment_ratio", "task.spring_scale"


def _answered(folder: Path, budget: int | None) -> tuple[str, Path]:
    """Write the three-finger starter in ``folder`` and search its design study; the answer's
    output and its results folder."""
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        new = CliRunner().invoke(app, ["new", "grasp-study", "mine", "--fingers", "3"])
        assert new.exit_code == 0, new.output
        assert "somo-sweep design mine/design.yaml" in new.output
        argv = ["design", "mine/design.yaml", "--jobs", "2"]
        res = CliRunner().invoke(app, argv + ([] if budget is None else ["--budget", str(budget)]))
        assert res.exit_code == 0, res.output
    finally:
        os.chdir(cwd)
    return " ".join(res.output.split()), folder / "results" / "my_grasp_design" / "design"


def _check_the_answer(said: str, answer: Path) -> pd.DataFrame:
    assert f"best design: {DSR} = " in said and f"{SCALE} = " in said
    ranking = pd.read_csv(answer / "ranking.csv")
    assert {DSR, SCALE, "robust_share", "share_low_95", "share_high_95", "simulations"} <= set(
        ranking.columns
    )
    best = ranking.iloc[0]
    assert best["share_low_95"] <= best["robust_share"] <= best["share_high_95"]
    assert sorted(answer.glob("finalist_*_design_*.png"))
    study = yaml.safe_load((answer / "best_design.yaml").read_text())
    assert study["model"].endswith("gripper.yaml") and study["sweep"][DSR] == [best[DSR]]
    return ranking


def test_the_three_finger_question_is_one_command(tmp_path: Path) -> None:
    said, answer = _answered(tmp_path, budget=300)
    ranking = _check_the_answer(said, answer)
    assert ranking["simulations"].sum() <= 300


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_the_three_finger_question_is_answered_with_its_whole_budget(tmp_path: Path) -> None:
    said, answer = _answered(tmp_path, budget=None)
    ranking = _check_the_answer(said, answer)
    assert ranking["complete"].iloc[0], "the best design was judged on every box with its replicas"
    assert ranking["simulations"].sum() <= 3000
