"""Diagnosis: effects as model features, noise and disagreements, and hidden-effect acceptance.

Acceptance data come from the simulator with one effect switched on (its name and
size known only to this file), plus relative noise; ``calibrate`` then ``diagnose``
must name that effect, or ``none`` on effect-free data.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from somo_sweep.calibration.measurements import COLUMNS, measurements_csv
from somo_sweep.calibration.meter import metered
from somo_sweep.calibration.report import model_yaml
from somo_sweep.calibration.solve import CALIBRATION_SETTINGS, build_problem, solve_fit
from somo_sweep.calibration.synthetic import bench_plan, example_finger, synthetic_rows
from somo_sweep.cli.app import app
from somo_sweep.diagnosis.diagnose import build_diagnosis, diagnose
from somo_sweep.diagnosis.effects import EFFECTS, add_effect, get_effect
from somo_sweep.diagnosis.noise import channels, estimate_noise, find_disagreements
from somo_sweep.errors import SomoError
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.description import Actuation
from somo_sweep.model.load import load_model
from somo_sweep.statics.bench import BenchSettings, run_bench

runner = CliRunner()
SETTINGS = CALIBRATION_SETTINGS
#: Hidden effects, sized like real soft fingers (tens of percent at the top of the range).
HIDDEN = {
    "none": 0.0,
    "nonlinear_stiffness": 80.0,  # +29 % joint stiffness at 240 kPa's bend
    "actuation_saturation": 260.0**-2,  # −21 % torque at 240 kPa
    # stiffness 1 − 6 /m·s along the 100-mm finger (tip:base 0.4, linear): tip joint 57 % softer
    # than the base joint (a tapered tip)
    "stiffness_gradient": float(np.log(0.4)),
    "self_weight": 0.008,  # kg: the finger weighs 28 g, the model says 20 g
    "hysteresis": 0.001,  # ±3 % of the top actuation torque
}


def _plan(direction: bool, short: bool = False) -> pd.DataFrame:
    """36 rows of the three protocols, 0–240 kPa and 0.02–0.1 N, tip loads on the straight and on
    the fully bent finger (with loading/unloading pairs of 18 rows for hysteresis); ``short``: 16 rows."""
    if direction:
        loads, pressures = [0.05, 0.1], [float(p) for p in range(0, 241, 40)]
        one = pd.concat([bench_plan(loads, pressures, pressures), bench_plan(loads, [], [], 240.0)])
        both = pd.concat([one.assign(direction="loading"), one.assign(direction="unloading")])
        return both.reset_index(drop=True)
    if short:
        pressures = [0.0, 48.0, 96.0, 144.0, 192.0, 240.0]
        return bench_plan([0.025, 0.05, 0.075, 0.1], pressures, pressures)
    loads, pressures = [0.02 * i for i in range(1, 6)], [float(p) for p in range(0, 241, 20)]
    both = pd.concat([bench_plan(loads, pressures, pressures), bench_plan(loads, [], [], 240.0)])
    return both.reset_index(drop=True)


def _hidden_rows(effect: str, seed: int, noise_rel: float, short: bool = False) -> pd.DataFrame:
    true = example_finger()
    assert true.manipulator is not None
    manip = true.manipulator if effect == "none" else add_effect(true.manipulator, effect, HIDDEN[effect])
    plan = _plan(effect == "hysteresis", short)
    rows = synthetic_rows(
        true.model_copy(update={"manipulator": manip}),
        plan,
        noise_rel,
        np.random.default_rng(seed),
        SETTINGS,
        2,
    )
    rows["line"] = range(2, len(rows) + 2)
    return rows


def _calibrate_then_diagnose(
    rows: pd.DataFrame, refine_top: int = 2, max_evaluations: int = 3, close_call_evaluations: int = 4
) -> object:
    base = planar_finger(0.100, 20, 0.020)
    calibrated = solve_fit(build_problem(rows, base), n_jobs=2).model
    problem = build_diagnosis(rows, calibrated, n_jobs=2)
    return diagnose(problem, 2, refine_top, max_evaluations, close_call_evaluations)


# --- effects as native model features -------------------------------------------------------


def test_unknown_effect_lists_the_valid_ones() -> None:
    with pytest.raises(SomoError, match=r"did you mean 'self_weight'.*allowed: nonlinear_stiffness"):
        get_effect("self_wieght")


def test_every_effect_is_as_given_at_its_current_values_and_changes_the_bench_when_on() -> None:
    manip = example_finger().manipulator
    assert manip is not None
    rows = pd.DataFrame({"pressure_kpa": [240.0], "tip_load_n": [0.1]})
    ref = run_bench(manip, "free_bending", 240.0, settings=SETTINGS).value
    for name, effect in EFFECTS.items():
        first, *others = effect.parameters(manip, rows)
        for par in (first, *others):
            assert par.apply(manip, par.current) == manip, (name, par.name)
        assert first.current == 0.0, name  # the effect is off in the example finger
        direction = "loading" if effect.needs_direction else None
        on_manip = first.apply(manip, 2 * first.probe)
        on = run_bench(on_manip, "free_bending", 240.0, settings=SETTINGS, direction=direction)
        assert np.hypot(*np.subtract(on.value, ref)[:2]) > 0.5, name  # mm
        for par in others:  # a shape parameter changes the bench once the effect is on
            shaped = run_bench(par.apply(on_manip, par.current + 2 * par.probe), "free_bending", 240.0)
            assert np.hypot(*np.subtract(shaped.value, on.value)[:2]) > 0.1, (name, par.name)


def test_saturated_actuation_follows_tanh() -> None:
    act = Actuation(pressure_gain_n_m_per_kpa=1e-4, saturation_pressure_kpa=200.0)
    assert act.torque_n_m(240.0) == pytest.approx(1e-4 * 200 * np.tanh(1.2))
    assert Actuation(pressure_gain_n_m_per_kpa=1e-4).torque_n_m(240.0) == pytest.approx(0.024)


def test_stiffness_gradient_scales_each_joint_linearly_and_rejects_negative_stiffness() -> None:
    act = example_finger().manipulator.actuators[0]  # type: ignore[union-attr]
    graded = act.model_copy(update={"stiffness_gradient_per_m": -4.0})
    # Joint 10 of 20 (5 mm segments) sits at the 11th segment's midpoint, 52.5 mm from the start.
    assert graded.stiffness_factor(10) == pytest.approx(1 - 4.0 * 0.0525)
    with pytest.raises(ValueError, match="stiffness_gradient_per_m"):
        type(act).model_validate({**act.model_dump(), "stiffness_gradient_per_m": -20.0})


hypothesis = pytest.importorskip("hypothesis")


@hypothesis.settings(max_examples=200, deadline=None, derandomize=True, database=None)
@hypothesis.given(
    log_ratio=hypothesis.strategies.floats(-np.log(1e6), np.log(1e6)),
    shape=hypothesis.strategies.floats(-10.0, 10.0),
)
def test_the_taper_is_positive_monotone_and_ends_at_its_ratio_for_any_parameter(
    log_ratio: float, shape: float
) -> None:
    """Every value the schema allows (ratio 1e-6 to 1e6, shape ±10) gives a positive, monotone
    profile from 1 at the base to the ratio at the tip: the fit can try nothing that makes a
    joint's stiffness ≤ 0 (the linear gradient it replaces could)."""
    from somo_sweep.model.description import taper_factor

    ratio = float(np.exp(log_ratio))
    x = np.linspace(0.0, 1.0, 41)
    f = np.array([taper_factor(float(v), ratio, shape) for v in x])
    assert np.all(f > 0) and np.all(np.isfinite(f))
    steps = np.diff(f) * np.sign(log_ratio)
    assert np.all(steps >= -1e-12 * np.max(f))
    assert f[0] == 1.0 and f[-1] == pytest.approx(ratio, rel=1e-9)


def test_the_taper_shapes_are_the_named_profiles() -> None:
    """λ = 1: linear in stiffness; 1/3: linear in thickness (EI ∝ t³); 0: exponential; −1: linear
    in compliance; and smooth through λ = 0."""
    from somo_sweep.model.description import taper_factor

    x, r = 0.3, 5.0
    assert taper_factor(x, r, 1.0) == pytest.approx(1 + (r - 1) * x, rel=1e-12)
    assert taper_factor(x, r, 1 / 3) == pytest.approx((1 + (r ** (1 / 3) - 1) * x) ** 3, rel=1e-12)
    assert taper_factor(x, r, 0.0) == pytest.approx(r**x, rel=1e-12)
    assert taper_factor(x, r, 1e-9) == pytest.approx(r**x, rel=1e-8)
    assert 1 / taper_factor(x, r, -1.0) == pytest.approx(1 + (1 / r - 1) * x, rel=1e-12)
    act = example_finger().manipulator.actuators[0]  # type: ignore[union-attr]
    tapered = act.model_copy(update={"stiffness_tip_ratio": 0.4})  # linear (λ = 1) by default
    graded = act.model_copy(update={"stiffness_gradient_per_m": -6.0})  # 1 − 6 /m·s over 100 mm
    for i in range(act.segments):
        assert tapered.stiffness_factor(i) == pytest.approx(graded.stiffness_factor(i), rel=1e-12)


def test_a_finger_told_0_g_is_weightless_and_self_weight_gives_it_its_weight() -> None:
    """The header's mass_g may be 0 (the weight left out); the absolute added mass then supplies it."""
    from somo_sweep.calibration.finger import finger_from_header
    from somo_sweep.diagnosis.effects import actuator_mass_kg

    weightless = finger_from_header({"length_mm": 100, "segments": 20, "mass_g": 0}).manipulator
    assert weightless is not None
    assert actuator_mass_kg(weightless) < 1e-7
    heavy = add_effect(weightless, "self_weight", 0.020)
    assert actuator_mass_kg(heavy) == pytest.approx(0.020, rel=1e-6)
    flat = run_bench(heavy, "blocked_force", 0.0, settings=SETTINGS).value
    assert flat == pytest.approx(0.020 * 9.81 * (1 - 1 / 20), rel=1e-3)  # W·(1 − 1/N) on the plate
    # 20 links at the schema's least mass (1e-9 kg): 2e-7 N
    assert run_bench(weightless, "blocked_force", 0.0, settings=SETTINGS).value == pytest.approx(0, abs=1e-6)


def test_stiffening_spring_matches_the_cubic_law_on_a_single_joint() -> None:
    manip = planar_finger(
        0.1, 1, 0.001, stiffness_n_m_per_rad=0.5, pressure_gain_n_m_per_kpa=1e-3, joint_placement="start"
    ).manipulator
    assert manip is not None
    stiff = add_effect(manip, "nonlinear_stiffness", 10.0)
    weightless = BenchSettings(time_step_s=1e-3, gravity_m_s2=0.0)
    x, z, angle_deg = run_bench(stiff, "free_bending", 200.0, settings=weightless).value  # type: ignore[misc]
    # One joint at the clamp: angle θ with k·θ·(1 + a·θ²) = u = 0.2 N·m.
    theta = float(np.arctan2(-z, x))
    assert 0.5 * theta * (1 + 10.0 * theta**2) == pytest.approx(0.2, rel=2e-3)
    assert angle_deg == pytest.approx(np.degrees(theta), rel=1e-6)


def test_hysteresis_makes_unloading_bend_further_than_loading() -> None:
    manip = add_effect(example_finger().manipulator, "hysteresis", 0.001)  # type: ignore[arg-type]
    up = run_bench(manip, "blocked_force", 120.0, settings=SETTINGS, direction="loading").value
    down = run_bench(manip, "blocked_force", 120.0, settings=SETTINGS, direction="unloading").value
    plain = run_bench(manip, "blocked_force", 120.0, settings=SETTINGS).value
    assert up < plain < down  # type: ignore[operator]


# --- noise and disagreements ----------------------------------------------------------------


def test_noise_from_repeats_and_from_second_differences() -> None:
    rng = np.random.default_rng(3)
    p = np.repeat(np.arange(0.0, 241.0, 20.0), 2)
    rows = pd.DataFrame({"test": "blocked_force", "pressure_kpa": p}).reindex(columns=COLUMNS)
    rows["axis"] = "grasp"
    rows["blocked_force_n"] = 0.002 * p + 0.01 * rng.standard_normal(len(p))
    residual = np.column_stack([np.zeros(len(p)), np.full(len(p), np.nan)])
    est = estimate_noise(rows, residual)["blocked_force"]
    assert est.method == "repeated rows" and est.sigma == pytest.approx(0.01, rel=0.4)
    single = rows.iloc[::2].reset_index(drop=True)
    trend = 2e-4 * single["pressure_kpa"].to_numpy()  # a wrong gain: linear, cancels
    res = np.column_stack([trend + 0.01 * rng.standard_normal(len(single)), np.full(len(single), np.nan)])
    est = estimate_noise(single, res)["blocked_force"]
    assert est.method == "residual second differences" and est.sigma == pytest.approx(0.01, rel=0.5)
    found = find_disagreements(single, res, {"blocked_force": est})
    assert found and found[0].input_from >= 60 and found[0].max_residual > 0


def test_noise_that_grows_with_the_reading_is_modelled_as_proportional() -> None:
    rng = np.random.default_rng(4)
    p = np.arange(0.0, 241.0, 20.0)
    rows = pd.DataFrame({"test": "blocked_force", "pressure_kpa": p}).reindex(columns=COLUMNS)
    rows["axis"] = "grasp"
    force = 0.002 * p
    rows["blocked_force_n"] = force * (1 + 0.02 * rng.standard_normal(len(p)))
    residual = np.column_stack([force - rows["blocked_force_n"], np.full(len(p), np.nan)])
    est = estimate_noise(rows, residual)["blocked_force"]
    assert est.proportional and est.model == "proportional"
    sigma = est.at(rows["blocked_force_n"].to_numpy())
    assert sigma[-1] == pytest.approx(0.02 * force[-1], rel=0.5) and sigma[1] < 0.3 * sigma[-1]


def test_measured_tip_angles_form_their_own_channel_in_degrees() -> None:
    plan = bench_plan([0.05], [100.0], [0.0, 80.0, 160.0, 240.0])
    rows = synthetic_rows(example_finger(), plan, 0.0, np.random.default_rng(0), SETTINGS)
    rows["line"] = range(2, len(rows) + 2)
    names = {ch.name: ch for ch in channels(rows)}
    assert names["free_bending.tip_angle"].unit == "deg"
    assert names["free_bending.tip_angle"].rows.sum() == 4
    angles = rows.loc[rows["test"] == "free_bending", "tip_angle_deg"].to_numpy()
    assert np.all(np.diff(angles) > 10)  # more pressure, more curl
    without = synthetic_rows(example_finger(), plan, 0.0, np.random.default_rng(0), SETTINGS, tip_angle=False)
    assert "free_bending.tip_angle" not in {ch.name for ch in channels(without)}


def test_tip_load_noise_follows_each_pressure_separately() -> None:
    """Second differences run along the load at one pressure, never across pressures."""
    loads = [0.02 * i for i in range(1, 6)]
    rows = pd.concat([bench_plan(loads, [], []), bench_plan(loads, [], [], 240.0)]).reset_index(drop=True)
    rows["tip_deflection_mm"] = 10 * rows["tip_load_n"] * np.where(rows["pressure_kpa"] > 0, 0.5, 1.0)
    offset = np.where(rows["pressure_kpa"] > 0, 1.0, 0.0)  # a residual differing by pressure only
    residual = np.column_stack([offset, np.full(len(rows), np.nan)])
    assert estimate_noise(rows, residual)["tip_load"].sigma < 1e-3


# --- hidden effects: calibrate, then diagnose ------------------------------------------------


def test_diagnose_names_a_hidden_saturation_and_halves_the_gap() -> None:
    """Default-suite representative: 16 rows, 1 % noise, one hidden effect, 2 + 2 chord iterations."""
    rows = _hidden_rows("actuation_saturation", seed=5, noise_rel=0.01, short=True)
    calibrated = solve_fit(build_problem(rows, planar_finger(0.100, 20, 0.020)), n_jobs=2).model
    reports: list[tuple[int, int]] = []
    with metered(lambda done, expected: reports.append((done, expected))):
        problem = build_diagnosis(rows, calibrated, n_jobs=2)
        result = diagnose(problem, 2, 1, 2, 2)
    # The progress bar counted every bench row the diagnosis simulated.
    assert reports[-1][0] == result.simulations
    assert all(done <= expected for done, expected in reports)
    assert result.missing_effect == "actuation_saturation", result.verdict  # type: ignore[attr-defined]
    assert result.combined_after <= 0.5 * result.combined_before  # type: ignore[attr-defined]


CASES = [
    pytest.param(effect, seed, noise, id=f"{effect}-seed{seed}-noise{100 * noise:.0f}pct")
    for seed in (1, 2, 3)
    for noise in (0.01, 0.02)
    for effect in HIDDEN
]


@pytest.mark.slow
@pytest.mark.parametrize(("effect", "seed", "noise_rel"), CASES)
def test_diagnose_names_the_hidden_effect(effect: str, seed: int, noise_rel: float) -> None:
    """36 rows, calibrate then diagnose: the hidden effect (or none) is named, and for an
    effect the combined score after is at most half the score before."""
    start = time.perf_counter()
    rows = _hidden_rows(effect, seed, noise_rel)
    result = _calibrate_then_diagnose(rows)
    record = {
        "effect": effect,
        "seed": seed,
        "noise_rel": noise_rel,
        "named": result.missing_effect,  # type: ignore[attr-defined]
        "verdict": result.verdict,  # type: ignore[attr-defined]
        "combined_before": result.combined_before,  # type: ignore[attr-defined]
        "combined_after": result.combined_after,  # type: ignore[attr-defined]
        "wall_time_s": time.perf_counter() - start,
    }
    log = Path(os.environ.get("SOMO_SWEEP_MATRIX_LOG", "/dev/null"))
    log.parent.mkdir(exist_ok=True)
    with log.open("a") as fh:
        fh.write(json.dumps(record) + "\n")
    assert result.missing_effect == effect, result.verdict  # type: ignore[attr-defined]
    if effect != "none":
        assert result.combined_after <= 0.5 * result.combined_before  # type: ignore[attr-defined]


# --- command line ------------------------------------------------------------------------------


def test_cli_bad_measurements_exit_2_naming_line_and_column_and_write_nothing(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text(
        "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm\n"
        "tip_load,0,0.05,abc,,,\n"
    )
    model = tmp_path / "m.yaml"
    model.write_text("manipulator: {}\n")
    out = tmp_path / "out"
    res = runner.invoke(app, ["diagnose", str(bad), "--model", str(model), "--out", str(out)])
    assert res.exit_code == 2
    assert "line 2, column tip_deflection_mm" in res.output
    assert not out.exists()


def test_cli_unknown_effect_exit_2(tmp_path: Path) -> None:
    res = runner.invoke(
        app,
        ["diagnose", "x.csv", "--model", "m.yaml", "--out", str(tmp_path / "o"), "--effects", "hysterisis"],
    )
    assert res.exit_code == 2 and "did you mean 'hysteresis'" in res.output


def test_cli_writes_json_report_model_and_plot(tmp_path: Path) -> None:
    """End to end on a tiny file (6 rows, one effect tried) against the true model."""
    rows = synthetic_rows(
        example_finger(),
        bench_plan([0.05, 0.1], [120.0, 240.0], [120.0, 240.0]),
        0.01,
        np.random.default_rng(0),
        SETTINGS,
    )
    csv = tmp_path / "bench.csv"
    csv.write_text(measurements_csv(rows))
    model = tmp_path / "model.yaml"
    model.write_text(model_yaml(example_finger()))
    out = tmp_path / "out"
    res = runner.invoke(
        app, ["diagnose", str(csv), "--model", str(model), "--out", str(out), "--effects", "self_weight"]
    )
    assert res.exit_code == 0, res.output
    assert "missing effect: none" in res.output
    record = json.loads((out / "diagnosis.json").read_text())
    assert record["missing_effect"] == "none"
    assert {"candidates", "rmse_before", "rmse_after", "disagreements"} <= set(record)
    assert record["rmse_before"]["combined"] >= 0 and "blocked_force" in record["rmse_after"]
    assert record["rmse_after"]["free_bending.tip_angle"]["unit"] == "deg"  # the CSV carried angles
    assert "free_bending.tip_angle" in record["noise"]
    assert [c["name"] for c in record["candidates"]] == sorted(
        ["none", "self_weight"], key=lambda n: next(c["bic"] for c in record["candidates"] if c["name"] == n)
    )
    assert (
        (out / "report.md").read_text().startswith("<!-- written by somo-sweep diagnose -->\n# Diagnosis of")
    )
    assert (out / "diagnosis.png").stat().st_size > 1000
    assert load_model(out / "model.yaml").manipulator is not None


def test_rows_repeated_exactly_are_counted_once() -> None:
    """The same 36 rows twice halved the noise estimates and turned 'none' into an 'unexplained'
    disagreement between pairs of identical rows."""
    from somo_sweep.calibration.measurements import read_measurements
    from somo_sweep.model.tables import bundled_path

    rows = read_measurements(bundled_path("tables", "planar_finger_synthetic.csv"))
    twice = pd.concat([rows, rows.assign(line=rows["line"] + 100)], ignore_index=True)
    once = build_diagnosis(rows, example_finger(), effects=["self_weight"])
    copied = build_diagnosis(twice, example_finger(), effects=["self_weight"])
    first = "; ".join(f"line {v + 100} repeats line {v}" for v in rows["line"].head(20))
    (note,) = copied.notes
    assert note.startswith(f"36 row(s) repeat an earlier row exactly ({first}; … 16 more row(s))")
    assert "each is counted once" in note
    assert len(copied.rows) == len(once.rows) == 36 and not once.notes
    assert {k: v.sigma for k, v in copied.noise.items()} == {k: v.sigma for k, v in once.noise.items()}
    assert copied.describe().startswith("36 row(s) repeat an earlier row exactly")


def test_an_effect_these_rows_cannot_reveal_is_named_when_asked_for() -> None:
    """--effects hysteresis on rows without a direction printed "effects tried: " and exited 0."""
    from somo_sweep.calibration.measurements import read_measurements
    from somo_sweep.model.tables import bundled_path

    rows = read_measurements(bundled_path("tables", "planar_finger_synthetic.csv"))
    with pytest.raises(SomoError, match="--effects hysteresis: these rows cannot reveal it"):
        build_diagnosis(rows, example_finger(), effects=["hysteresis"])
    both = build_diagnosis(rows, example_finger(), effects=["hysteresis", "self_weight"])
    assert [e.name for e, _ in both.effects] == ["self_weight"]
    assert any("effect(s) hysteresis not tried: these rows lack a direction column" in n for n in both.notes)


def test_cli_an_effect_given_twice_is_tried_once(tmp_path: Path) -> None:
    """actuation_saturation twice made the verdict 'unexplained'; 5000 times ran without end."""
    rows = synthetic_rows(
        example_finger(),
        bench_plan([0.05, 0.1], [120.0, 240.0], [120.0, 240.0]),
        0.01,
        np.random.default_rng(0),
        SETTINGS,
    )
    csv = tmp_path / "bench.csv"
    csv.write_text(measurements_csv(rows))
    model = tmp_path / "model.yaml"
    model.write_text(model_yaml(example_finger()))
    res = runner.invoke(
        app,
        [
            "diagnose",
            str(csv),
            "--model",
            str(model),
            "--out",
            str(tmp_path / "o"),
            "--effects",
            ",".join(["self_weight"] * 5000),
        ],
    )
    assert res.exit_code == 0, res.output
    record = json.loads((tmp_path / "o" / "diagnosis.json").read_text())
    assert sorted(c["name"] for c in record["candidates"]) == ["none", "self_weight"]


def test_cli_stops_when_its_own_first_calibration_fails(tmp_path: Path) -> None:
    """A very soft finger pushing 20x harder: calibrate exits 1 and writes nothing; diagnose went on
    with the unfitted model for 148 s and wrote a model and report (tip-angle noise 2390 deg)."""
    from somo_sweep.calibration.measurements import read_measurements
    from somo_sweep.model.tables import bundled_path

    src = bundled_path("tables", "planar_finger_synthetic.csv")
    rows = read_measurements(src).drop(columns="line")
    rows["tip_deflection_mm"] = rows["tip_load_n"] * 1900.0
    rows["blocked_force_n"] *= 20.0
    finger = next(ln for ln in src.read_text().splitlines() if ln.startswith("# finger:"))
    csv = tmp_path / "soft_strong.csv"
    csv.write_text(finger + "\n" + rows.to_csv(index=False))
    out = tmp_path / "o"
    res = runner.invoke(app, ["diagnose", str(csv), "--out", str(out)])
    assert res.exit_code == 1, res.output
    assert (
        "calibrating the CSV's finger first: not fitted" in res.output and "nothing was written" in res.output
    )
    assert not out.exists()
