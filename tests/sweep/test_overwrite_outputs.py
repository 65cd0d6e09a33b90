"""``run --overwrite`` with another study leaves none of the old study's outputs: the figures,
label tables and headlines that ``classify``, ``paper fig6`` and ``answer`` wrote into the results
folder are listed in its manifest, and deleted with the rest; nothing else is."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app

STUDY = """name: {name}
task: pinch_grasp
model: models/pinch_gripper.yaml
sweep:
  task.distal_segment_ratio: [0.2, 0.4]
  task.object_width_m: [{width}]
  task.centering_position_m: [0.1]
seed: 0
simulation: {{engine: mujoco}}
"""


def _invoke(*args: str) -> str:
    result = CliRunner().invoke(app, list(args))
    assert result.exit_code == 0, result.output
    return result.output


def test_an_overwrite_deletes_the_old_studys_derived_outputs_and_keeps_the_users_files(
    tmp_path: Path,
) -> None:
    """The old study's grasp_labels_contacts.csv and fig6_contacts.json (headline 0.25) stayed."""
    pytest.importorskip("mujoco")
    (tmp_path / "models").symlink_to(MODELS)
    first, second = tmp_path / "a.yaml", tmp_path / "b.yaml"
    first.write_text(STUDY.format(name="a", width=0.02))
    second.write_text(STUDY.format(name="b", width=0.06))
    out = tmp_path / "results"
    _invoke("run", str(first), "--out", str(out), "--no-plots", "-j", "1")
    _invoke("classify", str(out))
    _invoke("paper", "fig6", str(out))
    _invoke("paper", "fig6", str(out), "--rule", "paper", "--out", str(tmp_path / "figures"))
    _invoke(
        "answer",
        str(out),
        "--smallest",
        "distal_segment_ratio",
        "--every",
        "object_width_m",
        "--csv",
        str(out),
    )
    derived = [
        "grasp_labels_contacts.csv",
        "fig6_contacts.png",
        "fig6_contacts.svg",
        "fig6_contacts.json",
        "fig6_contacts_summary.csv",
        "fig6_paper.json",
        "answers.csv",
    ]
    assert all((out / name).exists() for name in derived)
    listed = set(json.loads((out / "manifest.json").read_text())["files"])
    assert set(derived) <= listed
    (out / "notes.txt").write_text("mine\n")
    said = _invoke("run", str(second), "--out", str(out), "--overwrite", "--no-plots", "-j", "1")
    assert "--overwrite: deleted" in said
    assert [name for name in derived if (out / name).exists()] == []
    assert (out / "notes.txt").read_text() == "mine\n"
    assert (tmp_path / "figures" / "fig6_paper.png").exists()  # outside the folder: never deleted
