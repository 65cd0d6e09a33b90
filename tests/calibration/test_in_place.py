"""Calibrating a finger in place, as the README types it: ``calibrate mine/bench.csv --model
mine/finger.yaml -o mine/finger.yaml`` onto the file ``new grasp-study`` wrote, then again onto the
calibrated file; what calibration does not fit is kept, the values before are in the provenance,
and a user's own file or a file changed meanwhile is never replaced."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.model.load import load_model

ROOT = Path(__file__).resolve().parents[2]
#: Bench rows of a 12-link, 70-mm finger solved on an independent elastica (the starter's finger).
BENCH = ROOT / "examples" / "own_gripper" / "finger_bench.csv"
IN_PLACE = ["calibrate", "mine/bench.csv", "--model", "mine/finger.yaml", "-o", "mine/finger.yaml"]


@pytest.fixture
def mine(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A starter folder ``mine`` in a fresh working folder, its bench.csv filled."""
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["new", "grasp-study", "mine"])
    assert result.exit_code == 0, result.output
    shutil.copy(BENCH, tmp_path / "mine" / "bench.csv")
    return tmp_path / "mine"


def _unfitted(path: Path) -> dict[str, Any]:
    """The model's fields with the fitted ones (joint stiffness, pressure gain) and provenance out."""
    data = load_model(path).model_dump(mode="json", exclude={"provenance"})
    for act in data["manipulator"]["actuators"]:
        for joint in act["joints"]:
            joint.pop("stiffness_n_m_per_rad")
    data["manipulator"]["actuation"].pop("pressure_gain_n_m_per_kpa")
    return data


def test_calibrating_the_starters_finger_in_place_keeps_the_rest_and_the_values_before(mine: Path) -> None:
    design = mine / "finger.yaml"
    design_bytes = design.read_bytes()
    (mine / "design_copy.yaml").write_bytes(design_bytes)
    before = load_model(design).manipulator
    assert before is not None and before.actuation is not None
    result = CliRunner().invoke(app, IN_PLACE)
    assert result.exit_code == 0, result.output
    assert "calibrated in place" in result.output
    assert _unfitted(design) == _unfitted(mine / "design_copy.yaml")
    after = load_model(design)
    assert after.provenance is not None
    record = after.provenance["calibration"]
    assert record["model"] == "mine/finger.yaml"
    assert record["model_sha256"] == hashlib.sha256(design_bytes).hexdigest()
    assert record["replaced"] == {  # exactly the fitted fields, with the design's values
        "manipulator.actuators[0].joints[0].stiffness_n_m_per_rad": before.actuators[0].joints[0].stiffness,
        "manipulator.actuation.pressure_gain_n_m_per_kpa": before.actuation.pressure_gain_n_m_per_kpa,
    }
    assert "previous" not in record
    # Every finger of the gripper is the calibrated one (by reference).
    assert after.manipulator is not None and after.manipulator.actuation is not None
    gain = after.manipulator.actuation.pressure_gain_n_m_per_kpa
    assert gain != before.actuation.pressure_gain_n_m_per_kpa
    fingers = load_model(mine / "gripper.yaml").as_assembly().manipulators
    gains = [m.manipulator.actuation.pressure_gain_n_m_per_kpa for m in fingers]  # type: ignore[union-attr]
    assert gains == [gain, gain]


def test_a_second_calibration_in_place_works_and_keeps_the_first_as_previous(mine: Path) -> None:
    assert CliRunner().invoke(app, IN_PLACE).exit_code == 0
    first = load_model(mine / "finger.yaml").provenance["calibration"]  # type: ignore[index]
    result = CliRunner().invoke(app, IN_PLACE)
    assert result.exit_code == 0, result.output
    second = load_model(mine / "finger.yaml").provenance["calibration"]  # type: ignore[index]
    assert second["previous"]["measurements"] == "mine/bench.csv"
    assert second["previous"]["created_utc"] == first["created_utc"]
    assert second["previous"]["values"] == {k: v["value"] for k, v in first["parameters"].items()}
    fitted = [p["value"] for p in first["parameters"].values()]
    assert all(old in fitted for old in second["replaced"].values())  # what it replaced: the first's
    # The same rows fit the same values again (within the fit's own relative error, 0.3 %).
    for name, p in second["parameters"].items():
        assert p["value"] == pytest.approx(first["parameters"][name]["value"], rel=3e-3)


def test_a_users_own_model_is_not_calibrated_in_place(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A hand-written file (its comments, its ``file:`` references) is never rewritten: -o another name."""
    monkeypatch.chdir(tmp_path)
    text = (ROOT / "examples" / "own_gripper" / "finger.yaml").read_text().replace("somo-sweep", "the tool")
    (tmp_path / "mine.yaml").write_text(text)
    shutil.copy(BENCH, tmp_path / "bench.csv")
    result = CliRunner().invoke(app, ["calibrate", "bench.csv", "--model", "mine.yaml", "-o", "mine.yaml"])
    assert result.exit_code == 2
    message = " ".join(result.output.split())
    assert "mine.yaml exists and has no 'somo-sweep' header" in message
    assert "-o the --model file calibrates it in place, which replaces only a model somo-sweep" in message
    assert (tmp_path / "mine.yaml").read_text() == text


def test_a_model_changed_while_it_is_calibrated_is_not_replaced(
    mine: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from somo_sweep.calibration import workflow

    real = workflow.calibrate_csv
    edited = "# somo-sweep: edited by hand during the fit\n" + (mine / "finger.yaml").read_text()

    def calibrate_while_editing(*args: Any, **kwargs: Any) -> Any:
        out = real(*args, **kwargs)
        (mine / "finger.yaml").write_text(edited)
        return out

    monkeypatch.setattr(workflow, "calibrate_csv", calibrate_while_editing)
    result = CliRunner().invoke(app, IN_PLACE)
    assert result.exit_code == 2
    assert "mine/finger.yaml changed while it was being calibrated; nothing was written" in result.output
    assert (mine / "finger.yaml").read_text() == edited
