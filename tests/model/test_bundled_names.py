"""The README's ``studies/...`` paths work from any folder, as they must for an installed package
(which has no ``studies/`` beside the user), and a user's own missing file is never replaced by a
bundled one."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from somo_sweep.calibration.measurements import read_measurements
from somo_sweep.cli.app import GLOBAL_FLAGS, app, empty_value, global_flags_first, main
from somo_sweep.errors import DescriptionError, MeasurementError
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_if_missing, bundled_path


@pytest.fixture
def empty(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty working folder: no ``studies/`` link, as after a wheel install."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize(
    ("typed", "folder", "suffix", "bundled"),
    [
        ("studies/models/ihm_finger.yaml", "models", ".yaml", ("models", "ihm_finger.yaml")),
        ("ihm_finger.yaml", "models", ".yaml", ("models", "ihm_finger.yaml")),
        ("ihm_finger", "models", ".yaml", ("models", "ihm_finger.yaml")),
        (
            "models/ihm_finger.yaml",
            "models",
            ".yaml",
            ("models", "ihm_finger.yaml"),
        ),  # a bundled study's layout
        (
            "studies/tables/planar_finger_bench_2.csv",
            "tables",
            ".csv",
            ("tables", "planar_finger_bench_2.csv"),
        ),
        ("planar_finger_bench_2", "tables", ".csv", ("tables", "planar_finger_bench_2.csv")),
        ("studies/pinch_grasp_demo.yaml", "", ".yaml", ("pinch_grasp_demo.yaml",)),
        ("pinch_grasp_demo", "", ".yaml", ("pinch_grasp_demo.yaml",)),
    ],
)
def test_a_missing_path_spelling_a_bundled_file_finds_it(
    empty: Path, typed: str, folder: str, suffix: str, bundled: tuple[str, ...]
) -> None:
    found = bundled_if_missing(typed, folder, suffix)
    assert found == bundled_path(*bundled) and found.is_file()


@pytest.mark.parametrize(
    "typed",
    [
        "my/models/ihm_finger.yaml",  # the user's own folder layout: their file is missing
        "my/studies/models/ihm_finger.yaml",
        "studies/tables/ihm_finger.yaml",  # a model under the tables' folder
        "tables/ihm_finger.yaml",
        "studies/models/nope.yaml",
        "studies/models/../models/ihm_finger.yaml",
        "..",
        "ihm_finger.yaml\x00",
        "x" * 5000,
    ],
)
def test_other_missing_paths_stay_as_typed(empty: Path, typed: str) -> None:
    assert bundled_if_missing(typed, "models") == Path(typed)


def test_an_absolute_missing_path_stays(empty: Path) -> None:
    assert bundled_if_missing(empty / "ihm_finger.yaml", "models") == empty / "ihm_finger.yaml"


def test_the_users_own_file_wins_over_the_bundled_one(empty: Path) -> None:
    (empty / "studies" / "models").mkdir(parents=True)
    mine = empty / "studies" / "models" / "ihm_finger.yaml"
    mine.write_text("manipulator: {name: mine}\n")
    assert bundled_if_missing("studies/models/ihm_finger.yaml", "models") == Path(
        "studies/models/ihm_finger.yaml"
    )
    with pytest.raises(DescriptionError):  # the user's (invalid) file is read, not the bundled one
        load_model("studies/models/ihm_finger.yaml")


def test_load_model_and_read_measurements_take_the_readme_paths(empty: Path) -> None:
    model = load_model("studies/models/ihm_finger.yaml")
    assert model.manipulator is not None and model.manipulator.name == "ihm_finger"
    rows = read_measurements("studies/tables/planar_finger_synthetic.csv")
    assert len(rows) > 0


def test_a_missing_model_names_the_bundled_ones_and_a_study_reference_does_not_fall_back(empty: Path) -> None:
    with pytest.raises(DescriptionError, match=r"file not found; bundled files .*ihm_finger\.yaml"):
        load_model("studies/models/ihm_fingr.yaml")
    with pytest.raises(DescriptionError, match=r"file not found$"):
        load_model("ihm_finger.yaml", bundled=False)
    with pytest.raises(MeasurementError, match=r"file not found; bundled .*planar_finger_bench_2\.csv"):
        read_measurements("measurements.csv")


def test_calibrate_and_check_run_the_readme_lines_from_an_empty_folder(empty: Path) -> None:
    runner = CliRunner()
    res = runner.invoke(app, ["check", "studies/models/ihm_finger.yaml"])
    assert res.exit_code == 0 and "ihm_finger: base fixed" in res.output, res.output
    res = runner.invoke(
        app, ["calibrate", "studies/tables/planar_finger_synthetic.csv", "-o", "results/planar_finger.yaml"]
    )
    assert res.exit_code == 0, res.output
    assert load_model(empty / "results" / "planar_finger.yaml").manipulator is not None
    assert sorted(p.name for p in empty.iterdir()) == ["results"]  # nothing else written here


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["calibrate", "m.csv", "-q"], ["-q", "calibrate", "m.csv"]),
        (
            ["run", "s.yaml", "--debug", "--jobs", "2", "-v"],
            ["--debug", "-v", "run", "s.yaml", "--jobs", "2"],
        ),
        (["-q", "run", "s.yaml"], ["-q", "run", "s.yaml"]),
        (["run", "s.yaml", "--", "-q"], ["run", "s.yaml", "--", "-q"]),
        (["run", "-quiet.yaml"], ["run", "-quiet.yaml"]),
    ],
)
def test_global_flags_typed_after_the_command_move_in_front(args: list[str], expected: list[str]) -> None:
    assert global_flags_first(args) == expected


def test_no_command_has_an_option_named_like_a_global_flag() -> None:
    """Moving the flags in front would otherwise take them from the command."""
    import typer.main

    group = typer.main.get_command(app)
    seen: list[str] = []

    def walk(cmd: object) -> None:
        for sub in getattr(cmd, "commands", {}).values():
            seen.extend(o for p in sub.params for o in (*p.opts, *p.secondary_opts))
            walk(sub)

    walk(group)
    assert seen and not set(seen) & GLOBAL_FLAGS


def test_quiet_after_the_command_works_from_the_console_script(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr("sys.argv", ["somo-sweep", "tasks", "-q"])
    with pytest.raises(SystemExit) as exit_:
        main()
    assert exit_.value.code in (0, None)
    out = capsys.readouterr()
    assert "pinch_grasp" in out.out and "No such option" not in out.err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "s.yaml", "--out", ""], "--out was given an empty value"),
        (["run", "s.yaml", "--out="], "--out was given an empty value"),
        (["calibrate", "m.csv", "-o", ""], "-o was given an empty value"),
        (["run", ""], "an argument is empty"),
        (["run", "s.yaml", "--out", "."], None),
        (["run", "s.yaml", "--out=results/x"], None),
    ],
)
def test_an_empty_value_is_named(args: list[str], message: str | None) -> None:
    assert empty_value(args) == message


def test_an_empty_folder_is_refused_not_read_as_this_folder(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Typer reads "" as ".": --out "$UNSET" wrote the results into the current folder."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(
        "sys.argv", ["somo-sweep", "run", str(bundled_path("finger_pressure_sweep.yaml")), "--out", ""]
    )
    with pytest.raises(SystemExit) as exit_:
        main()
    assert exit_.value.code == 2
    assert "--out was given an empty value" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_path_that_is_not_utf8_is_named_not_a_traceback(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A folder named in Latin-1 ended show, plot and paper fig6 in pyarrow's UnicodeEncodeError."""
    name = os.fsdecode(b"r\xe9sultats")  # a lone surrogate where the byte is not UTF-8
    monkeypatch.setattr("sys.argv", ["somo-sweep", "show", str(tmp_path / name)])
    with pytest.raises(SystemExit) as exit_:
        main()
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "r\\xe9sultats' holds bytes that are not UTF-8 text; allowed: UTF-8 names" in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    "typed",
    ["pinch_gripper.yaml", "pinch_gripper", "models/pinch_gripper.yaml", "studies/models/pinch_gripper.yaml"],
)
def test_a_study_s_model_spelling_a_bundled_one_finds_it_when_its_folder_has_none(
    empty: Path, typed: str
) -> None:
    from somo_sweep.sweep.study import load_study

    (empty / "elsewhere").mkdir()
    study = empty / "elsewhere" / "study.yaml"
    study.write_text(f"task: pinch_grasp\nmodel: {typed}\nsimulation: {{engine: mujoco}}\n")
    assert load_study(study).model_path == bundled_path("models", "pinch_gripper.yaml")


def test_a_study_s_own_model_wins_and_a_missing_one_lists_the_bundled_names(empty: Path) -> None:
    from somo_sweep.sweep.study import load_study

    (empty / "models").mkdir()
    (empty / "models" / "pinch_gripper.yaml").write_text("manipulator: {name: mine}\n")
    study = empty / "study.yaml"
    study.write_text("task: pinch_grasp\nmodel: models/pinch_gripper.yaml\n")
    with pytest.raises(DescriptionError, match=r"models/pinch_gripper\.yaml: line 1: manipulator\.actuators"):
        load_study(study)
    study.write_text("task: pinch_grasp\nmodel: models/my_gripper.yaml\n")
    with pytest.raises(DescriptionError) as info:
        load_study(study)
    assert [p.render() for p in info.value.problems] == [
        f"line 2: model: model file not found: {empty / 'models' / 'my_gripper.yaml'}; bundled files "
        "(by NAME or as models/NAME, studies/models/NAME): arm_with_fingers.yaml, ihm_finger.yaml, "
        "ihm_hand.yaml, pinch_finger.yaml, pinch_finger_original.yaml, pinch_gripper.yaml, "
        "pinch_gripper_original.yaml, snake.yaml, whole_arm.yaml"
    ]
