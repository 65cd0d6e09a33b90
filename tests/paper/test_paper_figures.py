"""The quick variants of the paper-figure targets (make fig3 / fig5-quick / fig8-quick / palm-quick).

(fig6-quick: tests/test_fig6.py; fig7-quick: tests/test_whole_arm.py.)

Each runs the same entry point as its ``make`` target into a temporary folder and checks
the files and the physical numbers written, so the targets cannot rot unseen.
"""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli import app
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.ihm_gait.task import UNBUILDABLE


def paper(*args: str) -> str:
    """Run ``somo-sweep paper ARGS`` and return what it printed (asserting exit code 0)."""
    result = CliRunner().invoke(app, ["paper", *args])
    assert result.exit_code == 0, result.output
    return result.output


def test_paper_help_lists_every_figure() -> None:
    text = CliRunner().invoke(app, ["paper", "--help"]).output
    for name in ("fig3", "fig5", "fig6", "fig7", "fig8", "palm"):
        assert f" {name} " in text


def test_fig3_writes_the_figure_and_the_fit_beats_eq8_9_on_blocked_force(tmp_path: Path) -> None:
    out = paper("fig3", "--out", str(tmp_path))
    assert (tmp_path / "fig3_blocked_force.png").stat().st_size > 10_000
    assert (tmp_path / "fig3_blocked_force.svg").read_text().startswith("<?xml")
    # Printed per method: "paper: ..." then its RMSE lines, then "fit: ...".
    paper_text, fit_text = out.split("\nfit: ")
    rmse = {
        name: float(re.search(r"blocked_force: RMSE ([0-9.e-]+) N", text).group(1))  # type: ignore[union-attr]
        for name, text in (("paper", paper_text), ("fit", fit_text))
    }
    assert rmse["paper"] == pytest.approx(0.159, abs=0.005)  # eq. (8)/(9) as published
    assert rmse["fit"] < 0.01


def test_fig8_quick_writes_the_figure_and_the_anisotropic_snake_advances(tmp_path: Path) -> None:
    paper("fig8", "--out", str(tmp_path), "--quick")
    assert {"fig8-quick.png", "fig8-quick.svg", "fig8-quick.json"} <= {p.name for p in tmp_path.iterdir()}
    numbers = json.loads((tmp_path / "fig8-quick.json").read_text())
    aniso, iso = numbers["anisotropic"], numbers["isotropic"]
    assert aniso["duration_s"] == pytest.approx(3.0)
    assert aniso["advance_body_widths"] > 3  # the 10-s run advances ~22 widths
    assert abs(iso["advance_body_widths"]) < 1


def test_palm_study_and_plot_give_rotation_and_drop_rate_and_cross_out_unbuildable_designs(
    tmp_path: Path,
) -> None:
    (tmp_path / "models").symlink_to(MODELS)
    study_file = tmp_path / "palm_tiny.yaml"
    study_file.write_text(
        textwrap.dedent(
            """\
            name: palm_tiny
            task: ihm_gait
            model: models/ihm_hand.yaml
            params: {duration_s: 3.0}
            sweep:
              task.palm_height_m: [0.085]
              task.palm_diameter_m: [0.030, 0.120]
            seed: 0
            simulation: {time_step_s: 1.0e-3, scale: 20}
            """
        )
    )
    summary = run_sweep(load_study(study_file, tmp_path / "palm_tiny"), RunOptions(n_jobs=2))
    # A 120 mm palm at 85 mm cuts through the fingers (inner faces ~49 mm from the axis there).
    assert summary.by_status == {"ok": 1, "error": 1}
    paper("palm", str(tmp_path / "palm_tiny"), "--out", str(tmp_path / "figures"))
    table = pd.read_csv(tmp_path / "figures" / "palm_tiny.csv").fillna({"note": ""})
    assert (tmp_path / "figures" / "palm_tiny.png").is_file()
    assert list(table["diameter_mm"]) == [30.0, 120.0] and set(table["height_mm"]) == {85.0}
    assert list(table["trials"]) == [1, 0]
    assert table["drop_rate"][0] == 0.0 and table["rot_z_per_cycle_deg"][0] < 0
    assert table["note"][0] == "" and UNBUILDABLE in table["note"][1]


def test_fig5_quick_writes_the_first_cycle_against_the_hardware(tmp_path: Path) -> None:
    paper("fig5", "--out", str(tmp_path), "--quick")
    summary = json.loads((tmp_path / "fig5-quick.json").read_text())
    assert summary["default"]["real_rot_z_deg"] == pytest.approx(-49.9, abs=1.0)
    assert -100.0 < summary["default"]["sim_rot_z_deg"] < -30.0
    # The finger fitted to the published bench values (make fig3's fit) and the map derived from it.
    values = summary["finger_calibration"]["values"]
    assert values["stiffness_n_m_per_rad[grasp]"] == pytest.approx(0.273, rel=0.01)
    assert values["pressure_gain_n_m_per_kpa"] == pytest.approx(6.42e-4, rel=0.01)
    weights = summary["finger_calibration"]["weights"]
    assert weights["w_side_n_m_per_psi"] / weights["w_grasp_n_m_per_psi"] == pytest.approx(3.25)
    assert -100.0 < summary["finger_calibrated"]["sim_rot_z_deg"] < -30.0
    # Off-axis motion of the same order as the hardware's (paper: x, y within 6 mm, tilt within 0.6 deg;
    # the recording over this first cycle: 2.1 mm, 1.4 mm in z, 0.44 deg).
    offaxis = summary["offaxis"]
    assert offaxis["hardware"]["max_abs_x_mm"] == pytest.approx(2.1, abs=0.1)
    for run in ("default", "finger_calibrated"):
        o = offaxis[run]
        assert max(o["max_abs_x_mm"], o["max_abs_y_mm"]) < 6.0 and o["max_abs_z_mm"] < 2.0
        assert max(o["max_abs_tilt_x_deg"], o["max_abs_tilt_y_deg"]) < 1.0
