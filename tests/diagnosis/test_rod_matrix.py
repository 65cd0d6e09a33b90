"""Hidden effects in data from a continuum, not from our chain: calibrate, then diagnose.

The bench rows come from :mod:`reference.rod`, an elastica (Kirchhoff rod) solved as a
boundary-value problem that shares no code with the rigid-link chain: the standard finger
(100 mm, tip stiffness 20 N/m, 20 g, 15 mm thick, 5e-4 N·m/kPa) with one physical effect of
its own kind switched on, plus relative noise. A 20-segment chain is calibrated on the rows and
diagnosed; the effect must be named (``none`` on the effect-free rod: the chain's own
discretization must not read as an effect), and the gap at least halved.

The gap is the model's distance from the noiseless continuum, in noise units: RMS of
(simulated − rod without noise) / noise level over every measured entry. Unlike the combined
score against the noisy rows it is 0 for a perfect model, so "halved" means something even
when the effect is only a few noise levels large.

Each case's noiseless rows are solved once per test process (:func:`noiseless_rows`) and given
each seed's noise by :func:`reference.rod.with_noise`, the noise :func:`reference.rod.bench_rows`
draws.

A second continuum, :mod:`reference.heavy_beam` (a ``solve_bvp`` elastica sharing no code with
the chain or the rod), makes the 60-g finger of ``self_weight_12x`` with its blocked force taken
on a stop under the fingertip (a load cell there), run through ``somo-sweep diagnose`` as a user
would: the weight is found when the CSV says so (``# bench: {stop: fingertip}``); read as a
plate bench the rows stay unexplained.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from reference import heavy_beam
from reference.rod import Rod, bench_rows, standard_finger, with_noise
from typer.testing import CliRunner

from somo_sweep.calibration.metrics import measured_array
from somo_sweep.calibration.solve import build_problem, solve_fit
from somo_sweep.cli.app import app
from somo_sweep.diagnosis.diagnose import FITS_WITHIN_NOISE, DiagnosisResult, build_diagnosis, diagnose
from somo_sweep.diagnosis.effects import taper_name
from somo_sweep.model.builders import planar_finger


@dataclass(frozen=True)
class Case:
    """A hidden continuum effect: the rod's fields, the mass the chain is told, the expected name."""

    effect: str
    rod: dict[str, float] = field(default_factory=dict)
    model_mass_kg: float = 0.020
    note: str = ""


#: The continuum's effects (rod.Rod fields), sized like real soft fingers at 240 kPa, and the
#: hidden effects a bench file can hide (a weight 12x what the model is told, a model told 0 g, and
#: stiffness rising or falling 5:1 from base to tip).
CASES: dict[str, Case] = {
    "none": Case("none"),
    "nonlinear_stiffness": Case(
        "nonlinear_stiffness", {"nonlinear_stiffness": 0.1}, note="m = EI·κ·(1 + 0.1·(κL)²): +32 % at 240 kPa"
    ),
    "actuation_saturation": Case(
        "actuation_saturation", {"actuation_saturation": 250.0}, note="p_sat 250 kPa: −24 % moment at 240 kPa"
    ),
    "stiffness_gradient": Case(
        "stiffness_gradient",
        {"stiffness_gradient": -6.0},
        note="EI from +30 % at the clamp to −30 % at the tip",
    ),
    "stiffness_gradient_5to1": Case(
        "stiffness_gradient", {"stiffness_gradient": 40 / 3}, note="EI linear, tip 5x the base"
    ),
    "stiffness_gradient_1to5": Case(
        "stiffness_gradient", {"stiffness_gradient": -40 / 3}, note="EI linear, base 5x the tip"
    ),
    "self_weight": Case(
        "self_weight", {"self_weight": 0.4}, note="the finger weighs 28 g, the model says 20 g"
    ),
    "self_weight_12x": Case(
        "self_weight",
        {"mass_kg": 0.005, "self_weight": 11.0},
        0.005,
        note="the finger weighs 60 g, the model says 5 g",
    ),
    "self_weight_0g": Case("self_weight", {}, 0.0, note="the finger weighs 20 g, the model says 0 g"),
}

NOISES = (0.01, 0.02)
SEEDS = (1, 2, 3)


def in_default_suite(name: str, seed: int, noise_rel: float) -> bool:
    """Every case at both noise levels, one seed each (rotating over the cases): 18 of the 54 cells.

    The whole matrix takes ~5 min on the shared 2-core machine (4–12 s a cell); the default suite
    runs this third (~1.5 min), ``-m slow`` the rest.
    """
    i = list(CASES).index(name) + NOISES.index(noise_rel)
    return seed == SEEDS[i % len(SEEDS)]


MATRIX = [
    pytest.param(
        name,
        seed,
        noise,
        id=f"{name}-seed{seed}-noise{100 * noise:.0f}pct",
        marks=() if in_default_suite(name, seed, noise) else pytest.mark.slow,
    )
    for name in CASES
    for noise in NOISES
    for seed in SEEDS
]


def rod_of(name: str) -> Rod:
    """The case's continuum finger."""
    return standard_finger(**CASES[name].rod)


@cache
def _noiseless(name: str) -> pd.DataFrame:
    rows = bench_rows(rod_of(name))
    rows["line"] = range(2, len(rows) + 2)
    return rows


def noiseless_rows(name: str) -> pd.DataFrame:
    """The case's 36 rows without noise (solved once per process; a copy each call)."""
    return _noiseless(name).copy()


def calibrate_then_diagnose(name: str, seed: int, noise_rel: float) -> tuple[DiagnosisResult, np.ndarray]:
    """The rod's 36 rows with case ``name`` hidden; the chain calibrated on them, then diagnosed.

    Returns:
        The diagnosis and the rod's noiseless rows (measured-array layout).
    """
    clean = noiseless_rows(name)
    rows = with_noise(clean, noise_rel, seed)
    # midpoint joints, 15 mm thick: the rod's section; told the case's mass
    chain = planar_finger(0.100, 20, CASES[name].model_mass_kg)
    calibrated = solve_fit(build_problem(rows, chain), n_jobs=2).model
    result = diagnose(build_diagnosis(rows, calibrated, n_jobs=2), 2)
    return result, measured_array(clean)


def gap(result: DiagnosisResult, truth: np.ndarray, simulated: np.ndarray) -> float:
    """RMS distance of ``simulated`` from the noiseless rod, in units of the estimated noise."""
    problem = result.problem
    r = problem.normalised(simulated, result.noise) - problem.normalised(truth, result.noise)
    return float(np.sqrt(np.mean(r**2)))


def _log(record: dict[str, object]) -> None:
    """Append a matrix cell to ``$SOMO_SWEEP_MATRIX_LOG`` (JSON lines) when set."""
    path = os.environ.get("SOMO_SWEEP_MATRIX_LOG")
    if path:
        with Path(path).open("a") as fh:
            fh.write(json.dumps(record) + "\n")


def check_cell(name: str, seed: int, noise_rel: float) -> None:
    """One matrix cell: the effect named, the gap at least halved, the fitted size right."""
    start = time.perf_counter()
    case = CASES[name]
    result, truth = calibrate_then_diagnose(name, seed, noise_rel)
    before, after = gap(result, truth, result.problem.before), gap(result, truth, result.after)
    best = result.candidate(result.best_candidate)
    values, errors = result.parameters(best), result.stderr(best)
    _log(
        {
            "case": name,
            "seed": seed,
            "noise_rel": noise_rel,
            "named": result.missing_effect,
            "gap_before": before,
            "gap_after": after,
            "combined_before": result.combined_before,
            "combined_after": result.combined_after,
            "parameters": values,
            "stderr": errors,
            "described": result.describe_effects(),
            "wall_time_s": time.perf_counter() - start,
        }
    )
    assert result.missing_effect == case.effect, result.verdict
    if case.effect == "none":
        assert result.combined_after <= FITS_WITHIN_NOISE, (before, after)
        return
    assert after <= 0.5 * before, (before, after, result.verdict)
    rod = rod_of(name)
    if case.effect == "self_weight":  # the weight the finger really has, within 5 %
        told = planar_finger(0.100, 20, case.model_mass_kg).manipulator
        assert told is not None
        fitted = told.actuators[0].link.mass_kg * 20 + values["added_mass_kg"]
        assert fitted == pytest.approx(rod.true_mass_kg, rel=0.05), values
        assert 0 < errors["added_mass_kg"] < 0.05 * rod.true_mass_kg
    if case.effect == "stiffness_gradient":  # the rod's tip:base ratio, within its uncertainty
        half = rod.stiffness_gradient * rod.length_m / 2
        log_ratio = math.log((1 + half) / (1 - half))
        fitted, err = values["stiffness_log_tip_ratio"], errors["stiffness_log_tip_ratio"]
        assert abs(fitted - log_ratio) <= 3 * err and err < 0.25, (values, errors)
        # The rod's EI is linear: the shape is named linear, or honestly left unresolved.
        named = taper_name(values["stiffness_taper_shape"], errors["stiffness_taper_shape"])
        assert named == "linear in stiffness" or named.startswith("shape not resolved"), named


@pytest.mark.parametrize(("name", "seed", "noise_rel"), MATRIX)
def test_the_hidden_continuum_effect_is_named_and_the_gap_halved(
    name: str, seed: int, noise_rel: float
) -> None:
    check_cell(name, seed, noise_rel)


def _diagnose_rows(rows: pd.DataFrame) -> DiagnosisResult:
    rows["line"] = range(2, len(rows) + 2)
    calibrated = solve_fit(build_problem(rows, planar_finger(0.100, 20, 0.020)), n_jobs=2).model
    return diagnose(build_diagnosis(rows, calibrated, n_jobs=2), 2)


def test_two_hidden_effects_are_named_as_a_pair() -> None:
    """Saturation and a heavier finger together: the best single effect leaves 9x noise."""
    rod = standard_finger(actuation_saturation=250.0, self_weight=0.6)
    result = _diagnose_rows(bench_rows(rod, None, 0.01, 1))
    assert set(result.missing_effect.split("+")) == {"actuation_saturation", "self_weight"}, result.verdict
    truth = measured_array(bench_rows(rod))
    assert gap(result, truth, result.after) <= 0.5 * gap(result, truth, result.problem.before)


def test_a_disagreement_no_effect_explains_is_unexplained_never_none() -> None:
    """A 3 mm offset of every free-bending tip x (a camera misplaced): nothing in the vocabulary
    makes it, and the combined score (1.7) alone would pass for noise."""
    rows = with_noise(noiseless_rows("none"), 0.01, 1).drop(columns="line")
    rows.loc[rows["test"] == "free_bending", "tip_x_mm"] += 3.0
    result = _diagnose_rows(rows)
    assert result.missing_effect == "unexplained"
    assert "remaining: free_bending.tip_x, pressure_kpa" in result.verdict


# ------------------------------------------- a second continuum: the heavy finger on a fingertip stop

HEAVY_FINGER_LINE = "# finger: {length_mm: 100, segments: 20, mass_g: 5}"
#: The heavy beam's true mass, kg (the CSV's finger line tells the model 5 g).
HEAVY_KG = 0.060


@cache
def _heavy_rows(noise_rel: float, seed: int) -> str:
    rows = heavy_beam.bench_rows(heavy_beam.HeavyBeam(mass_kg=HEAVY_KG), "fingertip", noise_rel, seed)
    return rows.to_csv(index=False, float_format="%.9g")


def diagnose_heavy_beam(tmp_path: Path, noise_rel: float, seed: int, bench_line: str) -> dict[str, object]:
    """``somo-sweep diagnose`` on the heavy beam's rows (fingertip stop) under ``bench_line``."""
    csv = tmp_path / "heavy_beam.csv"
    csv.write_text("\n".join(filter(None, [HEAVY_FINGER_LINE, bench_line, _heavy_rows(noise_rel, seed)])))
    res = CliRunner().invoke(app, ["diagnose", str(csv), "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    record: dict[str, object] = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    _log({"case": f"heavy_beam {bench_line or 'plate'}", "seed": seed, "noise_rel": noise_rel, **record})
    return record


def fitted_weight_kg(record: dict[str, object]) -> tuple[float, float]:
    """The bending body's mass the best candidate fits (told 5 g plus the added mass) and its error."""
    candidates = record["candidates"]
    assert isinstance(candidates, list)
    best = next(c for c in candidates if c["name"] == record["best_candidate"])
    return 0.005 + best["parameters"]["added_mass_kg"], best["parameter_stderr"]["added_mass_kg"]


#: Seed 2 draws tip x at 80, 100 and 120 kPa +0.97, +0.90 and +0.77 σ: so smooth that the
#: second-difference noise estimate is a third of the noise drawn (0.27 mm against 0.8 mm at 1 %),
#: and the run rule calls those three rows systematic (2.9x that estimate). The weight is right.
_SMOOTH_DRAW = pytest.mark.xfail(
    strict=True, reason="seed 2's smooth tip-x draws read as a systematic run (noise estimate 3x low)"
)


def _heavy_marks(noise_rel: float, seed: int) -> list[pytest.MarkDecorator]:
    marks = [] if (noise_rel, seed) == (0.01, 3) else [pytest.mark.slow]
    return marks + ([_SMOOTH_DRAW] if seed == 2 else [])


@pytest.mark.parametrize(
    ("noise_rel", "seed"),
    [
        pytest.param(noise, seed, id=f"seed{seed}-noise{100 * noise:.0f}pct", marks=_heavy_marks(noise, seed))
        for noise in NOISES
        for seed in SEEDS
    ],
)
def test_a_heavy_finger_on_a_fingertip_stop_is_named_with_its_weight(
    tmp_path: Path, noise_rel: float, seed: int
) -> None:
    """60 g, told 5 g, the CSV saying ``stop: fingertip``: the weight within 5 %, ``self_weight``."""
    record = diagnose_heavy_beam(tmp_path, noise_rel, seed, "# bench: {stop: fingertip}")
    assert record["bench_stop"] == "fingertip"
    assert record["best_candidate"] == "self_weight"
    weight, error = fitted_weight_kg(record)
    assert weight == pytest.approx(HEAVY_KG, rel=0.05)
    assert 0 < error < 0.05 * HEAVY_KG
    assert record["missing_effect"] == "self_weight", record["verdict"]


@pytest.mark.slow
def test_read_as_a_plate_bench_the_fingertip_rows_stay_unexplained(tmp_path: Path) -> None:
    """The held-out miss: on a plate the finger would put its whole weight on the stop at 0–20 kPa,
    the rows show ~3/8 of it; the best the weight can do is split the difference (54 ± 2 g at this
    seed) and leave free bending at low pressure millimetres off, so nothing is named."""
    record = diagnose_heavy_beam(tmp_path, 0.01, 3, "")
    assert record["missing_effect"] == "unexplained", record["verdict"]
    assert record["best_candidate"] == "self_weight"
    assert fitted_weight_kg(record)[0] < 0.95 * HEAVY_KG
