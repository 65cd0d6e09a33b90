"""Calibration: the paper's eq. (8)/(9), the simulator-in-the-loop fit, the CLI and its errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from conftest import MODELS, ROOT
from typer.testing import CliRunner

from somo_sweep.calibration.formulas import (
    actuation_torque_from_blocked_force,
    chain_tip_stiffness,
    joint_stiffness_from_tip_stiffness,
)
from somo_sweep.calibration.measurements import measurements_csv, read_measurements
from somo_sweep.calibration.meter import metered
from somo_sweep.calibration.metrics import per_test_metrics
from somo_sweep.calibration.solve import build_problem, paper_values, side_view, simulate_rows, solve_fit
from somo_sweep.calibration.synthetic import (
    TRUE_GAIN_N_M_PER_KPA,
    TRUE_STIFFNESS_N_M_PER_RAD,
    bench_plan,
    synthetic_rows,
)
from somo_sweep.cli.app import app
from somo_sweep.errors import MeasurementError
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.load import load_model
from somo_sweep.statics.bench import BenchSettings, run_bench

runner = CliRunner()
DATA = ROOT / "studies" / "tables"
SYNTHETIC = DATA / "planar_finger_synthetic.csv"
FIG3 = DATA / "ihm_fig3_published.csv"
BUILD = ["--length-mm", "100", "--segments", "20", "--mass-g", "20"]

WORKED_EXAMPLE = """test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm,axis
tip_load,0,0.0612,10,,,,grasp
tip_load,0,0.2905,10,,,,side
blocked_force,100,,,0.75,,,grasp
"""


def _csv(tmp_path: Path, text: str, name: str = "rows.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --- eq. (8) and (9) as published -------------------------------------------------------------


def test_paper_method_reproduces_somo_worked_example(tmp_path: Path) -> None:
    rows = read_measurements(_csv(tmp_path, WORKED_EXAMPLE))
    problem = build_problem(rows, load_model(MODELS / "ihm_finger.yaml"), min_rows_per_parameter=1)
    values = dict(zip((p.name for p in problem.parameters), paper_values(problem), strict=True))
    assert values["stiffness_n_m_per_rad[grasp]"] == pytest.approx(0.219, abs=5e-4)
    assert values["stiffness_n_m_per_rad[side]"] == pytest.approx(1.038, abs=5e-4)
    # 0.75 N at 100 kPa -> M_act = 0.075 N·m
    assert values["pressure_gain_n_m_per_kpa"] * 100 == pytest.approx(0.075, rel=1e-9)


def test_paper_cli_writes_calibrated_model_with_provenance_and_report(tmp_path: Path) -> None:
    out, report = tmp_path / "out" / "model.yaml", tmp_path / "report"
    res = runner.invoke(
        app,
        [
            "calibrate",
            str(_csv(tmp_path, WORKED_EXAMPLE)),
            "--model",
            str(MODELS / "ihm_finger.yaml"),
            "--method",
            "paper",
            "-o",
            str(out),
            "--report",
            str(report),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "calibration rows: blocked_force (1: lines 4); tip_load (2: lines 2, 3)" in res.stdout
    model = load_model(out)
    joints = model.manipulator.actuators[0].joints  # type: ignore[union-attr]
    assert joints[0].stiffness_n_m_per_rad == pytest.approx(0.2186, rel=1e-3)
    assert joints[1].stiffness_n_m_per_rad == pytest.approx(1.0375, rel=1e-3)
    record = model.provenance["calibration"]  # type: ignore[index]
    assert record["method"] == "paper" and record["calibration_lines"] == [2, 3, 4]
    assert {t["label"] for t in record["tests"]} == {"tip_load", "tip_load[side]", "blocked_force"}
    assert sorted(p.name for p in report.iterdir()) == [
        "blocked_force.png",
        "calibration.json",
        "tip_load.png",
        "tip_load_side.png",
    ]
    # provenance does not change what the model is
    assert model.content_hash() == model.model_copy(update={"provenance": None}).content_hash()


# --- what eq. (8) and (9) miss on a discrete chain (docs/calibration.md) ------------------------


def test_eq8_on_every_joint_makes_the_chain_stiffer_than_measured() -> None:
    # 20 equal joints at 0, 5, ..., 95 mm, load at the 100 mm tip, measured 10 N/m
    length_m, n, measured = 0.1, 20, 10.0
    kappa = joint_stiffness_from_tip_stiffness(measured, length_m, n)
    joints_m = np.arange(n) * length_m / n
    chain = chain_tip_stiffness([kappa] * n, joints_m, length_m)
    assert chain / measured == pytest.approx(1.89, abs=0.01)  # eq. (8) ~1.9x too stiff at N = 20
    # the IHM finger's 5 grasp joints (0, 20, ..., 80 mm), load at 100 mm: 1.62x
    ihm = chain_tip_stiffness(
        [joint_stiffness_from_tip_stiffness(6.12, 0.1, 5)] * 5, [0, 0.02, 0.04, 0.06, 0.08], 0.1
    )
    assert ihm / 6.12 == pytest.approx(1.62, abs=0.01)


def test_eq9_overestimates_the_moment_a_blocked_tip_balances() -> None:
    # Small angles, uniform torque u on every joint, tip held at zero deflection:
    # sum_j (u - F·a_j)·a_j / k = 0  =>  F = u·Σa / Σa²  (not u / L)
    arms_m = 0.1 - np.arange(20) * 0.005
    force_per_torque = arms_m.sum() / (arms_m**2).sum()
    ratio = actuation_torque_from_blocked_force(force_per_torque, 0.1)  # M_eq9 / u
    assert ratio == pytest.approx(1.463, abs=0.005)


def test_paper_method_lands_far_from_the_truth_on_the_bundled_planar_finger() -> None:
    problem = build_problem(read_measurements(SYNTHETIC), _example_base(), str(SYNTHETIC))
    stiffness, gain = paper_values(problem)
    # eq. (8) vs the midpoint chain: L²/Σa² / (3/(2N) − 1/(2N²)) = 2.04 at N = 20, plus the noise of
    # the measured tip-load slope.
    assert stiffness / TRUE_STIFFNESS_N_M_PER_RAD == pytest.approx(2.04, abs=0.1)
    assert gain / TRUE_GAIN_N_M_PER_KPA == pytest.approx(1.80, abs=0.05)


# --- the problem and the fit ------------------------------------------------------------------


def _example_base():  # type: ignore[no-untyped-def]
    return planar_finger(0.1, 20, 0.02)


def test_problem_says_which_rows_calibrate_and_which_validate() -> None:
    problem = build_problem(read_measurements(SYNTHETIC), _example_base(), str(SYNTHETIC))
    assert set(problem.calibration_rows["test"]) == {"tip_load", "blocked_force"}
    assert len(problem.calibration_rows) == 23
    assert set(problem.validation_rows["test"]) == {"free_bending"} and len(problem.validation_rows) == 13
    assert [p.name for p in problem.parameters] == [
        "stiffness_n_m_per_rad[grasp]",
        "pressure_gain_n_m_per_kpa",
    ]
    # closed-form starting values are already within 10 % of the truth
    assert problem.parameters[0].initial == pytest.approx(TRUE_STIFFNESS_N_M_PER_RAD, rel=0.1)
    assert problem.parameters[1].initial == pytest.approx(TRUE_GAIN_N_M_PER_KPA, rel=0.1)
    assert "validation rows: free_bending (13: lines 29, 30" in problem.describe()  # after 4 comment lines


def test_problem_extends_with_an_extra_effect_parameter() -> None:
    """Diagnosis appends parameters; residuals and solvers stay the same."""
    from dataclasses import replace

    from somo_sweep.calibration.solve import Parameter

    def set_tip_mass(manip, value):  # type: ignore[no-untyped-def]
        link = manip.actuators[0].link.model_copy(update={"mass_kg": value})
        return manip.model_copy(update={"actuators": [manip.actuators[0].model_copy(update={"link": link})]})

    problem = build_problem(read_measurements(SYNTHETIC), _example_base(), str(SYNTHETIC))
    extended = replace(
        problem, parameters=(*problem.parameters, Parameter("link_mass_kg", "kg", 1e-3, set_tip_mass))
    )
    manip = extended.manipulator_at([0.5, 2e-4, 3e-3])
    assert manip.actuators[0].joints[0].stiffness_n_m_per_rad == pytest.approx(0.5)
    assert manip.actuation is not None and manip.actuation.pressure_gain_n_m_per_kpa == pytest.approx(2e-4)
    assert manip.actuators[0].link.mass_kg == pytest.approx(3e-3)


def _small_truth():  # type: ignore[no-untyped-def]
    return planar_finger(0.1, 8, 0.02, stiffness_n_m_per_rad=0.3, pressure_gain_n_m_per_kpa=1.5e-4)


def test_fit_recovers_known_parameters_short() -> None:
    """Short version of the acceptance test: 8 segments, 12 rows, 1 % noise, seed 0."""
    plan = bench_plan([0.025, 0.05, 0.075, 0.1], [60, 120, 180, 240], [60, 120, 180, 240])
    rows = synthetic_rows(
        _small_truth(), plan, 0.01, np.random.default_rng(0), BenchSettings(time_step_s=1e-3)
    )
    rows["line"] = np.arange(len(rows)) + 2
    base = planar_finger(0.1, 8, 0.02)
    reports: list[tuple[int, int]] = []
    with metered(lambda done, expected: reports.append((done, expected))):
        result = solve_fit(build_problem(rows, base), n_jobs=1)
    # The progress bar counted every bench row, and the first estimate was an upper bound.
    assert reports[-1][0] == result.simulations
    assert all(done <= expected for done, expected in reports)
    assert reports[0][1] >= result.simulations
    assert result.values["stiffness_n_m_per_rad[grasp]"] == pytest.approx(0.3, rel=0.03)
    assert result.values["pressure_gain_n_m_per_kpa"] == pytest.approx(1.5e-4, rel=0.03)
    assert result.reproduces_within(0.05), result.metrics
    assert result.metric("free_bending").role == "validation"


@pytest.mark.slow
def test_fit_recovers_both_axes_of_a_two_axis_finger() -> None:
    """~40 s on the shared machine; the side view itself is checked fast against a closed form below."""
    from somo_sweep.calibration.parameters import set_axis_stiffness, set_pressure_gain

    base = load_model(MODELS / "ihm_finger.yaml")
    assert base.manipulator is not None
    truth = set_axis_stiffness(set_axis_stiffness(base.manipulator, 0.26, 0), 1.2, 1)
    truth = set_pressure_gain(truth, 6e-4)
    side = bench_plan([0.02, 0.04, 0.06], [], [])
    side["axis"] = "side"
    plan = pd.concat([bench_plan([0.02, 0.04, 0.06], [50, 100, 150], []), side], ignore_index=True)
    settings = BenchSettings(time_step_s=1e-3)
    rows = synthetic_rows(
        base.model_copy(update={"manipulator": truth}), plan, 0.01, np.random.default_rng(1), settings
    )
    rows["line"] = np.arange(len(rows)) + 2
    result = solve_fit(build_problem(rows, base), n_jobs=2)
    assert result.values["stiffness_n_m_per_rad[grasp]"] == pytest.approx(0.26, rel=0.03)
    assert result.values["stiffness_n_m_per_rad[side]"] == pytest.approx(1.2, rel=0.03)
    assert result.values["pressure_gain_n_m_per_kpa"] == pytest.approx(6e-4, rel=0.03)
    assert {m.label for m in result.metrics} == {"tip_load", "blocked_force", "tip_load[side]"}


@pytest.mark.slow
def test_fit_recovers_known_parameters_on_the_bundled_36_rows(tmp_path: Path) -> None:
    out = tmp_path / "model.yaml"
    res = runner.invoke(app, ["calibrate", str(SYNTHETIC), *BUILD, "-o", str(out), "--jobs", "2"])
    assert res.exit_code == 0, res.output
    record = load_model(out).provenance["calibration"]  # type: ignore[index]
    pars = record["parameters"]
    assert pars["stiffness_n_m_per_rad[grasp]"]["value"] == pytest.approx(
        TRUE_STIFFNESS_N_M_PER_RAD, rel=0.03
    )
    assert pars["pressure_gain_n_m_per_kpa"]["value"] == pytest.approx(TRUE_GAIN_N_M_PER_KPA, rel=0.03)
    assert all(t["relative_rmse"] <= 0.05 for t in record["tests"]), record["tests"]


@pytest.mark.slow
def test_bundled_synthetic_file_is_what_the_generator_makes(tmp_path: Path) -> None:
    from somo_sweep.calibration.synthetic import example_csv

    (tmp_path / "again.csv").write_text(example_csv())
    again, bundled = read_measurements(tmp_path / "again.csv"), read_measurements(SYNTHETIC)
    cols = ["tip_deflection_mm", "blocked_force_n", "tip_x_mm", "tip_z_mm"]
    np.testing.assert_allclose(again[cols].to_numpy(), bundled[cols].to_numpy(), rtol=1e-4)


# --- side axis, data files, determinism --------------------------------------------------------


def test_synthetic_rows_without_noise_are_what_somo_sweep_measure_prints(tmp_path: Path) -> None:
    from somo_sweep.calibration.report import model_yaml
    from somo_sweep.calibration.synthetic import example_finger

    model_path = tmp_path / "finger.yaml"
    model_path.write_text(model_yaml(example_finger()))
    res = runner.invoke(
        app,
        [
            "measure",
            str(model_path),
            "--test",
            "blocked_force",
            "--values",
            "100,200",
            "--csv",
            str(tmp_path / "m.csv"),
        ],
    )
    assert res.exit_code == 0, res.output
    measured = read_measurements(tmp_path / "m.csv")["blocked_force_n"].to_numpy()
    ours = synthetic_rows(example_finger(), bench_plan([], [100, 200], []), 0.0, np.random.default_rng(0))
    np.testing.assert_allclose(ours["blocked_force_n"].to_numpy(float), measured, rtol=1e-5)


def test_side_view_bends_the_side_joints_with_their_own_lever_arms() -> None:
    manip = load_model(MODELS / "ihm_finger.yaml").manipulator
    assert manip is not None
    settings = BenchSettings(time_step_s=1e-3, gravity_m_s2=0.0)
    deflection_mm = run_bench(side_view(manip), "tip_load", 0.0, 0.05, settings).value
    # side joints at 10, 30, ..., 90 mm; the load acts at the sphere's far end, 130 mm
    closed = chain_tip_stiffness([1.037] * 5, [0.01, 0.03, 0.05, 0.07, 0.09], 0.13)
    assert 0.05 / (float(deflection_mm) * 1e-3) == pytest.approx(closed, rel=0.01)  # type: ignore[arg-type]


def test_side_view_keeps_every_joints_stiffness_under_a_taper_and_a_gradient() -> None:
    """The side view drops the first segment; profile, gradient and taper are evaluated where each
    remaining joint sits on the whole finger (before, the gradient moved by one segment)."""
    manip = load_model(MODELS / "ihm_finger.yaml").manipulator
    assert manip is not None
    act = manip.actuators[0].model_copy(
        update={"stiffness_gradient_per_m": 3.0, "stiffness_tip_ratio": 0.2, "stiffness_taper_shape": 0.0}
    )
    manip = manip.model_copy(update={"actuators": [act]})
    side = side_view(manip).actuators[0]
    for i in range(side.segments):
        kept = side.joint_of_segment(i).stiffness * side.stiffness_factor(i)
        assert kept == pytest.approx(
            act.joint_of_segment(i + 1).stiffness * act.stiffness_factor(i + 1), rel=1e-12
        )


def test_fig3_data_reproduce_the_published_values_and_say_so() -> None:
    assert "NOT measured" in FIG3.read_text().splitlines()[0]
    rows = read_measurements(FIG3)
    blocked = rows[rows["test"] == "blocked_force"].set_index("pressure_kpa")["blocked_force_n"]
    assert blocked[100.0] == pytest.approx(0.75)
    for axis, stiffness in (("grasp", 6.12), ("side", 29.05)):
        sel = rows[(rows["test"] == "tip_load") & (rows["axis"] == axis)]
        k = sel["tip_load_n"] / (sel["tip_deflection_mm"] * 1e-3)
        np.testing.assert_allclose(k, stiffness, rtol=1e-5)


def test_the_coarser_calibration_step_agrees_with_the_reference_step() -> None:
    from somo_sweep.calibration.solve import CALIBRATION_SETTINGS

    plan = bench_plan([0.1], [240], [240])
    manip = _small_truth().manipulator
    coarse = simulate_rows(manip, plan, CALIBRATION_SETTINGS)
    reference = simulate_rows(manip, plan, BenchSettings(time_step_s=5e-4))
    np.testing.assert_allclose(coarse, reference, rtol=2e-4)


def test_rows_simulate_identically_with_one_or_two_workers() -> None:
    plan = bench_plan([0.05], [100], [200])
    manip = _small_truth().manipulator
    one = simulate_rows(manip, plan, BenchSettings(time_step_s=1e-3), n_jobs=1)
    two = simulate_rows(manip, plan, BenchSettings(time_step_s=1e-3), n_jobs=2, min_parallel_rows=0)
    np.testing.assert_array_equal(one, two)


def test_free_bending_error_is_relative_to_tip_travel() -> None:
    rows = bench_plan([], [], [0, 100])
    rows.loc[:, "tip_x_mm"], rows.loc[:, "tip_z_mm"] = [100.0, 90.0], [0.0, -30.0]
    rows["role"] = "validation"
    simulated = np.array([[100.0, 0.0], [90.0, -31.0]])
    (metric,) = per_test_metrics(rows, simulated)
    assert metric.rmse == pytest.approx(np.sqrt(0.5))
    # travel: 0 and sqrt(10² + 30²) mm -> RMS sqrt(500)
    assert metric.relative_rmse == pytest.approx(np.sqrt(0.5) / np.sqrt(500.0))


# --- bad input: exit 2, row and column named, nothing written ---------------------------------

HEADER = "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm\n"
GOOD = "tip_load,0,0.05,5,,,\ntip_load,0,0.1,10,,,\nblocked_force,100,,,0.3,,\nblocked_force,200,,,0.6,,\n"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (None, "file not found"),
        ("test,pressure_kpa\ntip_load,0\n", "missing column(s) tip_load_n"),
        (HEADER + GOOD + "blocked_force,abc,,,0.3,,\n", "line 6, column pressure_kpa: 'abc' is not a number"),
        (
            HEADER + GOOD + "tip_lod,0,0.1,3,,,\n",
            "line 6, column test: unknown test 'tip_lod' (did you mean 'tip_load'?)",
        ),
        (
            HEADER + GOOD + "tip_load,0,-0.1,3,,,\n",
            "line 6, column tip_load_n: -0.1 is outside what a bench measures; allowed: 0 to 1000 N",
        ),
        (
            HEADER + GOOD + "tip_load,0,1e300,3,,,\n",
            "line 6, column tip_load_n: 1e+300 is outside what a bench measures; allowed: 0 to 1000 N; "
            "check the unit",
        ),
        (
            HEADER + GOOD + "blocked_force,-200,,,0.3,,\n",
            "line 6, column pressure_kpa: -200 is outside what a bench measures; allowed: -101.325 to "
            "10000 kPa (gauge: not below vacuum, at most 10 MPa)",
        ),
        (
            HEADER + GOOD + "free_bending,100,,,,2e4,3\n",
            "line 6, column tip_x_mm: 20000 is outside what a bench measures; allowed: -10000 to 10000 mm",
        ),
        (
            HEADER + "tip_load,0,0.05,5,,,\nblocked_force,100,,,0.3,,\n",
            "column blocked_force_n: 1 blocked_force row(s)",
        ),
        (
            HEADER
            + "tip_load,0,0.05,5,,,\ntip_load,0,0.1,10,,,\n"
            + "blocked_force,100,,,0.6,,\nblocked_force,200,,,0.3,,\n",
            "column blocked_force_n: the blocked force does not grow with pressure_kpa (lines 4, 5",
        ),
        (
            HEADER
            + "tip_load,0,0.05,0,,,\ntip_load,0,0.1,0,,,\n"
            + "blocked_force,100,,,0.3,,\nblocked_force,200,,,0.6,,\n",
            "column tip_deflection_mm: the grasp-axis tip_load rows (lines 2, 3)",
        ),
        (
            HEADER.strip() + ",axis\ntip_load,0,0.05,5,,,,grasp\ntip_load,0,0.05,5,,,,side\n",
            "line 3, column axis: 'side', but the model's first actuator has one axis",
        ),
    ],
)
def test_bad_input_exits_2_naming_row_and_column_and_writes_nothing(
    tmp_path: Path, text: str | None, expected: str
) -> None:
    path = tmp_path / "missing.csv" if text is None else _csv(tmp_path, text)
    out = tmp_path / "model.yaml"
    res = runner.invoke(
        app, ["calibrate", str(path), *BUILD, "-o", str(out), "--report", str(tmp_path / "r")]
    )
    assert res.exit_code == 2
    assert expected in res.stderr
    assert not out.exists() and not (tmp_path / "r").exists()


def test_side_rows_with_pressure_are_rejected_naming_the_column(tmp_path: Path) -> None:
    text = WORKED_EXAMPLE + "tip_load,50,0.1,3,,,,side\n"
    rows = read_measurements(_csv(tmp_path, text))
    with pytest.raises(
        MeasurementError, match=r"line 5, column pressure_kpa: side-axis tip_load rows need 0 kPa"
    ):
        build_problem(rows, load_model(MODELS / "ihm_finger.yaml"), min_rows_per_parameter=1)


def test_calibrate_needs_a_model_or_the_finger_dimensions(tmp_path: Path) -> None:
    path = _csv(tmp_path, HEADER + GOOD)
    res = runner.invoke(app, ["calibrate", str(path), "--length-mm", "100", "-o", str(tmp_path / "m.yaml")])
    assert res.exit_code == 2
    assert "--segments, --mass-g" in res.stderr


def test_written_model_round_trips_through_the_schema(tmp_path: Path) -> None:
    from somo_sweep.calibration.report import model_yaml

    model = planar_finger(0.1, 20, 0.02).model_copy(update={"provenance": {"calibration": {"method": "fit"}}})
    path = tmp_path / "m.yaml"
    path.write_text(model_yaml(model, "header"))
    assert load_model(path) == model
    assert yaml.safe_load(path.read_text())["provenance"]["calibration"]["method"] == "fit"


def test_synthetic_plan_writes_schema_rows(tmp_path: Path) -> None:
    plan = bench_plan([0.1], [100], [])
    plan.loc[0, "tip_deflection_mm"], plan.loc[1, "blocked_force_n"] = 3.0, 0.5
    (tmp_path / "p.csv").write_text(measurements_csv(plan))
    assert list(pd.read_csv(tmp_path / "p.csv")["test"]) == ["tip_load", "blocked_force"]


def test_a_calibration_that_does_not_fit_warns_and_still_writes_the_model(tmp_path: Path) -> None:
    text = SYNTHETIC.read_text()
    first_load = next(ln for ln in text.splitlines() if ln.startswith("tip_load,"))
    load = first_load.split(",")
    load[2] = "100"  # 100 N for a deflection of about 1 mm: a unit slip (g entered as N)
    path = _csv(tmp_path, text.replace(first_load, ",".join(load), 1))
    out = tmp_path / "model.yaml"
    res = runner.invoke(app, ["calibrate", str(path), *BUILD, "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "warning: the calibrated model misses the tip_load rows by " in res.output
    assert "above 25% the model does not fit the measurements" in res.output and out.is_file()
    good = runner.invoke(app, ["calibrate", str(SYNTHETIC), *BUILD, "-o", str(tmp_path / "good.yaml")])
    assert good.exit_code == 0 and "warning" not in good.output


def test_a_finger_heavy_for_its_stiffness_is_fitted_from_a_second_start() -> None:
    """The example finger with its stiffness and gain ÷3 rests on the plate up to ~80 kPa (the
    blocked force stays at its weight) and lifts off above. From the whole range's slope the
    fit started where the force does not depend on the gain and stopped at 1/3 of it, with no
    warning (and ``diagnose`` then named a spurious effect)."""
    from dataclasses import replace

    from somo_sweep.calibration.synthetic import EXAMPLE_FINGER, example_plan

    truth = planar_finger(
        **EXAMPLE_FINGER,  # type: ignore[arg-type]
        stiffness_n_m_per_rad=TRUE_STIFFNESS_N_M_PER_RAD / 3,
        pressure_gain_n_m_per_kpa=TRUE_GAIN_N_M_PER_KPA / 3,
    )
    rows = synthetic_rows(truth, example_plan(), 0.01, np.random.default_rng(0), n_jobs=2)
    rows["line"] = np.arange(len(rows)) + 2
    base = planar_finger(**EXAMPLE_FINGER)  # type: ignore[arg-type]
    problem = build_problem(rows, base)
    assert len(problem.other_starts) == 1  # the blocked force is not linear in the pressure
    result = solve_fit(problem, n_jobs=2)
    assert result.values["stiffness_n_m_per_rad[grasp]"] == pytest.approx(
        TRUE_STIFFNESS_N_M_PER_RAD / 3, rel=0.03
    )
    assert result.values["pressure_gain_n_m_per_kpa"] == pytest.approx(TRUE_GAIN_N_M_PER_KPA / 3, rel=0.03)
    assert result.reproduces_within(0.05), result.metrics
    one_start = solve_fit(replace(problem, other_starts=()), n_jobs=2)
    assert one_start.values["pressure_gain_n_m_per_kpa"] < 0.7 * TRUE_GAIN_N_M_PER_KPA / 3


def test_a_row_without_equilibrium_is_named_by_its_file_line() -> None:
    """Warnings said 'row 15' for what is line 21 of the file."""
    from somo_sweep.calibration.parameters import RowFailure

    failure = RowFailure(15, "blocked_force", 100.0, 0.0, "no static equilibrium", line=21)
    assert failure.describe() == "line 21 (blocked_force at 100 kPa): no static equilibrium"
    assert RowFailure(15, "tip_load", 0.0, 0.5, "x").describe() == "row 15 (tip_load at 0 kPa, 0.5 N): x"


def _repeated(tmp_path: Path, times: int = 4) -> tuple[Path, int, int]:
    """The synthetic CSV with its fourth tip_load row written ``times`` more times below it (the
    last copy as ``+0.0600``-style text: the same numbers); returns the file, the row's line and
    the line of its last copy."""
    lines = SYNTHETIC.read_text().splitlines()
    i = [k for k, ln in enumerate(lines) if ln.startswith("tip_load")][3]
    fields = lines[i].split(",")
    respelled = ",".join([fields[0], f"{float(fields[1]):+.1f}", f"{float(fields[2])}0", *fields[3:]])
    copies = [lines[i]] * (times - 1) + [respelled]
    path = tmp_path / "repeated.csv"
    path.write_text("\n".join([*lines[: i + 1], *copies, *lines[i + 1 :]]) + "\n")
    return path, i + 1, i + 1 + times


def test_rows_repeated_exactly_are_named_and_counted_once_by_calibrate(tmp_path: Path) -> None:
    """One row written five times changed the fit and lowered the reported error, silently."""
    path, line, last = _repeated(tmp_path)
    clean = runner.invoke(
        app, ["calibrate", str(SYNTHETIC), "--method", "paper", "-o", str(tmp_path / "a.yaml")]
    )
    res = runner.invoke(app, ["calibrate", str(path), "--method", "paper", "-o", str(tmp_path / "b.yaml")])
    assert clean.exit_code == 0 and res.exit_code == 0, res.output
    later = ", ".join(str(n) for n in range(line + 1, last + 1))
    assert (
        f"warning: {path}: 4 row(s) repeat an earlier row exactly (lines {later} repeat line {line}): every "
        "field is equal as read (the same test, axis and direction, numbers equal in value, the same empty "
        "cells); each is counted once"
    ) in res.output
    assert "pass --keep-duplicates if they are separate measurements" in res.output

    def values(name: str) -> dict[str, float]:
        return load_model(tmp_path / name).provenance["calibration"]["parameters"]  # type: ignore[index]

    assert values("b.yaml") == values("a.yaml")
    kept = runner.invoke(
        app,
        ["calibrate", str(path), "--method", "paper", "-o", str(tmp_path / "c.yaml"), "--keep-duplicates"],
    )
    assert kept.exit_code == 0 and "kept as separate measurements (--keep-duplicates)" in kept.output
    assert values("c.yaml") != values("a.yaml")


def test_rows_differing_in_any_field_are_not_repeats(tmp_path: Path) -> None:
    from somo_sweep.calibration.repeats import find_repeats

    path = tmp_path / "m.csv"
    path.write_text(
        "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm,axis\n"
        "tip_load,0,0.1,1.5,,,,grasp\n"
        "tip_load,0,0.1,1.5,,,,side\n"  # another axis
        "tip_load,0,0.1,1.50001,,,,grasp\n"  # another value
        "tip_load,0.0,1e-1,1.50,,,,grasp\n"  # the first row again, spelled otherwise
        "tip_load,0,0.1,1.5,,,,\n"  # the axis left empty: not the same row as written
    )
    assert find_repeats(read_measurements(path)) == {2: [5]}


def test_diagnose_takes_keep_duplicates_and_counts_repeats_once_by_default(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from somo_sweep.diagnosis import workflow
    from somo_sweep.errors import SomoError

    seen: list[tuple[int, bool]] = []

    def stop(rows: pd.DataFrame, *args: object, keep_duplicates: bool = False, **kwargs: object) -> None:
        seen.append((len(rows), keep_duplicates))
        raise SomoError("stopped here")

    monkeypatch.setattr(workflow, "build_diagnosis", stop)
    path, line, _ = _repeated(tmp_path)
    model = str(MODELS / "ihm_finger.yaml")
    for extra in ([], ["--keep-duplicates"]):
        res = runner.invoke(
            app, ["diagnose", str(path), "--model", model, "--out", str(tmp_path / "d"), *extra]
        )
        assert res.exit_code == 2 and "stopped here" in res.output
        assert f"repeat line {line})" in res.output
    n = len(read_measurements(SYNTHETIC))
    assert seen == [(n, True), (n + 4, True)]


def test_a_row_repeated_thousands_of_times_is_named_in_one_short_line() -> None:
    from somo_sweep.calibration.repeats import describe_repeats

    text = describe_repeats({2: list(range(3, 5003))}, kept=False)
    lines = ", ".join(str(n) for n in range(3, 23))
    assert text.startswith(
        f"5000 row(s) repeat an earlier row exactly (lines {lines}, … repeat line 2; … 4980 more"
    )
    assert len(text) < 600


def test_problem_description_of_a_long_file_stays_short(tmp_path: Path) -> None:
    """``calibrate -q`` on 4999 rows printed 4976 line numbers."""
    text = SYNTHETIC.read_text().splitlines()
    header = next(i for i, ln in enumerate(text) if not ln.startswith("#"))
    free = [ln for ln in text[header + 1 :] if ln.startswith("free_bending")]
    long = tmp_path / "long.csv"
    long.write_text("\n".join([*text, *free * 300]) + "\n")
    said = build_problem(read_measurements(long), _example_base(), str(long)).describe()
    assert "validation rows: free_bending (3913: lines 29, 30" in said and "… (3901 more)" in said
    assert len(said) < 600
