"""A 12-link finger of one's own, through the whole chain on both engines: its bench CSV, ``calibrate``,
a gripper of the calibrated finger (``new grasp-study --finger``), a robust grasp study, its labels
and its plots.

The bench rows (examples/own_gripper/finger_bench.csv) are solved on an independent planar elastica
(tests/reference/rod.py), so the calibration is also checked against a truth our chain did not make.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from somo_sweep.cli.app import app

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "own_gripper"
#: The elastica's pressure gain, N·m/kPa (examples/own_gripper/make_bench_csv.py).
TRUE_GAIN_N_M_PER_KPA = 8e-4
SIMULATION = {
    "mujoco": {"engine": "mujoco", "time_step_s": 4e-3},
    # Within the explicit springs' stability limit of this finger's 1-g links once their inertia
    # is shaped (0.21 ms without; `somo-sweep check` prints it; NUMERICS below).
    "pybullet": {"engine": "pybullet", "time_step_s": 2.5e-4},
}


def _calibrated(folder: Path) -> Path:
    out = folder / "finger_calibrated.yaml"
    result = CliRunner().invoke(
        app,
        [
            "-q",
            "calibrate",
            str(EXAMPLE / "finger_bench.csv"),
            "--model",
            str(EXAMPLE / "finger.yaml"),
            "-o",
            str(out),
            "--report",
            str(folder / "calibration"),
        ],
    )
    assert result.exit_code == 0, result.output
    return out


#: Inertia shaping per link on PyBullet, kg·m² (numerics, not physics: docs/physics.md).
NUMERICS = {"mujoco": {}, "pybullet": {"numerics": {"added_inertia_kg_m2": 2e-8}}}
#: Centering positions (m) of the study: two cells on MuJoCo, one on PyBullet (16x the steps).
CENTERING_M = {"mujoco": [0.126, 0.154], "pybullet": [0.126]}


@pytest.mark.parametrize(
    "engine",
    ["mujoco", pytest.param("pybullet", marks=[pytest.mark.slow, pytest.mark.timeout(1200)])],
)
def test_a_twelve_link_finger_from_its_bench_csv_to_a_robust_grasp_map(tmp_path: Path, engine: str) -> None:
    finger = _calibrated(tmp_path)
    calibrated = yaml.safe_load(finger.read_text())
    gain = calibrated["manipulator"]["actuation"]["pressure_gain_n_m_per_kpa"]
    assert gain == pytest.approx(TRUE_GAIN_N_M_PER_KPA, rel=0.03)  # the elastica's, not our chain's
    report = json.loads(next((tmp_path / "calibration").glob("*.json")).read_text())
    assert report  # the report was written

    folder = tmp_path / "mine"
    result = CliRunner().invoke(app, ["new", "grasp-study", str(folder), "--finger", str(finger)])
    assert result.exit_code == 0, result.output
    study = yaml.safe_load((folder / "study.yaml").read_text())
    study["sweep"] = {
        "task.distal_segment_ratio": [0.25],
        "task.object_width_m": [0.04],
        "task.centering_position_m": CENTERING_M[engine],
    }
    study["params"].update(NUMERICS[engine])
    study["robustness"] = {"replicas": 2}
    study["simulation"] = SIMULATION[engine]
    (folder / "study.yaml").write_text(yaml.safe_dump(study))

    out = tmp_path / "grasp_map"
    result = CliRunner().invoke(app, ["run", str(folder / "study.yaml"), "--out", str(out), "--jobs", "1"])
    assert result.exit_code == 0, result.output
    table = pd.read_parquet(out / "trials")
    trials = table[table["replica"] == 0] if "replica" in table else table
    assert len(trials) == len(CENTERING_M[engine]) and (trials["status"] == "ok").all()
    assert (trials["n_finger_links"] == 12).all()
    assert (trials["n_distal_links"] == 3).all()
    assert trials["task_pressure_kpa"].eq(150).all()
    assert trials["hold_normal_force_n"].gt(0).all()  # the calibrated gain closed the fingers on the box
    assert set(trials["label_grasp"]) <= {"pinch", "power", "no_grasp"}
    assert set(trials["label_grasp_paper"]) <= {"pinch", "power", "no_grasp"}
    plots = out / "plots"
    assert (plots / "summary.png").stat().st_size > 0  # every trial's labels, whatever the grid
    maps = {p.name for p in plots.glob("label_map_*.png")}
    if len(CENTERING_M[engine]) > 1:  # a map needs an axis that varies: one cell has none
        assert maps == {"label_map_grasp.png", "label_map_grasp_paper.png"}
    else:
        assert maps == set()
