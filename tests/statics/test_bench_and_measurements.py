"""Bench protocols, the measurement CSV schema and `somo-sweep measure`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import MODELS, ihm_finger_dict
from typer.testing import CliRunner

from somo_sweep.calibration.measurements import (
    COLUMNS,
    measurements_csv,
    read_measurements,
    simulate_measurements,
)
from somo_sweep.cli.app import app
from somo_sweep.errors import MeasurementError, SimulationError
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.load import load_model, model_from_dict
from somo_sweep.statics.bench import BenchSettings, run_bench

runner = CliRunner()


def test_measure_prints_schema_rows_that_round_trip(tmp_path: Path) -> None:
    out = tmp_path / "rows.csv"
    res = runner.invoke(
        app,
        [
            "measure",
            str(MODELS / "ihm_finger.yaml"),
            "--test",
            "blocked_force",
            "--values",
            "0,50,100",
            "--csv",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    assert ",".join(COLUMNS) in res.stdout
    rows = read_measurements(out)
    assert list(rows["pressure_kpa"]) == [0.0, 50.0, 100.0]
    force = rows["blocked_force_n"].to_numpy()
    assert np.all(np.diff(force) > 0)  # more pressure, more force
    # the round trip reproduces the simulation
    again = simulate_measurements(load_model(MODELS / "ihm_finger.yaml"), rows)
    np.testing.assert_allclose(again["blocked_force_n"], force, rtol=1e-5)


def test_measure_tip_load_and_free_bending_cli() -> None:
    res = runner.invoke(
        app,
        ["measure", str(MODELS / "ihm_finger.yaml"), "--test", "tip_load", "--values", "0.02,0.05"],
    )
    assert res.exit_code == 0, res.output
    assert "tip_load,0,0.02," in res.stdout
    res = runner.invoke(
        app,
        ["measure", str(MODELS / "ihm_finger.yaml"), "--test", "free_bending", "--values", "100"],
    )
    assert res.exit_code == 0
    lines = res.stdout.strip().splitlines()
    row = dict(zip(lines[-2].split(","), lines[-1].split(","), strict=True))
    x_mm, z_mm, angle_deg = (float(row[c]) for c in ("tip_x_mm", "tip_z_mm", "tip_angle_deg"))
    assert z_mm < -20 and 0 < x_mm < 130  # curled toward -z
    assert 20 < angle_deg < 180


def test_measure_rejects_unknown_test_and_negative_load() -> None:
    res = runner.invoke(
        app, ["measure", str(MODELS / "ihm_finger.yaml"), "--test", "tipload", "--values", "1"]
    )
    assert res.exit_code == 2 and "allowed: tip_load, blocked_force, free_bending" in res.output
    res = runner.invoke(
        app, ["measure", str(MODELS / "ihm_finger.yaml"), "--test", "tip_load", "--values", "-1"]
    )
    assert (
        res.exit_code == 2
        and "--values -1 is outside what a bench measures; allowed: 0 to 1000 N" in res.output
    )


def test_free_bending_curls_down_and_tip_load_deflects_down() -> None:
    model = model_from_dict(ihm_finger_dict(motor_limit=0.0))
    weightless = run_bench(model, "free_bending", 0.0, settings=BenchSettings(gravity_m_s2=0.0)).value
    sagging = run_bench(model, "free_bending", 0.0).value
    bent = run_bench(model, "free_bending", 150.0).value
    assert isinstance(weightless, tuple) and isinstance(sagging, tuple) and isinstance(bent, tuple)
    assert weightless == pytest.approx((130.0, 0.0, 0.0), abs=1e-4)  # 100 mm chain + 30 mm sphere
    assert sagging[1] < -5 and np.hypot(*sagging[:2]) == pytest.approx(130.0, abs=2.0)  # sags, rigid links
    assert 0 < sagging[2] < bent[2]  # the tip tilts down under its weight, further with pressure
    assert bent[1] < sagging[1] - 20
    small, large = (run_bench(model, "tip_load", 0.0, f).value for f in (0.02, 0.04))
    assert 0 < small < large


@pytest.mark.parametrize("pressure_kpa", [50.0, 200.0])
def test_free_bending_tip_angle_is_the_sum_of_the_joint_angles_even_past_180_degrees(
    pressure_kpa: float,
) -> None:
    """Weightless finger, uniform joint torque u = gain·p: every joint turns u/k, so the tip
    turns N·u/k (1 rad at 50 kPa; 4 rad = 229° at 200 kPa, read unwrapped, not as −131°)."""
    model = planar_finger(0.100, 20, 0.020, stiffness_n_m_per_rad=0.5, pressure_gain_n_m_per_kpa=5e-4)
    weightless = BenchSettings(gravity_m_s2=0.0, time_step_s=1e-3)
    x_mm, z_mm, angle_deg = run_bench(model, "free_bending", pressure_kpa, settings=weightless).value  # type: ignore[misc]
    theta_rad = 20 * 5e-4 * pressure_kpa / 0.5
    assert angle_deg == pytest.approx(np.degrees(theta_rad), rel=1e-4)
    # The tip of the midpoint chain: a half link along x, 19 links turning θ/20 more each, and a
    # last half link at θ: a polygon inscribed in a circle.
    phi = theta_rad / 20 * np.arange(21)
    lengths_mm = np.array([2.5, *[5.0] * 19, 2.5])
    assert x_mm == pytest.approx(np.sum(lengths_mm * np.cos(phi)), abs=0.05)
    assert z_mm == pytest.approx(-np.sum(lengths_mm * np.sin(phi)), abs=0.05)


def test_blocked_force_at_zero_pressure_is_part_of_the_finger_weight() -> None:
    model = model_from_dict(ihm_finger_dict(motor_limit=0.0))
    force = run_bench(model, "blocked_force", 0.0).value
    weight_n = 9.81 * (10 * 0.00294 + 0.015)
    assert 0 < force < weight_n


def test_pressure_without_actuation_map_is_an_error() -> None:
    data = ihm_finger_dict()
    del data["manipulator"]["actuation"]
    with pytest.raises(SimulationError, match="no 'actuation'"):
        run_bench(model_from_dict(data), "free_bending", 10.0)


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.csv"
    path.write_text(text)
    return path


HEADER = ",".join(COLUMNS)


def test_reader_names_row_and_column_of_every_problem(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        f"# a comment line\n{HEADER}\n"
        "tip_load,0,0.05,abc,,,\n"
        "tipload,0,0.05,1.0,,,\n"
        "tip_load,0,-0.1,1.0,,,\n"
        "blocked_force,100,,,,,\n",
    )
    with pytest.raises(MeasurementError) as err:
        read_measurements(path)
    text = str(err.value)
    assert "line 3, column tip_deflection_mm: 'abc' is not a number" in text
    assert "line 4, column test: unknown test 'tipload' (did you mean 'tip_load'?)" in text
    assert "line 5, column tip_load_n: -0.1 is outside what a bench measures; allowed: 0 to 1000 N" in text
    assert "line 6, column blocked_force_n: empty" in text


def test_reader_rejects_missing_and_unknown_columns(tmp_path: Path) -> None:
    path = _write(tmp_path, "test,pressure_kpa,tip_load_n,tip_deflecton_mm\n")
    with pytest.raises(MeasurementError) as err:
        read_measurements(path)
    assert "missing column(s)" in str(err.value)
    assert "did you mean 'tip_deflection_mm'" in str(err.value)


def test_reader_keeps_optional_axis_and_direction(tmp_path: Path) -> None:
    path = _write(tmp_path, f"{HEADER},axis,direction\ntip_load,0,0.05,3.0,,,,grasp,loading\n")
    rows = read_measurements(path)
    assert rows.loc[0, "axis"] == "grasp" and rows.loc[0, "direction"] == "loading"
    bad = _write(tmp_path, f"{HEADER},axis\ntip_load,0,0.05,3.0,,,,sideways\n")
    with pytest.raises(MeasurementError, match="allowed: grasp, side"):
        read_measurements(bad)


def test_tip_angle_column_is_optional_free_bending_only_and_round_trips(tmp_path: Path) -> None:
    plain = read_measurements(_write(tmp_path, f"{HEADER}\nfree_bending,100,,,,90,-30\n"))
    assert np.isnan(plain.loc[0, "tip_angle_deg"])
    assert "tip_angle_deg" not in measurements_csv(plain)
    path = _write(
        tmp_path, f"{HEADER},tip_angle_deg\nfree_bending,100,,,,90,-30,41.5\nblocked_force,100,,,0.7,,,\n"
    )
    rows = read_measurements(path)
    assert rows.loc[0, "tip_angle_deg"] == 41.5 and np.isnan(rows.loc[1, "tip_angle_deg"])
    again = tmp_path / "again.csv"
    again.write_text(measurements_csv(rows))
    assert read_measurements(again).loc[0, "tip_angle_deg"] == 41.5
    bad = _write(tmp_path, f"{HEADER},tip_angle_deg\ntip_load,0,0.05,3.0,,,,12\n")
    with pytest.raises(MeasurementError, match="line 2, column tip_angle_deg: only 'free_bending' rows"):
        read_measurements(bad)


def test_writer_header_comment_is_read_back(tmp_path: Path) -> None:
    rows = pd.DataFrame(
        [
            {
                "test": "blocked_force",
                "pressure_kpa": 100.0,
                "tip_load_n": np.nan,
                "tip_deflection_mm": np.nan,
                "blocked_force_n": 0.75,
                "tip_x_mm": np.nan,
                "tip_z_mm": np.nan,
            }
        ]
    )
    path = tmp_path / "w.csv"
    path.write_text(measurements_csv(rows, header="derived from published values\nnot measured"))
    assert path.read_text().startswith("# derived from published values\n# not measured\n")
    assert read_measurements(path).loc[0, "blocked_force_n"] == 0.75


def test_missing_file_is_a_measurement_error(tmp_path: Path) -> None:
    with pytest.raises(MeasurementError, match="file not found"):
        read_measurements(tmp_path / "nope.csv")


def test_blocked_force_keeps_rising_when_the_tip_curls_back_along_the_stop() -> None:
    """A strongly curled tip slides back along x; it must stay on the plate, not read 0 N."""
    model = load_model(MODELS / "ihm_finger.yaml")
    forces = [run_bench(model, "blocked_force", p).value for p in (200.0, 240.0, 300.0)]
    assert all(isinstance(f, float) and f > 1.0 for f in forces)
    assert forces[0] < forces[1] < forces[2]


@pytest.mark.parametrize("name", ["pinch_finger", "ihm_finger"])
def test_unpressurised_blocked_force_is_at_most_the_fingers_weight(name: str) -> None:
    """Closed-form bound: at 0 kPa the plate can carry no more than the weight of what rests on
    it. The pinch finger's tip is thinner than its segments; the plate used to sit at the tip's
    underside, inside the segments, and read 259.55 N for a 56-g finger."""
    manip = load_model(MODELS / f"{name}.yaml").manipulator
    assert manip is not None
    mass_kg = sum(a.segments * a.segment_link().mass_kg for a in manip.actuators)
    mass_kg += sum(t.mass_kg for t in manip.tip_links)
    value = run_bench(manip, "blocked_force", pressure_kpa=0.0).value
    assert isinstance(value, float)
    assert 0.0 < value <= 9.81 * mass_kg * 1.001


def test_a_chain_bending_about_its_own_axis_is_refused_as_such_not_as_an_equilibrium() -> None:
    data = ihm_finger_dict()
    data["manipulator"]["actuators"][0]["joints"][0]["axis"] = [0, 0, 1]
    with pytest.raises(SimulationError) as err:
        run_bench(model_from_dict(data), "free_bending", 0.0)
    assert "must not be the chain axis (z)" in str(err.value)
    assert "no static equilibrium" not in str(err.value)


def test_check_says_when_a_mounted_manipulators_own_base_mode_is_not_used(tmp_path: Path) -> None:
    finger = {
        "actuators": [
            {
                "length_m": 0.04,
                "n_segments": 2,
                "link": {"shape": "box", "size_m": [0.01, 0.01], "mass_kg": 0.001},
                "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": 1.0}],
            }
        ]
    }
    hand = {
        "assembly": {
            "name": "hand",
            "base": {"mode": "fixed"},
            "manipulators": [
                {"name": "a", "manipulator": finger | {"base": {"mode": "free"}}},
                {"name": "b", "manipulator": finger | {"base": {"mode": "fixed"}}},
            ],
        }
    }
    path = tmp_path / "hand.json"
    path.write_text(json.dumps(hand))
    res = CliRunner().invoke(app, ["check", str(path)])
    assert res.exit_code == 0, res.output
    assert "note: a: its own base mode 'free' is not used" in res.output and "note: b" not in res.output


def test_check_notes_a_joint_axis_outside_its_link(tmp_path: Path) -> None:
    """A finger written in mm (offset 6 where 0.006 m was meant) passed without a word."""
    data = ihm_finger_dict()
    data["manipulator"]["actuators"][0]["joints"][0]["offset_m"] = [0.0, -6.0, 0.0]
    path = tmp_path / "mm.json"
    path.write_text(json.dumps(data))
    res = CliRunner().invoke(app, ["check", str(path)])
    assert res.exit_code == 0, res.output
    assert "puts the axis outside the link's cross-section" in res.output
    path.write_text(json.dumps(ihm_finger_dict()))
    assert "outside the link" not in CliRunner().invoke(app, ["check", str(path)]).output
