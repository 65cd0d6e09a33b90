"""``somo-sweep new grasp-study``: a finger ``run`` would refuse is refused up front in ``run``'s
words; bundled finger names work as the docs spell them; a path in the way exits 2; the "next:"
line runs as printed; the finger file is one ``calibrate`` may replace in place."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.study import load_study

TEMPLATE = bundled_path("starters", "grasp_study", "finger.yaml")


def _finger(change: Any) -> dict[str, Any]:
    data = yaml.safe_load(TEMPLATE.read_text())
    change(data["manipulator"])
    return data


def _three_actuators(finger: dict[str, Any]) -> None:
    act = finger["actuators"][0]
    finger["actuators"] = [{**act, "name": f"a{i}", "length_m": 0.028, "n_segments": 4} for i in range(3)]


def _no_actuation(finger: dict[str, Any]) -> None:
    del finger["actuation"]


def _run_refusals(tmp_path: Path, finger: dict[str, Any]) -> list[str]:
    """What `run` (loading the study) says of a starter whose finger.yaml is ``finger``."""
    folder = tmp_path / "as_run"
    assert CliRunner().invoke(app, ["new", "grasp-study", str(folder)]).exit_code == 0
    (folder / "finger.yaml").write_text(yaml.safe_dump(finger))
    with pytest.raises(DescriptionError) as info:
        load_study(folder / "study.yaml")
    return [p.message for p in info.value.problems]


@pytest.mark.parametrize("change", [_three_actuators, _no_actuation], ids=["three_actuators", "no_actuation"])
def test_a_finger_run_would_refuse_is_refused_with_runs_words(tmp_path: Path, change: Any) -> None:
    finger = _finger(change)
    (tmp_path / "f.yaml").write_text(yaml.safe_dump(finger))
    argv = ["new", "grasp-study", str(tmp_path / "mine"), "--finger", str(tmp_path / "f.yaml")]
    result = CliRunner().invoke(app, argv)
    assert result.exit_code == 2
    assert not (tmp_path / "mine").exists()
    said = " ".join(result.output.split())
    assert "a gripper of 2 of these fingers would be refused by `somo-sweep run`" in said
    refusals = _run_refusals(tmp_path, finger)
    assert refusals
    for message in refusals:
        assert " ".join(message.split()) in said


@pytest.mark.parametrize("name", ["pinch_finger", "pinch_finger.yaml", "studies/models/pinch_finger.yaml"])
def test_a_bundled_finger_is_found_by_the_name_the_docs_give(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    monkeypatch.chdir(tmp_path)  # no studies/ folder here
    result = CliRunner().invoke(app, ["new", "grasp-study", "mine", "--finger", name])
    assert result.exit_code == 0, result.output
    written = (tmp_path / "mine" / "finger.yaml").read_text()
    assert written.startswith(f"# Written by somo-sweep new grasp-study from {name}.")
    assert written.endswith(bundled_path("models", "pinch_finger.yaml").read_text())
    assert "segments: 20" in (tmp_path / "mine" / "bench.csv").read_text()


def test_a_file_in_the_folders_path_exits_2_and_writes_nothing(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("mine\n")
    result = CliRunner().invoke(app, ["new", "grasp-study", str(tmp_path / "afile" / "sub")])
    assert result.exit_code == 2
    assert f"{tmp_path / 'afile'} is a file, not a folder; nothing was written" in result.output
    assert (tmp_path / "afile").read_text() == "mine\n"


def test_the_next_line_runs_as_printed_in_a_folder_with_spaces(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["new", "grasp-study", "my grasp study"])
    assert result.exit_code == 0, result.output
    line = next(ln for ln in result.output.splitlines() if ln.startswith("next: "))
    command = shlex.split(line.removeprefix("next: ").split("   (")[0])
    assert command == ["somo-sweep", "run", "my grasp study/study.yaml"]
    assert Path(command[2]).is_file()
