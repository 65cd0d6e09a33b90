"""``somo-sweep render``: snapshots of one pinch-grasp trial, and the times it refuses."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app


def _study(folder: Path, params: str) -> Path:
    shutil.copytree(MODELS, folder / "models")
    path = folder / "one.yaml"
    path.write_text(
        "name: one\ntask: pinch_grasp\nmodel: models/pinch_gripper.yaml\n"
        f"params: {{{params}}}\nsweep:\n  task.distal_segment_ratio: [0.0]\n"
    )
    return path


@pytest.mark.parametrize(
    ("at_s", "message"),
    [
        ("1e300", "--at-s 1e+300: a snapshot time must be from 0 to 4 s (the trial's length)"),
        ("-1", "--at-s -1: a snapshot time must be from 0 to 4 s"),
        ("nan", "--at-s nan: a snapshot time must be from 0 to 4 s"),  # was a ValueError traceback
        (",", "--at-s: give 1 to 100 snapshot times, got 0"),
        (",".join(["1"] * 101), "--at-s: give 1 to 100 snapshot times, got 101"),
        ("one", "--at-s must be comma-separated numbers, got 'one'"),
    ],
)
def test_snapshot_times_outside_the_trial_are_refused_before_it_runs(
    tmp_path: Path, at_s: str, message: str
) -> None:
    path = _study(tmp_path, "object_width_m: 0.04")
    res = CliRunner().invoke(
        app, ["render", str(path), "--trial", "0", "--at-s", at_s, "--out", str(tmp_path / "r")]
    )
    assert res.exit_code == 2 and message in res.output and "Traceback" not in res.output
    assert not (tmp_path / "r").exists()


def test_a_trial_that_ends_early_says_so_and_renders_what_it_reached(tmp_path: Path) -> None:
    """DSR 0, a 10-mm box at c = 175 mm: no contact by the end of the squeeze (the quick study at
    0.5 ms: 2.08 s)."""
    path = _study(tmp_path, "object_width_m: 0.01, centering_position_m: 0.175")
    text = path.read_text() + "simulation: {time_step_s: 5.0e-4, body_per_manipulator: true}\n"
    path.write_text(text)
    out = tmp_path / "r"
    res = CliRunner().invoke(
        app, ["render", str(path), "--trial", "0", "--at-s", "0.5,3.5", "--out", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert "trial 0: no_grasp (ended early at 2." in res.output
    assert ": no_contact_after_squeeze; no snapshot after it); step 0.5 ms\n" in res.output
    assert sorted(p.name for p in out.iterdir()) == ["one_dsr0.00_w10mm_c175mm_t0.50s.png"]
    assert (out / "one_dsr0.00_w10mm_c175mm_t0.50s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_study_that_has_not_chosen_its_step_says_it_draws_the_starting_guess(tmp_path: Path) -> None:
    path = _study(tmp_path, "object_width_m: 0.04, centering_position_m: 0.100")
    res = CliRunner().invoke(
        app, ["render", str(path), "--trial", "0", "--at-s", "0.1", "--out", str(tmp_path / "r")]
    )
    assert res.exit_code == 0, res.output
    assert "the automatic step's starting guess: this study has not chosen its step yet" in res.output


def test_render_runs_a_trial_on_mujoco_and_draws_it(tmp_path: Path) -> None:
    """``--engine mujoco`` reruns the study's trial on MuJoCo (its own numerics) and draws it there."""
    pytest.importorskip("mujoco")
    path = _study(tmp_path, "object_width_m: 0.04, centering_position_m: 0.100")
    out = tmp_path / "r"
    res = CliRunner().invoke(
        app, ["render", str(path), "--trial", "0", "--at-s", "3.5", "--out", str(out), "--engine", "mujoco"]
    )
    if "MuJoCo cannot render here" in res.output:
        pytest.skip("no OpenGL library for MuJoCo's offscreen renderer")
    assert res.exit_code == 0, res.output
    assert res.output.startswith("trial 0: ")
    image = out / "one_mujoco_dsr0.00_w40mm_c100mm_t3.50s.png"
    assert sorted(p.name for p in out.iterdir()) == [image.name]
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_an_engine_render_does_not_know_is_refused(tmp_path: Path) -> None:
    path = _study(tmp_path, "object_width_m: 0.04")
    res = CliRunner().invoke(
        app, ["render", str(path), "--trial", "0", "--engine", "ode", "--out", str(tmp_path / "r")]
    )
    assert res.exit_code == 2 and "engine must be one of pybullet, mujoco, got 'ode'" in res.output
    assert not (tmp_path / "r").exists()
