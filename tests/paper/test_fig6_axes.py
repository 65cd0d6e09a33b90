"""Fig. 6 on a study that sweeps more than DSR × width × c, and on a folder whose replicas were cut
short: a row of panels and a headline per value of the extra axis, never two trials in one cell,
and a headline from an unfinished folder marked provisional. Real MuJoCo trials (~0.2 s each)."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.paper.fig6 import MAX_ROWS, build, draw_dsr_panel, grasp_table
from somo_sweep.paper.grasp_trials import read_results
from somo_sweep.sweep.run.runner import RunEvents, RunOptions, run_sweep
from somo_sweep.sweep.study import load_study

STUDY = """name: extra
task: pinch_grasp
model: models/pinch_gripper.yaml
sweep:
  task.distal_segment_ratio: [0.2, 0.4]
  task.pressure_kpa: [40, 150]
  task.object_width_m: [0.02, 0.06]
  task.centering_position_m: [0.1, 0.13]
seed: 0
simulation: {engine: mujoco}
"""


def _study(folder: Path, extra: str = "") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "models").exists():
        (folder / "models").symlink_to(MODELS)
    path = folder / "extra.yaml"
    path.write_text(STUDY + extra)
    return path


@pytest.fixture(scope="module")
def robust_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2 DSR × 2 pressures × 2 widths × 2 c, with 2 boundary replicas per cell that matters."""
    root = tmp_path_factory.mktemp("extra")
    result = CliRunner().invoke(
        app, ["run", str(_study(root)), "--out", str(root / "out"), "--robust", "2", "-j", "2", "--no-plots"]
    )
    assert result.exit_code == 0, result.output
    return root / "out"


def _fig6(folder: Path, out: Path) -> str:
    result = CliRunner().invoke(app, ["paper", "fig6", str(folder), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return result.output


def test_an_extra_axis_with_robust_labels_gets_a_row_and_a_headline_per_value(
    robust_folder: Path, tmp_path: Path
) -> None:
    """It ended in "ValueError: Length of values (8) does not match length of index (16)"."""
    output = _fig6(robust_folder, tmp_path)
    heads = [line for line in output.splitlines() if "smallest all-width pinch DSR" in line]
    assert [h.split(":")[0] for h in heads] == ["pressure 40 kPa", "pressure 150 kPa"]
    info = json.loads((tmp_path / "fig6_contacts.json").read_text())
    assert info["axes"] == ["task_pressure_kpa"]
    assert [a["task_pressure_kpa"] for a in info["answers"]] == [40, 150]
    assert all(a["complete"] for a in info["answers"])
    asked = CliRunner().invoke(
        app,
        [
            "answer",
            str(robust_folder),
            "--smallest",
            "task.distal_segment_ratio",
            "--every",
            "object_width_m",
            "--some",
            "centering_position_m",
        ],
    )
    assert asked.exit_code == 0, asked.output
    for a in info["answers"]:
        dsr = a["smallest_all_width_pinch_dsr"]
        assert (
            f"pressure {a['task_pressure_kpa']:g} kPa: {'none' if dsr is None else f'{dsr:g}'}"
            in asked.output
        )


def test_no_panel_draws_two_trials_in_one_cell(robust_folder: Path) -> None:
    """Without the extra axis it drew 60 trials into 30 cells, the last pressure's label winning."""
    trials = read_results(robust_folder)
    own = trials[trials["replica"] == 0].copy()
    own.attrs.clear()  # the study as run without replicas
    table = grasp_table(own)
    out = build(table)
    panels = [ax for ax in out.figures["fig6"].axes if ax.get_title().startswith("DSR")]
    assert len(panels) == 4  # 2 DSR × 2 pressures
    assert [len(ax.patches) for ax in panels] == [4, 4, 4, 4]  # 2 widths × 2 centerings each
    answers = out.json["fig6.json"]["answers"]
    assert sorted(a["task_pressure_kpa"] for a in answers) == sorted(set(table["task_pressure_kpa"]))
    plt.close("all")


def test_a_panel_asked_to_draw_two_cells_in_one_place_refuses_naming_the_axis() -> None:
    table = pd.DataFrame(
        {
            "distal_segment_ratio": [0.2, 0.2],
            "centering_position_m": [0.1, 0.1],
            "object_width_m": [0.02, 0.02],
            "task_pressure_kpa": [40.0, 150.0],
            "label": ["pinch", "power"],
        }
    )
    fig, ax = plt.subplots()
    with pytest.raises(
        SomoError, match=r"two cells at DSR 0.20, c 100 mm, width 20 mm: .* task_pressure_kpa"
    ):
        draw_dsr_panel(ax, table, 0.2)
    plt.close(fig)


def test_more_values_of_the_extra_axes_than_rows_is_refused_naming_them() -> None:
    n = MAX_ROWS + 1
    table = pd.DataFrame(
        {
            "distal_segment_ratio": [0.2] * n,
            "centering_position_m": [0.1] * n,
            "object_width_m": [0.02] * n,
            "task_pressure_kpa": [float(p) for p in range(n)],
            "label": ["pinch"] * n,
        }
    )
    with pytest.raises(SomoError, match=rf"pressure_kpa \({n} values\).*somo-sweep answer"):
        build(table)


def test_a_headline_from_a_run_cut_short_in_the_replica_phase_is_provisional(tmp_path: Path) -> None:
    """It printed "no DSR pinch-grasps every width (robust cells)" where the resumed run gave 0.20,
    with no word of the 14 cells that had none of their replicas."""
    path = _study(tmp_path, "robustness: {replicas: 2, where: all}\n")
    seen: list[object] = []

    def stop(outcome: object) -> None:
        seen.append(outcome)
        if len(seen) == 16 + 4:
            raise KeyboardInterrupt

    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1), RunEvents(outcome=stop))
    output = _fig6(tmp_path / "out", tmp_path / "fig")
    heads = [
        line for line in output.splitlines() if "smallest all-width pinch DSR" in line or "no DSR" in line
    ]
    assert len(heads) == 2 and all("provisional:" in h and "await replicas" in h for h in heads)
    assert "14 cell(s) await some of their 2 replicas (14 with none stored yet)" in output
    assert "not robust: c =" not in output  # awaiting is never "not robust"
    info = json.loads((tmp_path / "out" / "fig6_contacts.json").read_text())
    assert [a["complete"] for a in info["answers"]] == [False, False]
    classify = CliRunner().invoke(app, ["classify", str(tmp_path / "out")])
    assert classify.exit_code == 0, classify.output
    assert (
        "14 await replicas" in classify.output and "the robustness replicas are unfinished" in classify.output
    )
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))  # the resume completes them
    output = _fig6(tmp_path / "out", tmp_path / "fig")
    assert "provisional" not in output and "await" not in output


def test_a_side_by_side_of_folders_with_an_extra_axis_is_refused_naming_it(
    robust_folder: Path, tmp_path: Path
) -> None:
    args = ["paper", "fig6-compare", str(robust_folder), str(robust_folder), "--out", str(tmp_path)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert "ours also sweeps task_pressure_kpa: a side-by-side panel holds one value" in " ".join(
        result.output.split()
    )
    assert not list(tmp_path.iterdir())
