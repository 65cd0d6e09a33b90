"""A CSV diagnosed from Python as the command does it: the effects named on the command line,
and a first calibration that fits nothing stopping the diagnosis with its evidence."""

from __future__ import annotations

from dataclasses import replace

import pytest
from conftest import ROOT

from somo_sweep.calibration import solve
from somo_sweep.diagnosis import workflow
from somo_sweep.diagnosis.effects import EFFECTS
from somo_sweep.diagnosis.workflow import DiagnosisOptions, FingerNotCalibrated, diagnose_csv, effect_names
from somo_sweep.errors import SomoError

SYNTHETIC = ROOT / "studies" / "tables" / "planar_finger_synthetic.csv"


def test_effect_names_keeps_each_once_in_the_order_given() -> None:
    first, second = list(EFFECTS)[:2]
    assert effect_names(None) is None
    assert effect_names(f" {second}, {first},{second} ,") == (second, first)


def test_effect_names_refuses_an_empty_list_and_an_unknown_name() -> None:
    with pytest.raises(SomoError, match="--effects names no effect; allowed: comma-separated names from"):
        effect_names(" , ")
    with pytest.raises(SomoError, match="unknown effect 'bogus'"):
        effect_names(f"{next(iter(EFFECTS))},bogus")


def test_a_first_calibration_that_fits_nothing_stops_with_its_result(monkeypatch: pytest.MonkeyPatch) -> None:
    def unfitted(problem, n_jobs=1):  # type: ignore[no-untyped-def]
        return replace(solve.solve_paper(problem, n_jobs), message="not fitted: (test)", fitted=False)

    monkeypatch.setattr(workflow, "solve_fit", unfitted)
    with pytest.raises(FingerNotCalibrated) as caught:
        diagnose_csv(SYNTHETIC, DiagnosisOptions(n_jobs=1))
    assert caught.value.source == str(SYNTHETIC) and not caught.value.calibration.fitted
    assert str(caught.value).startswith(
        f"{SYNTHETIC}: calibrating the CSV's finger first: not fitted: (test)"
    )
