"""Hostile study files: huge grids, bombs, NaN, bad bytes, repeated keys, results outside results/."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from test_sweep import make_study, selftest_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.jobs import table as jobs_module
from somo_sweep.sweep.study import load_study

HEAD = "task: selftest_sleep\nmodel: models/ihm_finger.yaml\n"


def _problems(path: Path, **kwargs: object) -> str:
    with pytest.raises(DescriptionError) as info:
        load_study(path, **kwargs)  # type: ignore[arg-type]
    return str(info.value)


def test_a_billion_trial_grid_is_refused_at_once_with_its_count(tmp_path: Path) -> None:
    path = make_study(
        tmp_path,
        HEAD + "sweep:\n"
        "  task.x: {start: 0, stop: 1, num: 1000}\n"
        "  task.sleep_s: {start: 0, stop: 1, num: 1000}\n"
        "  model.manipulator.actuators[0].length_m: {start: 0.1, stop: 0.2, num: 1000}\n",
    )
    start = time.perf_counter()
    text = _problems(path)
    assert time.perf_counter() - start < 1.0
    assert (
        "line 3: sweep: the study has 1000000000 trials (1000000000 grid points x 1 repeat(s)); "
        "allowed: at most 1000000; pass --max-trials 1000000000 to run it anyway"
    ) in text


def test_a_billion_value_range_is_refused_from_the_command_line(tmp_path: Path) -> None:
    path = make_study(tmp_path, HEAD + "sweep:\n  task.x: {start: 0, stop: 1000000000, step: 1}\n")
    start = time.perf_counter()
    res = CliRunner().invoke(app, ["run", str(path), "--dry-run"])
    assert time.perf_counter() - start < 2.0
    assert res.exit_code == 2 and "the study has 1000000001 trials" in res.output
    assert "--max-trials 1000000001" in res.output and "Traceback" not in res.output


def test_max_trials_sets_the_limit(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, extra="repeats: 2")
    res = CliRunner().invoke(app, ["run", str(path), "--max-trials", "10", "--out", str(tmp_path / "out")])
    assert (
        res.exit_code == 2
        and "the study has 16 trials (8 grid points x 2 repeat(s)); allowed: at most 10" in (res.output)
    )
    assert not (tmp_path / "out").exists()
    assert load_study(path, max_trials=16).n_trials == 16


def test_a_dry_run_prints_count_and_first_rows_without_building_every_job(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = selftest_study(tmp_path, n=200, extra="repeats: 1000")

    def refuse(*args: object) -> None:
        raise AssertionError("the dry run built the whole job table")

    monkeypatch.setattr(jobs_module, "build_jobs", refuse)
    start = time.perf_counter()
    res = CliRunner().invoke(app, ["run", str(path), "--dry-run"])
    assert res.exit_code == 0, res.output
    assert time.perf_counter() - start < 5.0
    assert "st: task selftest_sleep, 200000 trials (200 grid points x 1000 repeat(s))" in res.output
    assert "job_id" in res.output and "... 199990 more" in res.output


@pytest.mark.parametrize(
    ("line", "where", "shown"),
    [
        ("sweep: {task.x: [1.0, .nan]}", "line 3: sweep.task.x[1]", "nan"),
        ("sweep: {task.x: {values: [.inf]}}", "line 3: sweep.task.x.values[0]", "inf"),
        ("params: {sleep_s: -.inf}", "line 3: params.sleep_s", "-inf"),
        ("set: {task.x: .nan}", "line 3: set.task.x", "nan"),
    ],
    ids=["axis", "values", "params", "set"],
)
def test_nan_and_infinity_are_refused_with_their_key_path(
    tmp_path: Path, line: str, where: str, shown: str
) -> None:
    path = make_study(tmp_path, HEAD + line + "\n")
    assert f"{where}: must be a finite number, got {shown}" in _problems(path)


def test_an_alias_bomb_study_is_refused_at_once(tmp_path: Path) -> None:
    pairs = zip("abcdefgh", "bcdefghi", strict=True)
    levels = "".join(f"_{c}: &{c} [" + ", ".join([f"*{p}"] * 9) + "]\n" for p, c in pairs)
    path = make_study(
        tmp_path, HEAD + "_a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9]\n" + levels + "params: {crash_x: *i}\n"
    )
    start = time.perf_counter()
    res = CliRunner().invoke(app, ["run", str(path), "--dry-run"])
    assert time.perf_counter() - start < 2.0
    assert res.exit_code == 2 and "expands to more than 100000 values" in res.output


def test_a_key_given_twice_names_both_lines(tmp_path: Path) -> None:
    path = make_study(tmp_path, HEAD + "repeats: 1\nseed: 3\nrepeats: 2\n")
    assert (
        "line 5: repeats: key 'repeats' is given twice (lines 3 and 5); allowed: each key once per mapping"
        in _problems(path)
    )


def test_a_study_that_is_not_utf8_names_the_byte(tmp_path: Path) -> None:
    path = tmp_path / "study.yaml"
    path.write_bytes(HEAD.encode() + "# réglages\n".encode("latin-1"))
    res = CliRunner().invoke(app, ["run", str(path), "--dry-run"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert (
        f"error: {path}: 1 problem(s)\n  - <top level>: not UTF-8 text: byte 0xe9 at offset 54" in res.output
    )


def test_a_binary_study_is_named_binary(tmp_path: Path) -> None:
    path = tmp_path / "study.json"
    path.write_bytes(b"PK\x03\x04\x14\x00\x00\x00")
    assert "binary file (NUL byte at offset 5); allowed: UTF-8 text" in _problems(path)


@pytest.mark.parametrize(
    ("line", "key", "given"),
    [
        ('name: ".."', "name", ".."),
        ("output: ../..", "output", "../.."),
        ("output: /some/dir", "output", "/some/dir"),
        ("output: results", "output", "results"),
    ],
    ids=["name-dotdot", "output-up", "output-absolute", "output-the-root-itself"],
)
def test_results_may_not_leave_the_results_root_unless_out_is_given(
    tmp_path: Path, line: str, key: str, given: str
) -> None:
    path = make_study(tmp_path, HEAD + line + "\n")
    assert (
        f"line 3: {key}: '{given}' puts the results in" in _problems(path)
        and "outside results/; allowed: a folder inside results/ of the current directory "
        "(or choose any folder with --out)"
        in _problems(path)
    )
    assert load_study(path, tmp_path / "chosen").output == tmp_path / "chosen"


def test_output_inside_results_is_accepted(tmp_path: Path) -> None:
    path = make_study(tmp_path, HEAD + "output: results/sub/folder\n")
    assert load_study(path).output == Path("results/sub/folder")


def test_a_model_that_is_not_a_model_file_is_blamed_on_the_model_key(tmp_path: Path) -> None:
    secret = tmp_path / "passwd"
    secret.write_text("root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\n")
    path = make_study(tmp_path, f"task: selftest_sleep\nmodel: {secret}\n")
    text = _problems(path)
    assert f"line 2: model: {secret}: <top level>: top level must be a mapping of keys" in text
    assert "root:x" not in text and "daemon" not in text


def test_a_model_that_cannot_be_parsed_is_blamed_without_quoting_it(tmp_path: Path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text("manipulator:\n  name: [api-key-42\n")
    text = _problems(make_study(tmp_path, f"task: selftest_sleep\nmodel: {broken}\n"))
    assert f"line 2: model: {broken}: line 3: <top level>: cannot parse" in text and "api-key-42" not in text


BIG = "z" * 1_000_000


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (f"sampling: {BIG}\n", "line 3: sampling: Input should be 'grid', 'adaptive' or 'active', got 'zzz"),
        (f"params: {{sleep_s: {BIG}}}\n", "line 3: params.sleep_s: expected a number >= 0, not text"),
        (f"? {BIG}\n: 1\n", "line 3: zzz"),
        (f"name: {BIG}\n", "line 3: name: String should have at most 100 characters"),
    ],
    ids=["choice", "number", "key", "name"],
)
def test_a_megabyte_value_or_key_is_cut_in_the_message(tmp_path: Path, body: str, message: str) -> None:
    text = _problems(make_study(tmp_path, HEAD + body))
    assert message in text and "(1000000 characters)" in text
    assert len(text) < 1500


def test_an_unknown_megabyte_task_name_is_cut(tmp_path: Path) -> None:
    text = _problems(make_study(tmp_path, f"task: {BIG}\nmodel: models/ihm_finger.yaml\n"))
    assert "unknown task 'zzz" in text and "… (1000000 characters)'; allowed: bench, ihm_gait" in text
    assert len(text) < 1000


def test_a_results_folder_name_too_long_for_the_file_system_is_one_line(tmp_path: Path) -> None:
    path = make_study(tmp_path, HEAD + f"output: results/{'q' * 300}\n")
    res = CliRunner().invoke(app, ["run", str(path)])
    assert res.exit_code == 2 and "cannot create the results folder results/qqq" in res.output
    assert "File name too long" in res.output and "Traceback" not in res.output


def test_an_os_error_no_command_foresaw_is_one_line_naming_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from somo_sweep.cli.app import main

    path = make_study(tmp_path, HEAD + "sweep:\n  task.x: [1, 2]\n")
    monkeypatch.setattr("sys.argv", ["somo-sweep", "run", str(path), "--out", "q" * 300])
    with pytest.raises(SystemExit) as info:
        main()
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: qqq") and err.count("\n") == 1
    assert err.endswith(
        "… (300 characters): the name is longer than the file system allows (File name too long); give a "
        "shorter name, then run the same command again\n"
    )


def test_a_pinch_grasp_object_wider_than_any_link_is_refused_before_any_trial(tmp_path: Path) -> None:
    path = make_study(
        tmp_path,
        "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\n"
        "sweep:\n  task.object_width_m: [0.04, 1.0e+300]\n",
    )
    assert "line 4: sweep.task.object_width_m: Input should be less than or equal to 100, got 1e+300" in (
        _problems(path)
    )


def test_a_nul_byte_in_output_is_refused_at_its_line(tmp_path: Path) -> None:
    """It passed --dry-run and then was a ValueError traceback from mkdir."""
    path = selftest_study(tmp_path, extra='output: "results/x\\u0000y"')
    assert "output: holds a NUL byte, which no folder name can" in _problems(path)


def test_a_long_name_is_cut_with_its_own_length_said(tmp_path: Path) -> None:
    """A 300-character name was reported as "(302 characters)": the length of its repr."""
    path = make_study(tmp_path, f"name: {'a' * 300}\n" + HEAD)
    text = _problems(path)
    assert f"name: String should have at most 100 characters, got '{'a' * 60}…' (300 characters)" in text


@pytest.mark.parametrize(
    ("line", "message"),
    [
        (
            'simulation: {engine: mujoco, noslip_iterations: "5"}',
            "line 3: simulation.noslip_iterations: expected an integer from 0 to 1000, not text "
            "(unquote it), got '5'",
        ),
        (
            'simulation: {time_step_s: "1e-3"}',
            "line 3: simulation.time_step_s: expected a number > 0, not text (unquote it), got '1e-3'",
        ),
        ('repeats: "2"', "line 3: repeats: expected an integer >= 1, not text (unquote it), got '2'"),
        (
            'robustness: {replicas: "4"}',
            "line 3: robustness.replicas: expected an integer from 0 to 16, not text (unquote it)",
        ),
    ],
    ids=["noslip", "step", "repeats", "replicas"],
)
def test_a_quoted_number_in_the_study_settings_stays_text_and_is_refused(
    tmp_path: Path, line: str, message: str
) -> None:
    """Quoting keeps a value text: ``noslip_iterations: "5"`` was taken as 5."""
    path = make_study(tmp_path, HEAD + line + "\nsweep:\n  task.x: [1, 2]\n")
    text = _problems(path)
    assert str(path) in text and message in text
