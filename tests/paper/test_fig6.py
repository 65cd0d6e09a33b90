"""Fig. 6 table, headline and files; the classify and fig6 commands on a hand-made results folder."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.paper.fig6 import build, grasp_table, smallest_all_width_pinch_dsr
from somo_sweep.tasks.pinch_grasp.legacy import legacy_columns


def tidy(labels: dict[tuple[float, float], list[str]]) -> pd.DataFrame:
    """Rows for {(dsr, width): labels over centering positions c = 70, 75, ... mm}."""
    rows = [
        {
            "distal_segment_ratio": d,
            "object_width_m": w,
            "centering_position_m": 0.07 + 0.005 * i,
            "label": lab,
        }
        for (d, w), labs in labels.items()
        for i, lab in enumerate(labs)
    ]
    return pd.DataFrame(rows)


def test_smallest_dsr_needs_a_pinch_at_every_width() -> None:
    table = tidy(
        {
            (0.1, 0.01): ["power", "pinch"],
            (0.1, 0.12): ["power", "no_grasp"],
            (0.2, 0.01): ["power", "pinch"],
            (0.2, 0.12): ["pinch", "no_grasp"],
            (0.3, 0.01): ["pinch", "pinch"],
            (0.3, 0.12): ["pinch", "pinch"],
        }
    )
    assert smallest_all_width_pinch_dsr(table) == 0.2
    assert smallest_all_width_pinch_dsr(table[table["distal_segment_ratio"] < 0.15]) is None


def test_fig6_build_returns_figure_summary_and_headline() -> None:
    table = tidy(
        {(0.1, 0.01): ["power", "pinch"], (0.1, 0.04): ["pinch", "no_grasp"], (0.6, 0.01): ["pinch"] * 2}
    )
    out = build(table)
    info = out.json["fig6.json"]
    assert info["smallest_all_width_pinch_dsr"] == 0.1
    assert info["labels"] == {"pinch": 4, "power": 1, "no_grasp": 1}
    assert list(out.figures) == ["fig6"] and out.formats == ("png", "svg")
    summary = out.tables["fig6_summary.csv"]
    assert set(summary.columns) >= {"distal_segment_ratio", "object_width_m", "pinch", "power", "no_grasp"}
    assert out.lines[-1] == "smallest all-width pinch DSR: 0.10"


def test_trials_without_an_outcome_are_drawn_in_the_legend_and_qualify_the_headline() -> None:
    """An all-error folder crashed the legend (ncol=0); failed cells silently moved the headline."""
    import matplotlib.pyplot as plt

    some = build(
        tidy(
            {
                (0.1, 0.01): ["power", "error"],
                (0.1, 0.04): ["pinch", "unstable"],
                (0.3, 0.01): ["pinch", "power"],
                (0.3, 0.04): ["power", "pinch"],
            }
        )
    )
    legend = [t.get_text() for t in some.figures["fig6"].legends[0].get_texts()]
    assert legend == ["pinch", "power", "unstable", "error"]
    assert some.lines[-1] == (
        "smallest all-width pinch DSR: 0.30 (0.10 if the 2 trial(s) without an outcome were pinches)"
    )
    assert some.json["fig6.json"]["trials_without_outcome"] == 2
    failed = build(tidy({(0.1, 0.01): ["error", "error"], (0.2, 0.01): ["error"]}))
    assert (
        failed.lines[-1]
        == "no DSR pinch-grasps every width (0.10 if the 3 trial(s) without an outcome were pinches)"
    )
    same = build(tidy({(0.1, 0.01): ["pinch", "error"], (0.2, 0.01): ["error", "error"]}))
    assert same.lines[-1].endswith("(the same whatever the 3 trial(s) without an outcome would give)")
    plt.close("all")


def test_fig6_axis_is_the_papers_centering_with_the_bases_distance_on_top() -> None:
    out = build(tidy({(0.1, 0.01): ["power", "pinch", "pinch"]}))
    ax = out.figures["fig6"].axes[0]
    assert ax.get_xlabel() == "centering position c (mm)"
    (top,) = ax.child_axes  # the secondary axis: d = 200 mm − c
    assert top.get_xlabel().startswith("bases' distance d")
    assert ax.get_xlim() == pytest.approx((67.5, 82.5))  # cells centred on c = 70, 75, 80 mm
    assert "d = 200 mm − c" in out.figures["fig6"]._suptitle.get_text()


def results_folder(
    tmp_path: Path, centering_column: str = "task_centering_position_m", final_counts: bool = False
) -> Path:
    """A results folder in the sweep engine's layout with two pinch_grasp rows and one blow-up."""
    rows = []
    for i, (per_link, final, status) in enumerate(
        [({20: 1.0, 21: 1.0}, 20.5, "ok"), ({3: 1.0, 19: 1.0}, 20.0, "ok"), ({}, float("nan"), "unstable")]
    ):
        row: dict[str, object] = {
            "job_id": f"job{i}",
            "trial": i,
            "status": status,
            "study_hash": "h",
            "task_distal_segment_ratio": 0.2,
            "task_object_width_m": 0.04,
            centering_column: 0.1 + 0.005 * i,
            "task_lift_m": 0.075,
            "object_x_m": 0.0,
            "object_y_m": 0.0,
            "object_z_m": 0.1,
            "lift_height_m": 0.07,
            "hold_normal_force_n_palm": 0.0,
            "hold_contact_fraction_both_fingers": 1.0,
            "hold_ground_contact_fraction": 0.0,
            "final_mean_contact_link": final,
            "hold_contact_count_palm": 0,
        }
        for k, name in enumerate(legacy_columns("hold_normal_force_n"), start=1):
            row[name] = per_link.get(k, 0.0)
        if final_counts:
            for k, name in enumerate(["final_contact_count_base", *legacy_columns("final_contact_count")]):
                row[name] = 0 if status != "ok" else int(k == 16)  # one contact on link 16: mean 16
        rows.append(row)
    folder = tmp_path / "results" / "pinch"
    (folder / "trials").mkdir(parents=True)
    (folder / "manifest.json").write_text(json.dumps({"study_hash": "h"}))
    pd.DataFrame(rows).to_parquet(folder / "trials" / "part-0.parquet")
    return folder


def test_classify_command_relabels_from_stored_metrics(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    result = CliRunner().invoke(app, ["classify", str(folder)])
    assert result.exit_code == 0, result.output
    labels = pd.read_csv(folder / "grasp_labels_contacts.csv")
    assert labels["grasp_contacts"].tolist() == ["pinch", "power", "unstable"]
    result = CliRunner().invoke(app, ["classify", str(folder), "--rule", "paper"])
    assert pd.read_csv(folder / "grasp_labels_paper.csv")["grasp_paper"].tolist() == [
        "pinch",
        "pinch",
        "unstable",
    ]
    # Stored before the final step's per-part counts: relabelled where the stored mean decides.
    assert "note: 2 trials were stored before the final step's per-part contact counts" in result.output


def test_classify_paper_rule_uses_the_final_per_part_counts(tmp_path: Path) -> None:
    folder = results_folder(tmp_path, final_counts=True)
    result = CliRunner().invoke(app, ["classify", str(folder), "--rule", "paper"])
    assert result.exit_code == 0, result.output
    # Mean link 16 at DSR 0.2: 16 / 20 is not above 0.8, whatever the stored (older) mean says.
    labels = pd.read_csv(folder / "grasp_labels_paper.csv")["grasp_paper"].tolist()
    assert labels == ["power", "power", "unstable"]
    assert "note:" not in result.output


def test_fig6_command_prints_the_headline_and_writes_files(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    result = CliRunner().invoke(app, ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig")])
    assert result.exit_code == 0, result.output
    assert "smallest all-width pinch DSR: 0.20" in result.output
    assert (tmp_path / "fig" / "fig6_contacts.png").exists()
    assert json.loads((folder / "fig6_contacts.json").read_text())["smallest_all_width_pinch_dsr"] == 0.2


def test_bad_rule_and_missing_folder_are_user_errors(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    result = CliRunner().invoke(app, ["classify", str(folder), "--rule", "papr"])
    assert result.exit_code == 2
    assert "did you mean 'paper'" in result.output
    result = CliRunner().invoke(app, ["classify", str(tmp_path / "nope")])
    assert result.exit_code == 2


def test_fig6_refuses_a_folder_made_before_the_papers_centering_position(tmp_path: Path) -> None:
    # Old folders stored centering_m, the bases' distance d to the chain starts: never plotted as c.
    folder = results_folder(tmp_path, centering_column="task_centering_m")
    result = CliRunner().invoke(app, ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig")])
    assert result.exit_code == 2
    assert "before the geometry change" in result.output and "centering_position_m" in result.output
    result = CliRunner().invoke(app, ["classify", str(folder)])
    assert result.exit_code == 0, result.output  # relabelling does not read the axis
    # and keeps the old column under its own name
    assert "task_centering_m" in pd.read_csv(folder / "grasp_labels_contacts.csv").columns


def test_grasp_table_marks_blow_ups(tmp_path: Path) -> None:
    from somo_sweep.paper.grasp_trials import read_results

    table = grasp_table(read_results(results_folder(tmp_path)))
    assert table["label"].tolist() == ["pinch", "power", "unstable"]


def test_fig6_quick_pipeline_runs_real_trials_and_draws_the_figure(tmp_path: Path) -> None:
    # make fig6(-quick) end to end on two real trials: somo-sweep run, then somo-sweep fig6.
    from conftest import MODELS

    (tmp_path / "models").symlink_to(MODELS)
    study = tmp_path / "pinch_tiny.yaml"
    study.write_text(
        "name: pinch_tiny\ntask: pinch_grasp\nmodel: models/pinch_gripper.yaml\n"
        "sweep:\n  task.distal_segment_ratio: [0.1, 0.5]\n  task.object_width_m: [0.080, 0.120]\n"
        "  task.centering_position_m: [0.085, 0.115]\n"
        "link: [[task.distal_segment_ratio, task.object_width_m, task.centering_position_m]]\n"
        "seed: 0\nparams: {numerics: {added_inertia_kg_m2: 3.0e-5}}\n"
        "simulation: {time_step_s: 4.0e-3, scale: 20, solver_iterations: 50}\n"
    )
    folder = tmp_path / "results" / "pinch_tiny"
    result = CliRunner().invoke(app, ["run", str(study), "--out", str(folder), "--jobs", "2"])
    assert result.exit_code == 0, result.output
    result = CliRunner().invoke(app, ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "fig" / "fig6_contacts.png").stat().st_size > 10_000
    summary = pd.read_csv(tmp_path / "fig" / "fig6_contacts_summary.csv")
    assert len(summary) == summary[["distal_segment_ratio", "object_width_m"]].drop_duplicates().shape[0] >= 1
    # A long distal segment pinches the 80 mm box at its fingertips; a hand close to a wide box wraps it.
    trials = pd.read_parquet(folder / "trials").sort_values("task_distal_segment_ratio")
    assert trials["status"].tolist() == ["ok", "ok"]
    assert trials["label_grasp"].tolist() == ["pinch", "power"]


def test_cells_an_adaptive_run_inferred_keep_their_stored_label_and_are_drawn(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    inferred = {
        "job_id": "job3",
        "trial": 3,
        "status": "ok",
        "study_hash": "h",
        "task_distal_segment_ratio": 0.2,
        "task_object_width_m": 0.04,
        "task_centering_position_m": 0.115,
        "label_grasp": "power",
        "label_grasp_paper": "pinch",
        "inferred": True,
    }
    pd.DataFrame([inferred]).to_parquet(folder / "inferred.parquet")
    from somo_sweep.paper.grasp_trials import read_results

    table = grasp_table(read_results(folder))
    assert table["label"].tolist() == ["pinch", "power", "unstable", "power"]
    assert table["inferred"].tolist() == [False, False, False, True]
    assert grasp_table(read_results(folder), "paper")["label"].tolist()[-1] == "pinch"
    result = CliRunner().invoke(app, ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig")])
    assert result.exit_code == 0, result.output
    assert "4 trials (1 inferred, not simulated)" in result.output
    assert json.loads((folder / "fig6_contacts.json").read_text())["inferred"] == 1
    result = CliRunner().invoke(app, ["classify", str(folder)])
    assert result.exit_code == 0, result.output
    labels = pd.read_csv(folder / "grasp_labels_contacts.csv")
    assert labels["grasp_contacts"].tolist()[-1] == "power" and labels["inferred"].tolist()[-1]


@pytest.mark.parametrize(
    ("max_dsr", "message"),
    [
        (float("nan"), "--max-dsr must be from 0 to 1, got nan"),
        (-5.0, "--max-dsr must be from 0 to 1, got -5"),
        (2.0, "--max-dsr must be from 0 to 1, got 2"),
        (0.05, "--max-dsr 0.05 draws nothing: the smallest DSR in the results is 0.1"),
    ],
)
def test_a_max_dsr_that_draws_nothing_is_refused(max_dsr: float, message: str) -> None:
    """NaN or -5 drew an empty figure and wrote it as if it were Fig. 6."""
    from somo_sweep.errors import SomoError
    from somo_sweep.paper.fig6 import check_max_dsr

    with pytest.raises(SomoError, match=re.escape(message)):
        check_max_dsr(max_dsr, pd.Series([0.1, 0.2, 0.1]))
    check_max_dsr(0.1, pd.Series([0.1, 0.2]))
