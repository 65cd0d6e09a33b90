"""``distal_segment_ratio: null`` (the fingers simulated as written) end to end: stored, read,
relabelled and mapped, never called damaged rows; ``paper fig6`` says why it leaves them out."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from test_own_gripper import ROOT
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.paper.fig6 import build, grasp_table
from somo_sweep.paper.grasp_trials import read_results, relabel
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.folder import read_manifest
from somo_sweep.sweep.store.folder import read_results as read_trials
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.label_maps import label_maps
from somo_sweep.sweep.views.results import Results, open_results

MODEL = ROOT / "somo_sweep" / "data" / "models" / "pinch_gripper.yaml"
LEFT_OUT = (
    "2 cell(s) left out, of distal_segment_ratio null (the fingers simulated as written), with no DSR to "
    "place them on: `somo-sweep classify` labels them and `somo-sweep plot` draws their map"
)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """4 MuJoCo trials: DSR null and 0.2, two widths."""
    pytest.importorskip("mujoco")
    tmp = tmp_path_factory.mktemp("as_written")
    study = tmp / "study.yaml"
    study.write_text(
        f"task: pinch_grasp\nmodel: {MODEL}\nsweep:\n  task.distal_segment_ratio: [null, 0.2]\n"
        "  task.object_width_m: [0.02, 0.04]\nparams: {centering_position_m: 0.1}\n"
        "simulation: {engine: mujoco}\n"
    )
    summary = run_sweep(load_study(study, tmp / "out"), RunOptions(n_jobs=1))
    assert summary.run == 4
    return tmp / "out"


def test_null_is_stored_as_null_and_read_without_calling_the_rows_damaged(folder: Path) -> None:
    table = read_results(folder)
    dsr = table.set_index("trial")["task_distal_segment_ratio"].sort_index()
    assert dsr.isna().tolist() == [True, True, False, False]
    assert (table["status"] == "ok").all()


def test_classify_relabels_the_null_cells_and_writes_them(folder: Path) -> None:
    counts, cells = relabel(folder)
    assert sum(counts.values()) == 4 and cells["grasp_contacts"].notna().all()
    res = CliRunner().invoke(app, ["classify", str(folder)])
    assert res.exit_code == 0, res.output
    written = pd.read_csv(folder / "grasp_labels_contacts.csv")
    assert written["task_distal_segment_ratio"].isna().sum() == 2


def test_plot_maps_null_as_a_column_of_its_own(folder: Path) -> None:
    res = CliRunner().invoke(app, ["plot", str(folder)])
    assert res.exit_code == 0, res.output
    maps = dict(label_maps(open_results(folder)))
    ticks = {
        tuple(t.get_text() for t in ax.get_xticklabels() + ax.get_yticklabels())
        for ax in maps["label_map_grasp"].axes
        if ax.get_visible() and ax.get_xticklabels()
    }
    assert any("null" in labels and "0.2" in labels for labels in ticks), ticks
    trials = read_trials(folder)
    only_null = trials[trials["task_distal_segment_ratio"].isna()]  # an axis of null alone: no TypeError
    assert [name for name, _ in label_maps(Results.of_table(only_null, read_manifest(folder)))] == [
        "label_map_grasp",
        "label_map_grasp_paper",
    ]


def test_fig6_leaves_the_null_cells_out_and_says_so(folder: Path) -> None:
    table = grasp_table(read_results(folder))
    art = build(table)
    assert art.lines[1] == LEFT_OUT
    assert art.json["fig6.json"]["cells_as_written"] == 2 and art.json["fig6.json"]["trials"] == 2
    with pytest.raises(SomoError, match=r"^every cell is of distal_segment_ratio null \(the fingers"):
        build(table[table["distal_segment_ratio"].isna()])


def test_show_counts_the_null_cells_in_a_row_of_their_own(folder: Path) -> None:
    res = CliRunner().invoke(app, ["show", str(folder)], env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    rows = [line.split("│") for line in res.output.splitlines() if line.startswith("│ null")]
    assert rows and all(int(row[2]) == 2 for row in rows), res.output  # 2 ok trials of DSR null
