"""The sweep engine: results table, resume, crash, blow-up, lock, changed study, bad input.

Most tests use the ``selftest_*`` tasks (milliseconds per trial, real worker processes);
the determinism tests sweep the ``bench`` task's free-bending protocol over pressure.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.sweep.jobs.table import build_jobs, trial_modules
from somo_sweep.sweep.run.execution import dask_client
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import ResultStore, read_manifest, read_results
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.plots import summary_figure
from somo_sweep.sweep.views.results import Results

#: Columns that legitimately differ between runs of the same study.
RUN_COLUMNS = ["wall_time_s", "host"]


def make_study(folder: Path, body: str, name: str = "study.yaml") -> Path:
    """A study file in ``folder`` (next to a copy of the bundled models)."""
    if not (folder / "models").exists():
        shutil.copytree(MODELS, folder / "models")
    path = folder / name
    path.write_text(textwrap.dedent(body))
    return path


def selftest_study(
    folder: Path, task: str = "selftest_sleep", extra: str = "", n: int = 8, auto: bool = False
) -> Path:
    """A study of ``n`` trials x = 1..n of a selftest task; ``extra`` lines go at the end.

    It names its step (1 ms) unless ``extra`` has a ``simulation:`` or ``auto`` is set: without one a
    run first chooses the step from a sample of its cells (sweep/convergence.py).
    """
    if not auto and "simulation" not in extra:
        extra = f"{extra}\nsimulation: {{time_step_s: 1.0e-3}}"
    params = "" if "task.sleep_s" in extra else "params: {sleep_s: 0.0}\n"  # one key per field
    body = (
        f"name: st\ntask: {task}\nmodel: models/ihm_finger.yaml\n{params}"
        f"sweep:\n  task.x: {{start: 1, stop: {n}, step: 1}}\n{extra}\n"
    )
    return make_study(folder, body)


def results_only(df: pd.DataFrame) -> pd.DataFrame:
    return df.drop(columns=RUN_COLUMNS).sort_values("job_id").reset_index(drop=True)


def test_run_writes_one_row_per_trial_with_params_metrics_labels_and_provenance(tmp_path: Path) -> None:
    study = load_study(selftest_study(tmp_path), tmp_path / "out")
    summary = run_sweep(study, RunOptions(n_jobs=1))
    assert summary.run == 8 and summary.by_status == {"ok": 8}
    df = pd.read_parquet(tmp_path / "out" / "trials")  # one pandas call
    assert len(df) == 8 and set(df["status"]) == {"ok"}
    assert {"job_id", "seed", "task_x", "task_sleep_s", "y", "noise", "label_sign", "wall_time_s"} <= set(
        df.columns
    )
    assert (df["y"] == df["task_x"] ** 2).all()
    assert df["noise"].dtype == "float64" and df["label_sign"].eq("positive").all()
    manifest = read_manifest(tmp_path / "out")
    assert manifest["study_hash"] == df["study_hash"].iloc[0]
    assert {"python", "pybullet", "somo-sweep"} <= set(manifest["versions"])
    assert manifest["hosts"] and manifest["runs"][0]["status"] == "completed"
    assert manifest["runs"][0]["to_run"] == 8 and "cells_not_stored" not in manifest["runs"][0]
    assert manifest["runs"][0]["start_utc"] and manifest["runs"][0]["end_utc"]
    schema = pq.read_schema(next((tmp_path / "out" / "trials").glob("*.parquet")))
    assert schema.field("wall_time_s").metadata == {b"unit": b"s"}


def test_dry_run_prints_the_job_table_and_writes_nothing(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    res = CliRunner().invoke(app, ["run", str(path), "--dry-run", "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "8 trials" in res.output and "job_id" in res.output
    assert not (tmp_path / "out").exists()


def test_job_ids_are_stable_and_follow_the_model_content(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    a, b = build_jobs(load_study(path)), build_jobs(load_study(path))
    assert [j.job_id for j in a.jobs] == [j.job_id for j in b.jobs] and a.study_hash == b.study_hash
    path.write_text(path.read_text() + "set:\n  model.manipulator.actuators[0].length_m: 0.11\n")
    c = build_jobs(load_study(path))
    assert not {j.job_id for j in a.jobs} & {j.job_id for j in c.jobs}


def test_a_worker_imports_what_a_trial_imports_before_forking_it() -> None:
    """A module a trial imports itself (the bench statics, SciPy) must be imported in the worker,
    once, not in every forked trial, where the import is redone and lost with the child."""
    code = (
        "import sys\n"
        "from somo_sweep.model.tables import bundled_path\n"
        "from somo_sweep.sweep.run.execution import run_isolated\n"
        "from somo_sweep.sweep.jobs.table import first_jobs\n"
        "from somo_sweep.sweep.study import load_study\n"
        "job = first_jobs(load_study(bundled_path('finger_pressure_sweep.yaml')), 1)[0]\n"
        "solver = 'somo_sweep.statics.solve'\n"
        "before = solver in sys.modules\n"
        "out = run_isolated(job)\n"
        "print(out.status, before, solver in sys.modules, 'scipy.linalg' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["ok", "False", "True", "True"]


def test_code_version_covers_the_code_a_trial_runs_and_nothing_else() -> None:
    bench = trial_modules("somo_sweep.tasks.bench.task")
    assert {
        "somo_sweep.tasks.bench.task",
        "somo_sweep.statics.bench",
        "somo_sweep.sim.world",
        "somo_sweep.sim.pybullet.springs",
    } <= set(bench)
    assert not {
        "somo_sweep.cli.app",
        "somo_sweep.sweep.run.runner",
        "somo_sweep.sweep.store.result_store",
        "somo_sweep.sweep.views.plots",
    } & set(bench)
    assert "somo_sweep.sim.world" not in trial_modules("somo_sweep.tasks.selftest")


@pytest.mark.parametrize("engine,other", [("pybullet", "mujoco"), ("mujoco", "pybullet")])
def test_a_trial_hashes_its_own_engine_and_not_the_other(engine: str, other: str) -> None:
    """The sim layer imports both engines by name, lazily: a scan of its imports finds both, but a
    trial runs one, so editing MuJoCo must keep a PyBullet study's job ids, and the reverse."""
    for task in ("somo_sweep.tasks.pinch_grasp.task", "somo_sweep.tasks.bench.task"):
        modules = trial_modules(task, engine)
        assert f"somo_sweep.sim.{engine}.world" in modules
        assert not [m for m in modules if m.startswith(f"somo_sweep.sim.{other}")], task


def test_resume_runs_only_missing_trials_and_gives_the_same_table(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, extra="repeats: 2")
    full = load_study(path, tmp_path / "full")
    run_sweep(full, RunOptions(n_jobs=1))
    reference = read_results(tmp_path / "full")
    part = load_study(path, tmp_path / "part")
    run_sweep(part, RunOptions(n_jobs=1, chunk_rows=4))
    parts = sorted((tmp_path / "part" / "trials").glob("*.parquet"))
    assert len(parts) == 4
    for p in parts[1:3]:
        p.unlink()
    summary = run_sweep(load_study(path, tmp_path / "part"), RunOptions(n_jobs=1))
    assert (summary.skipped, summary.run) == (8, 8)
    pd.testing.assert_frame_equal(results_only(read_results(tmp_path / "part")), results_only(reference))
    again = run_sweep(load_study(path, tmp_path / "part"), RunOptions(n_jobs=1))
    assert again.run == 0


def test_a_dying_trial_process_is_an_error_and_the_sweep_goes_on(tmp_path: Path) -> None:
    path = selftest_study(
        tmp_path,
        task="selftest_crash",
        extra="  task.how: [exit, segfault, kill]\nset: {task.crash_x: [2.0]}",
        n=3,
    )
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=2))
    assert summary.run == 9 and summary.by_status == {"ok": 6, "error": 3}
    df = read_results(tmp_path / "out").set_index(["task_x", "task_how"])
    assert df.loc[(1.0, "kill"), "status"] == "ok"
    assert "died (exit code 3)" in df.loc[(2.0, "exit"), "message"]
    assert "SIGSEGV" in df.loc[(2.0, "segfault"), "message"]
    assert "SIGKILL" in df.loc[(2.0, "kill"), "message"]
    res = CliRunner().invoke(app, ["show", str(tmp_path / "out")])
    assert "most common reasons (not ok)" in res.output and "exit code 3" in res.output
    assert df.loc[(3.0, "segfault"), "y"] == 9.0


def test_an_exception_in_a_trial_is_an_error_with_its_message(tmp_path: Path) -> None:
    path = selftest_study(
        tmp_path, task="selftest_crash", extra="set: {task.crash_x: [2.0], task.how: raise}", n=3
    )
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert summary.by_status == {"ok": 2, "error": 1}
    df = read_results(tmp_path / "out").set_index("task_x")
    assert df.loc[2.0, "message"] == "RuntimeError: selftest failure at x=2.0"


def test_identical_trials_are_refused(tmp_path: Path) -> None:
    path = make_study(
        tmp_path, "task: selftest_sleep\nmodel: models/ihm_finger.yaml\nsweep: {task.x: [1.0, 2.0, 1.0]}\n"
    )
    # Refused as the study loads (so --dry-run says it too), not only once the jobs are built.
    with pytest.raises(SomoError, match=r"sweep.task.x: value 1.0 is given twice \(entries 0 and 2\)"):
        load_study(path)


def test_resume_skips_errors_unless_asked_to_retry_them(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, task="selftest_crash", extra="set: {task.crash_x: [2.0, 5.0]}", n=6)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1, chunk_rows=4))
    assert run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1)).run == 0
    again = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1, retry_errors=True))
    assert (again.skipped, again.run, again.by_status) == (4, 2, {"error": 2})
    df = read_results(tmp_path / "out")
    assert len(df) == 6 and df["job_id"].is_unique and (df["status"] == "error").sum() == 2


def test_first_rows_without_metrics_still_give_one_readable_schema(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, task="selftest_crash", extra="set: {task.crash_x: [1.0, 2.0]}", n=4)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1, chunk_rows=1))
    df = pd.read_parquet(tmp_path / "out" / "trials").sort_values("trial")
    assert list(df["status"]) == ["error", "error", "ok", "ok"]
    assert df["y"].isna().tolist() == [True, True, False, False]


def test_a_blow_up_is_stored_as_unstable_not_as_an_outcome(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, task="selftest_unstable", extra="set: {task.unstable_x: [3.0]}", n=4)
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert summary.by_status == {"ok": 3, "unstable": 1}
    row = read_results(tmp_path / "out").set_index("task_x").loc[3.0]
    assert row["status"] == "unstable" and "unstable" in row["message"]
    assert pd.isna(row["y"]) and pd.isna(row["label_sign"])


def test_a_second_run_on_a_locked_folder_refuses_clearly(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    study = load_study(path, tmp_path / "out")
    table = build_jobs(study)
    holder = ResultStore(study.output, table.study_hash, table.resolved, table.axes, {})
    try:
        res = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out"), "-j", "1"])
        assert res.exit_code == 2
        assert "is in use by another somo-sweep run (pid" in res.output
        assert "Traceback" not in res.output
        assert not list((tmp_path / "out" / "trials").glob("*.parquet"))
    finally:
        holder.close()
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out"), "-j", "1", "--no-plots"])
    assert res.exit_code == 0, res.output


def test_results_of_a_changed_study_are_never_mixed_in(tmp_path: Path) -> None:
    path = selftest_study(tmp_path)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    before = read_results(tmp_path / "out")
    path.write_text(path.read_text().replace("stop: 8", "stop: 9"))
    with pytest.raises(SomoError, match="holds results of a different study") as info:
        run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert "changed: sweep.task.x (8 values -> 9 values)" in str(info.value) and "--out" in str(info.value)
    pd.testing.assert_frame_equal(read_results(tmp_path / "out"), before)
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1, overwrite=True))
    assert (summary.skipped, summary.run) == (0, 9)
    assert len(read_results(tmp_path / "out")) == 9


def test_a_trial_over_its_time_limit_is_an_error(tmp_path: Path) -> None:
    path = selftest_study(tmp_path, extra="set: {task.sleep_s: 30.0}", n=1)
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1, timeout_s=0.5))
    assert summary.by_status == {"error": 1}
    assert read_results(tmp_path / "out")["message"].iloc[0] == "timed out after 0.5 s"


def test_an_unreachable_dask_scheduler_is_a_clear_error() -> None:
    with pytest.raises(SomoError, match=r"cannot connect to the Dask scheduler at tcp://127\.0\.0\.1:9"):
        dask_client("tcp://127.0.0.1:9", timeout_s=1.0)


def test_a_scheduler_address_dask_cannot_parse_names_the_form() -> None:
    with pytest.raises(SomoError, match=r"--scheduler nonsense://x is not a Dask address .*tcp://HOST:8786"):
        dask_client("nonsense://x", timeout_s=1.0)


def test_a_server_that_is_not_a_dask_scheduler_is_a_clear_error() -> None:
    """A web server on the port answers bytes that Dask reads as a frame length of exabytes."""
    import socket
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]

    def answer() -> None:
        conn, _ = server.accept()
        with conn:
            conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)
            conn.recv(1024)

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    try:
        with pytest.raises(SomoError, match=rf"127\.0\.0\.1:{port}"):
            dask_client(f"tcp://127.0.0.1:{port}", timeout_s=3.0)
    finally:
        server.close()


def test_dask_backend_needs_a_scheduler(tmp_path: Path) -> None:
    res = CliRunner().invoke(app, ["run", str(selftest_study(tmp_path)), "--backend", "dask"])
    assert res.exit_code == 2 and "--backend dask needs --scheduler" in res.output


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        (None, "file not found"),
        ("task: bench\nmodel: models/ihm_finger.yaml\nsweep: {task.pressure_kpa: [0, 1}\n", "cannot parse"),
        ("task: bnch\nmodel: models/ihm_finger.yaml\n", "unknown task 'bnch' (did you mean 'bench'?)"),
        (
            "task: bench\nmodel: models/ihm_finger.yaml\nrepeat: 2\n",
            "unknown key 'repeat' (did you mean 'repeats'?)",
        ),
        (
            "task: bench\nmodel: models/ihm_finger.yaml\n"
            "sweep: {task.pressure_kpa: {start: 0, stop: 9, step: -1}}\n",
            "line 3: sweep.task.pressure_kpa.step: must be > 0, got -1",
        ),
        (
            "task: bench\nmodel: models/ihm_finger.yaml\nsweep: {task.pressure_kpa: []}\n",
            "at least one value",
        ),
        (
            "task: bench\nmodel: models/ihm_finger.yaml\nseed: abc\n",
            "line 3: seed: expected an integer >= 0, not text, got 'abc'",
        ),
    ],
    ids=[
        "missing-file",
        "yaml-syntax",
        "unknown-task",
        "unknown-key",
        "negative-step",
        "empty-axis",
        "wrong-type",
    ],
)
def test_bad_input_exits_2_with_one_message_and_writes_nothing(
    tmp_path: Path, body: str | None, expected: str
) -> None:
    path = tmp_path / "missing.yaml" if body is None else make_study(tmp_path, body)
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out")])
    assert res.exit_code == 2
    assert expected in res.output and res.output.startswith("error: ")
    assert "Traceback" not in res.output
    assert not (tmp_path / "out").exists()


def test_show_and_plot_summarise_a_results_folder(tmp_path: Path) -> None:
    run_sweep(load_study(selftest_study(tmp_path), tmp_path / "out"), RunOptions(n_jobs=1))
    res = CliRunner().invoke(app, ["show", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert "8 of 8 trials stored" in res.output and "by task.x: sign" in res.output
    assert "positive" in res.output
    res = CliRunner().invoke(app, ["plot", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "plots" / "summary.png").read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert (tmp_path / "out" / "plots" / "summary.svg").read_text().startswith("<?xml")
    assert (tmp_path / "out" / "plots" / "label_map_sign.png").read_bytes().startswith(b"\x89PNG")
    res = CliRunner().invoke(app, ["show", str(tmp_path)])
    assert res.exit_code == 2 and "not a somo-sweep results folder" in res.output


def test_signal_handlers_are_restored_after_a_run(tmp_path: Path) -> None:
    before = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    run_sweep(load_study(selftest_study(tmp_path, n=2), tmp_path / "out"), RunOptions(n_jobs=1))
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def test_plots_of_a_folder_without_one_ok_trial_draw_without_warnings(tmp_path: Path) -> None:
    # Every trial raised: no lines and no bars to put in a legend (matplotlib warned twice).
    body = (
        "name: st\ntask: selftest_crash\nmodel: models/ihm_finger.yaml\n"
        "params: {sleep_s: 0.0, crash_x: [1, 2, 3], how: raise}\n"
        "sweep:\n  task.x: [1, 2, 3]\n  task.u: [0.5, 1.5]\n"
    )
    summary = run_sweep(load_study(make_study(tmp_path, body), tmp_path / "out"), RunOptions(n_jobs=1))
    assert summary.by_status == {"error": 6}
    df = pd.read_parquet(tmp_path / "out" / "trials")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        summary_figure(Results.of_table(df, read_manifest(tmp_path / "out")))
