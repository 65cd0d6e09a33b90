"""Command-line conventions: exit codes, messages before progress bars, help texts, tasks, workers, Dask."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click
import joblib
import pytest
import typer
from test_sweep import selftest_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.sweep.run.execution import dask_client
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import read_manifest
from somo_sweep.sweep.study import load_study

CRASHING = "set: {task.crash_x: [2.0, 5.0], task.how: raise}"


def _run(path: Path, out: Path, *extra: str) -> object:
    return CliRunner().invoke(app, ["run", str(path), "--out", str(out), "-j", "1", "--no-plots", *extra])


def test_run_exits_1_when_a_trial_ended_in_error(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, task="selftest_crash", extra=CRASHING, n=6)
    res = _run(path, tmp_path / "out")
    assert res.exit_code == 1, res.output
    assert "2 of 6 trial(s) ended in error (exit code 1)" in res.output and "--allow-errors" in res.output


def test_allow_errors_accepts_a_run_with_errors(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, task="selftest_crash", extra=CRASHING, n=6)
    assert _run(path, tmp_path / "out", "--allow-errors").exit_code == 0


def test_resuming_a_folder_with_errors_says_how_many_and_names_retry_errors(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, task="selftest_crash", extra=CRASHING, n=6)
    _run(path, tmp_path / "out")
    res = _run(path, tmp_path / "out")
    assert res.exit_code == 1
    assert (
        f"resuming {tmp_path / 'out'}: 6 of 6 trials already stored, 2 of them as error; "
        "run with --retry-errors to run those again"
    ) in res.output
    assert "already done" not in res.output


def test_a_refused_run_draws_no_progress_bar(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    path.write_text(path.read_text().replace("stop: 8", "stop: 9"))
    res = _run(path, tmp_path / "out")
    assert res.exit_code == 2 and "holds results of a different study" in res.output
    assert "━" not in res.output and "trials/s" not in res.output
    assert res.output.startswith("error: ")


def _commands(group: click.Command, prefix: str = "") -> list[tuple[str, click.Command]]:
    found = [(prefix, group)]
    for name, sub in getattr(group, "commands", {}).items():
        found += _commands(sub, f"{prefix} {name}".strip())
    return found


@pytest.mark.parametrize("name", [n for n, _ in _commands(typer.main.get_command(app))])
def test_help_shows_flags_as_flags_and_no_raw_markup(name: str) -> None:
    res = CliRunner().invoke(app, [*name.split(), "--help"], terminal_width=200)
    assert res.exit_code == 0, res.output
    assert "<bool>" not in res.output
    assert "``" not in res.output
    usage = next(line for line in res.output.splitlines() if "Usage:" in line)
    assert "{" not in usage, usage


def test_run_help_lists_its_arguments_in_capitals() -> None:
    res = CliRunner().invoke(app, ["run", "--help"], terminal_width=200)
    assert "run [OPTIONS] STUDY" in res.output


def test_tasks_hides_selftest_tasks_unless_all() -> None:
    shown = CliRunner().invoke(app, ["tasks"]).output
    assert "bench [bench]" in shown and "selftest" not in shown
    assert "selftest_sleep [selftest]" in CliRunner().invoke(app, ["tasks", "--all"]).output


def test_shell_completion_is_offered() -> None:
    res = CliRunner().invoke(app, ["--help"], terminal_width=200)
    assert "--install-completion" in res.output and "--show-completion" in res.output


def test_default_workers_follow_the_cpus_this_process_may_use(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(joblib, "cpu_count", lambda *a, **k: 1)
    monkeypatch.setattr("os.cpu_count", lambda: 64)
    run_sweep(load_study(selftest_study(tmp_path, n=2), tmp_path / "out"), RunOptions())
    assert read_manifest(tmp_path / "out")["runs"][-1]["n_jobs"] == 1


def test_dask_backend_without_dask_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(SomoError) as info:
        dask_client("tcp://127.0.0.1:9")
    assert str(info.value) == (
        '--backend dask needs Dask, which is not installed: pip install "somo-sweep[dask]"'
    )


def test_dask_backend_without_dask_is_a_clear_cli_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    res = _run(
        selftest_study(tmp_path), tmp_path / "out", "--backend", "dask", "--scheduler", "tcp://127.0.0.1:9"
    )
    assert res.exit_code == 2 and 'pip install "somo-sweep[dask]"' in res.output
    assert "Traceback" not in res.output and not (tmp_path / "out").exists()


def test_measure_refuses_nan_values_clearly() -> None:
    from conftest import MODELS

    res = CliRunner().invoke(
        app, ["measure", str(MODELS / "ihm_finger.yaml"), "--test", "free_bending", "--values", "10,nan"]
    )
    assert res.exit_code == 2
    assert res.output.startswith("error: --values must be finite numbers, got nan in '10,nan'")


def test_the_cli_default_trial_limit_is_the_librarys() -> None:
    from somo_sweep.cli.sweep import MAX_TRIALS as CLI_LIMIT
    from somo_sweep.sweep.study import MAX_TRIALS

    assert CLI_LIMIT == MAX_TRIALS


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "STUDY", "--jobs", "1000000"],
        ["run", "STUDY", "--jobs", "-1"],
        ["calibrate", "MEASUREMENTS", "--jobs", "0"],
        ["calibrate", "MEASUREMENTS", "--jobs", "1000000"],
        ["diagnose", "MEASUREMENTS", "--jobs", "1000000"],
        ["paper", "fig3", "--jobs", "1000000"],
    ],
    ids=["run-huge", "run-negative", "calibrate-zero", "calibrate-huge", "diagnose-huge", "fig3-huge"],
)
def test_jobs_beyond_what_the_machine_can_hold_are_refused_before_any_process(
    tmp_path: Path, argv: list[str]
) -> None:
    """--jobs 1000000 used to start that many loky processes (about 90 MB each)."""
    from somo_sweep.cli.output import MAX_JOBS_PER_CPU

    bench = Path(__file__).parents[2] / "somo_sweep" / "data" / "tables" / "planar_finger_synthetic.csv"
    argv = [
        str(selftest_study(tmp_path)) if a == "STUDY" else str(bench) if a == "MEASUREMENTS" else a
        for a in argv
    ]
    res = CliRunner().invoke(app, argv)
    limit = MAX_JOBS_PER_CPU * (joblib.cpu_count() or 1)
    assert res.exit_code == 2, res.output
    assert f"--jobs must be from 1 to {limit}" in res.output and "workers per CPU" in res.output
    assert not (tmp_path / "results").exists()


def test_a_study_smaller_than_jobs_starts_no_idle_worker(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from somo_sweep.sweep.run import execution

    asked: list[int] = []
    real = execution._parallel

    def spy(n_jobs: int) -> object:
        asked.append(n_jobs)
        return real(n_jobs)

    monkeypatch.setattr(execution, "_parallel", spy)
    summary = run_sweep(load_study(selftest_study(tmp_path, n=3), tmp_path / "out"), RunOptions(n_jobs=8))
    # The workers started ahead (while the jobs are built) and the run's pool: 3 each, never 8.
    assert summary.run == 3 and set(asked) == {3}


def test_ctrl_c_during_a_long_step_says_what_stopped_and_that_nothing_was_written(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from somo_sweep.cli.output import working

    with pytest.raises(KeyboardInterrupt), working("calibrating (fit)", bench_rows=True):
        raise KeyboardInterrupt
    assert "interrupted while calibrating (fit): nothing was written" in capsys.readouterr().err


@pytest.mark.parametrize("timeout", ["nan", "-1", "0"])
def test_a_timeout_that_no_trial_can_meet_is_refused_before_any_trial(tmp_path: Path, timeout: str) -> None:
    """--timeout nan or -1 stored every trial as an error."""
    res = _run(selftest_study(tmp_path), tmp_path / "out", "--timeout", timeout)
    assert res.exit_code == 2 and "--timeout must be a number of seconds > 0" in res.output  # type: ignore[attr-defined]
    assert not (tmp_path / "out").exists()


BENCH = Path(__file__).parents[2] / "somo_sweep" / "data" / "tables" / "planar_finger_synthetic.csv"
FINGER_MODEL = Path(__file__).parents[2] / "somo_sweep" / "data" / "models" / "ihm_finger.yaml"


@pytest.mark.parametrize(
    ("argv", "kind"),
    [
        (["calibrate", str(BENCH), "-o", "FILE"], "text"),
        (["measure", str(FINGER_MODEL), "--test", "tip_load", "--values", "0.1", "--csv", "FILE"], "text"),
        (["recheck", "STUDY", "-n", "1", "--report", "FILE"], "json"),
    ],
    ids=["calibrate", "measure", "recheck"],
)
def test_a_file_somo_sweep_did_not_write_is_never_replaced(
    tmp_path: Path, argv: list[str], kind: str
) -> None:
    """`-o notes.txt` would have replaced it."""
    precious = tmp_path / "notes.txt"
    precious.write_text("my own notes\n")
    study = selftest_study(tmp_path)
    argv = [str(precious) if a == "FILE" else str(study) if a == "STUDY" else a for a in argv]
    res = CliRunner().invoke(app, argv)
    assert res.exit_code == 2, res.output
    what = 'has no "written_by": "somo-sweep …" key' if kind == "json" else "has no 'somo-sweep' header"
    assert f"{precious} exists and {what}: somo-sweep did not write it, so it is not replaced" in res.output
    assert precious.read_text() == "my own notes\n"


def test_calibrate_never_writes_over_its_own_measurements_and_replaces_its_own_model(tmp_path: Path) -> None:
    measurements = tmp_path / "m.csv"
    measurements.write_bytes(BENCH.read_bytes())  # has a somo-sweep header: only the input rule saves it
    res = CliRunner().invoke(app, ["calibrate", str(measurements), "-o", str(measurements)])
    assert res.exit_code == 2 and "is this command's input" in res.output
    assert measurements.read_bytes() == BENCH.read_bytes()
    model = tmp_path / "model.yaml"
    for _ in range(2):  # the second run replaces the model the first one wrote
        res = CliRunner().invoke(app, ["calibrate", str(measurements), "-o", str(model)])
        assert res.exit_code == 0, res.output
    assert model.read_text().startswith("# calibrated by somo-sweep calibrate")


def test_diagnose_out_folder_keeps_the_users_own_report_and_replaces_its_own(tmp_path: Path) -> None:
    out = tmp_path / "here"
    out.mkdir()
    (out / "report.md").write_text("my report\n")
    res = CliRunner().invoke(app, ["diagnose", str(BENCH), "--out", str(out), "--effects", "self_weight"])
    assert res.exit_code == 2 and "report.md exists and has no 'somo-sweep' header" in res.output
    assert (out / "report.md").read_text() == "my report\n" and len(list(out.iterdir())) == 1
    (out / "report.md").write_text("# Diagnosis of an earlier version's run\n")  # before the header
    res = CliRunner().invoke(app, ["diagnose", str(BENCH), "--out", str(out), "--effects", "self_weight"])
    assert res.exit_code == 0, res.output
    assert (out / "report.md").read_text().startswith("<!-- written by somo-sweep diagnose -->")


def test_the_resource_trackers_leak_list_is_filtered_for_the_processes_a_run_starts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Loky's resource tracker is a process of its own that outlives a killed run; it printed its
    list of "leaked" semaphores (which it then removes) under the user's prompt."""
    import subprocess

    from somo_sweep.cli.app import _quiet_resource_tracker

    monkeypatch.setenv("PYTHONWARNINGS", "error::DeprecationWarning")
    _quiet_resource_tracker()
    _quiet_resource_tracker()
    assert os.environ["PYTHONWARNINGS"] == "error::DeprecationWarning,ignore:resource_tracker:UserWarning"
    tracker = (
        "import warnings; warnings.warn('resource_tracker: There appear to be 8 leaked semlock objects')"
    )
    ours = "import warnings; warnings.warn('something else')"
    for code, shown in ((tracker, False), (ours, True)):
        err = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stderr
        assert ("UserWarning" in err) == shown, err


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["calibrate", str(BENCH), "--method", "paper", "-o", "OUT"], "model.yaml"),
        (
            ["measure", str(FINGER_MODEL), "--test", "tip_load", "--values", "0.1", "--csv", "OUT"],
            "measurements.csv",
        ),
        (["recheck", "STUDY", "-n", "1", "--report", "OUT"], "recheck.json"),
    ],
    ids=["calibrate", "measure", "recheck"],
)
@pytest.mark.parametrize("how", ["slash", "existing", "file"])
def test_an_output_file_option_given_a_folder_writes_into_it(
    tmp_path: Path, argv: list[str], name: str, how: str
) -> None:
    """``-o out/`` wrote a file named ``out``. A folder (a trailing slash, or one that exists)
    gets the file under its documented name; a plain new name is still the file itself."""
    study = selftest_study(tmp_path)
    if argv[0] == "recheck":
        run_sweep(load_study(study, tmp_path / "results"), RunOptions(n_jobs=1))
        argv = [*argv, "--out", str(tmp_path / "results")]
    out = tmp_path / "out"
    if how == "existing":
        out.mkdir()
    given = f"{out}/" if how == "slash" else str(out)
    res = CliRunner().invoke(app, [given if a == "OUT" else str(study) if a == "STUDY" else a for a in argv])
    assert res.exit_code == 0, res.output
    if how == "file":
        assert out.is_file()
    else:
        assert out.is_dir() and sorted(os.listdir(out)) == [name]
