"""Fig. 6 with robustness replicas: the headline counts robust cells and names those deciding it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from test_fig6 import results_folder, tidy
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.paper.fig6 import (
    UNCERTAIN_HATCH,
    build,
    counted_cells,
    deciding_cells,
    draw_dsr_panel,
    grasp_table,
    smallest_all_width_pinch_dsr,
)


def with_robustness(table: pd.DataFrame, shaky: set[tuple[float, float, int]]) -> pd.DataFrame:
    """Every cell replicated 4 times and robust, except ``shaky`` (dsr, width, index along c): 3/5."""
    out = table.copy()
    out["replicas"] = 4
    index = out.groupby(["distal_segment_ratio", "object_width_m"]).cumcount()
    keys = zip(out["distal_segment_ratio"], out["object_width_m"], index, strict=True)
    bad = np.array([k in shaky for k in keys])
    out["agreement"] = np.where(bad, 0.6, 1.0)
    out["robust"] = pd.array(~bad, dtype="boolean")
    out["inferred"] = False
    return out


def test_the_headline_counts_only_robust_pinches_and_says_what_every_cell_would_give() -> None:
    table = tidy(
        {
            (0.1, 0.01): ["pinch", "power"],
            (0.1, 0.12): ["pinch", "power"],
            (0.2, 0.01): ["pinch", "power"],
            (0.2, 0.12): ["pinch", "power"],
        }
    )
    table = with_robustness(table, {(0.1, 0.01, 0)})  # DSR 0.1's only 10-mm pinch is a coin toss
    assert smallest_all_width_pinch_dsr(table) == 0.1
    assert smallest_all_width_pinch_dsr(table, robust_only=True) == 0.2
    out = build(table)
    info = out.json["fig6.json"]
    assert info["smallest_all_width_pinch_dsr"] == 0.2
    assert info["robustness"] == {
        "cells_replicated": 8,
        "robust": 7,
        "not_robust": 1,
        "awaiting_replicas": 0,
        "smallest_all_width_pinch_dsr_every_cell": 0.1,
    }
    assert "smallest all-width pinch DSR: 0.20 (robust cells); 0.10 counting every cell" in out.lines
    assert info["deciding_cells"] == [
        "DSR 0.10, width 10 mm: no robust pinch; not robust: c = 70 mm (60% of runs)",
        "DSR 0.20, width 10 mm: pinch at c = 70 mm (100% of runs)",
        "DSR 0.20, width 120 mm: pinch at c = 70 mm (100% of runs)",
    ]


def test_cells_without_replicas_count_only_inside_a_region_of_one_label() -> None:
    table = tidy({(0.1, 0.01): ["pinch", "pinch", "pinch", "power"]})
    table = with_robustness(table, set())
    table.loc[[1, 2], "replicas"] = 0
    table.loc[[1, 2], "robust"] = pd.NA
    # Cell 1 is flanked by pinches (interior); cell 2 touches the power cell (a boundary).
    assert counted_cells(table).tolist() == [True, True, False, True]


def test_a_table_without_replicas_counts_every_cell() -> None:
    table = tidy({(0.1, 0.01): ["pinch", "power"]})
    assert counted_cells(table).all()
    assert deciding_cells(with_robustness(table, set()), 0.1) == [
        "DSR 0.10, width 10 mm: pinch at c = 70 mm (100% of runs)"
    ]


def test_a_cell_whose_replicas_disagree_is_cross_hatched() -> None:
    import matplotlib.pyplot as plt

    table = with_robustness(tidy({(0.1, 0.01): ["pinch", "power"]}), {(0.1, 0.01, 1)})
    fig, ax = plt.subplots()
    draw_dsr_panel(ax, table, 0.1)
    hatches = [patch.get_hatch() for patch in ax.patches]
    plt.close(fig)
    assert hatches == [None, UNCERTAIN_HATCH]


def test_grasp_table_folds_replica_rows_into_their_cell(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    trials = pd.read_parquet(folder / "trials")
    own = trials.assign(replica=0)
    # Two replicas of trial 0: one lands power (contacts on link 3 and 19), one stays a pinch.
    copies = own[own["trial"] == 0].loc[[0, 0]].assign(replica=[1, 2], job_id=["r1", "r2"])
    copies.loc[copies["replica"] == 1, ["hold_normal_force_n_link03", "hold_normal_force_n_link20"]] = [
        1.0,
        0.0,
    ]
    runs = pd.concat([own, copies], ignore_index=True)
    table = grasp_table(runs, "contacts")
    assert len(table) == 3
    assert table["label"].tolist() == ["pinch", "power", "unstable"]
    assert table["replicas"].tolist() == [2, 0, 0]
    assert table["agreement"].iloc[0] == 2 / 3 and np.isnan(table["agreement"].iloc[1])
    assert table["robust"].tolist() == [False, pd.NA, pd.NA]


def test_fig6_and_classify_commands_report_robustness(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    trials = pd.read_parquet(folder / "trials").assign(replica=0)
    extra = trials[trials["trial"] == 1].assign(replica=1, job_id="r1")
    pd.concat([trials, extra]).to_parquet(folder / "trials" / "part-0.parquet")
    res = CliRunner().invoke(app, ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig")])
    assert res.exit_code == 0, res.output
    assert "(robust cells)" in res.output and "the cells that decide the headline" in res.output
    info = json.loads((tmp_path / "fig" / "fig6_contacts.json").read_text())
    assert info["robustness"]["cells_replicated"] == 1
    res = CliRunner().invoke(app, ["classify", str(folder)])
    assert res.exit_code == 0, res.output
    assert "robustness: 1 cell(s) with replicas, 1 robust under rule contacts, 0 not" in res.output
    labels = pd.read_csv(folder / "grasp_labels_contacts.csv")
    assert labels["replicas"].tolist() == [0, 1, 0] and labels["robust"].tolist()[1] is True


def test_a_cell_awaiting_some_of_its_planned_replicas_is_not_counted_in_the_headline(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    trials = pd.read_parquet(folder / "trials").assign(replica=0)
    partial = trials[trials["trial"] == 0].loc[[0, 0]].assign(replica=[1, 2], job_id=["r1", "r2"])
    pd.concat([trials, partial]).to_parquet(folder / "trials" / "part-0.parquet")
    # The run that planned 4 replicas per cell was killed after 2 of the pinch cell's.
    manifest = {"study_hash": "h", "runs": [{"status": "running", "replicas": 4}]}
    (folder / "manifest.json").write_text(json.dumps(manifest))
    res = CliRunner().invoke(app, ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig")])
    assert res.exit_code == 0, res.output
    assert "no DSR pinch-grasps every width (robust cells)" in res.output
    assert "1 cell(s) await replicas" in res.output
    info = json.loads((tmp_path / "fig" / "fig6_contacts.json").read_text())
    assert info["robustness"]["robust"] == 0 and info["robustness"]["awaiting_replicas"] == 1
    res = CliRunner().invoke(app, ["classify", str(folder)])
    assert "1 cell(s) with replicas, 0 robust under rule contacts, 0 not, 1 await replicas" in res.output


def test_cells_without_replicas_and_awaiting_them_are_drawn_apart_from_robust_ones() -> None:
    """An unreplicated cell looked like a robust one."""
    import matplotlib.pyplot as plt

    from somo_sweep.paper.fig6 import AWAITING_HATCH, UNCHECKED_ALPHA

    table = with_robustness(tidy({(0.1, 0.01): ["pinch", "pinch", "power"]}), set())
    table["replicas"] = [4, 0, 0]
    table["replicas_awaited"] = [0, 0, 4]
    table["robust"] = pd.array([True, pd.NA, pd.NA], dtype="boolean")
    fig, ax = plt.subplots()
    draw_dsr_panel(ax, table, 0.1)
    robust, bare, waiting = ax.patches
    plt.close(fig)
    assert robust.get_alpha() in (None, 1.0) and robust.get_hatch() is None
    assert bare.get_alpha() == UNCHECKED_ALPHA and bare.get_hatch() is None
    assert waiting.get_hatch() == AWAITING_HATCH
