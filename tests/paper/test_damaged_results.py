"""Commands that read a results folder, on folders damaged or edited by hand: one line naming the
file and what is wrong, never a traceback, never a double count, never a user's file replaced."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
from test_fig6 import results_folder
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.sweep.store.folder import read_manifest, read_results


def _invoke(*args: str) -> tuple[int, str]:
    res = CliRunner().invoke(app, list(args))
    assert "Traceback" not in res.output
    return res.exit_code, res.output


def _notes(folder: Path) -> tuple[pd.DataFrame, list[str]]:
    seen: list[str] = []
    table = read_results(folder, lambda path, why: seen.append(f"{path.name}: {why}"))
    return table, seen


def test_a_copied_part_file_is_counted_once_and_named(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    manifest = {"study_hash": "h", "files": ["trials/part-0.parquet"]}
    (folder / "manifest.json").write_text(json.dumps(manifest))
    # The copy sorts first; the part the manifest lists is the one kept.
    shutil.copy(folder / "trials" / "part-0.parquet", folder / "trials" / "part-0.bak.parquet")
    table, seen = _notes(folder)
    assert len(table) == 3 and table["job_id"].is_unique and "__part_file__" not in table.columns
    assert seen == ["part-0.bak.parquet: repeats 3 row(s) stored in part-0.parquet: counted once (a copy?)"]
    code, out = _invoke("paper", "fig6", str(folder), "--out", str(tmp_path / "f"))
    assert code == 0 and "3 trials" in out


def test_parts_that_are_not_ours_or_clash_are_skipped_by_name(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    good = pd.read_parquet(folder / "trials" / "part-0.parquet")
    clash = good.assign(job_id=["x0", "x1", "x2"], trial=["0", "1", "2"])  # trial as text
    clash.to_parquet(folder / "trials" / "part-1.parquet")
    good.drop(columns=["status"]).assign(job_id=["y0", "y1", "y2"]).to_parquet(
        folder / "trials" / "part-2.parquet"
    )
    typed = good.assign(job_id=["z0", "z1", "z2"], object_z_m=["a", "b", "c"])  # a metric as text
    typed.to_parquet(folder / "trials" / "part-3.parquet")
    table, seen = _notes(folder)
    assert sorted(table["job_id"]) == ["job0", "job1", "job2"]
    assert (
        seen[0]
        == "part-1.parquet: its 'trial' column holds large_string, not the whole numbers somo-sweep writes"
    )
    assert seen[1] == "part-2.parquet: no 'status' column: not a part file of a somo-sweep results folder"
    assert seen[2] == (
        "part-3.parquet: its 'object_z_m' column holds large_string, where the results hold double"
    )
    for command in (["show", str(folder)], ["classify", str(folder)]):
        code, out = _invoke(*command)
        assert code == 0, out


def test_rows_of_another_study_name_their_file(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    other = pd.read_parquet(folder / "trials" / "part-0.parquet").assign(
        study_hash="zz", job_id=["a", "b", "c"]
    )
    other.to_parquet(folder / "trials" / "my_notes.parquet")
    with pytest.raises(
        SomoError, match=r"3 row\(s\) belong to another study \(hash zz\), in my_notes\.parquet"
    ):
        read_results(folder)


@pytest.mark.parametrize(
    ("edit", "why"),
    [
        ({"axes": ["a"]}, "its 'axes' is list, not a mapping"),
        ({"runs": "x"}, "its 'runs' is str, not a list"),
        ({"runs": ["x"]}, "its 'runs' holds an entry that is not a mapping"),
        ({"n_trials": "24"}, "its 'n_trials' is \"24\", not a whole number of trials"),
    ],
)
def test_a_manifest_edited_into_the_wrong_shape_is_called_damaged(
    tmp_path: Path, edit: dict[str, object], why: str
) -> None:
    folder = results_folder(tmp_path)
    (folder / "manifest.json").write_text(json.dumps({"study_hash": "h", **edit}))
    with pytest.raises(SomoError, match="is damaged"):
        read_manifest(folder)
    for command in ("show", "plot"):
        code, out = _invoke(command, str(folder))
        assert code == 2 and why in out, out


def test_non_finite_parameters_and_missing_status_are_named_rows(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    part = folder / "trials" / "part-0.parquet"
    table = pd.read_parquet(part)
    table.loc[1, "task_distal_segment_ratio"] = float("nan")
    table.to_parquet(part)
    for command in ("classify", "paper fig6"):
        code, out = _invoke(*command.split(), str(folder))
        assert code == 2 and "trial(s) 1 have no finite task_distal_segment_ratio: damaged rows" in out
    table.loc[1, "task_distal_segment_ratio"] = 0.2
    table.loc[0, "status"] = None
    table.to_parquet(part)
    code, out = _invoke("classify", str(folder))
    assert code == 2 and "trial(s) 0 have no status" in out


def test_an_all_error_folder_draws_a_figure(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    part = folder / "trials" / "part-0.parquet"
    pd.read_parquet(part).assign(status="error").to_parquet(part)
    code, out = _invoke("paper", "fig6", str(folder), "--out", str(tmp_path / "f"))
    assert code == 0 and "3 trial(s) without an outcome" in out


def test_an_unfinished_folder_says_the_figure_is_partial(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    (folder / "manifest.json").write_text(json.dumps({"study_hash": "h", "n_trials": 24}))
    code, out = _invoke("paper", "fig6", str(folder), "--out", str(tmp_path / "f"))
    assert code == 0 and "note: 3 of the study's 24 trials are stored" in out


def test_figures_and_labels_never_replace_a_users_file(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    mine = folder / "grasp_labels_contacts.csv"
    mine.write_text("my hand-checked labels\n")
    code, out = _invoke("classify", str(folder))
    assert code == 2 and "is not an earlier copy of this output" in out
    assert mine.read_text() == "my hand-checked labels\n"
    mine.unlink()
    assert _invoke("classify", str(folder))[0] == 0
    assert _invoke("classify", str(folder))[0] == 0  # its own earlier copy is replaced
    out_dir = tmp_path / "figs"
    out_dir.mkdir()
    notes = out_dir / "fig6_contacts_summary.csv"
    notes.write_text("notes\n")
    code, out = _invoke("paper", "fig6", str(folder), "--out", str(out_dir))
    assert code == 2 and notes.read_text() == "notes\n"
    assert sorted(p.name for p in out_dir.iterdir()) == ["fig6_contacts_summary.csv"]  # nothing half-written
    notes.unlink()
    for _ in range(2):
        code, out = _invoke("paper", "fig6", str(folder), "--out", str(out_dir))
        assert code == 0, out


def test_recheck_never_writes_its_report_over_a_results_manifest(tmp_path: Path) -> None:
    from somo_sweep.cli.output import check_replaceable

    folder = results_folder(tmp_path)
    (folder / "manifest.json").write_text(json.dumps({"study_hash": "h", "runs": []}))
    with pytest.raises(SomoError, match="is a results folder's manifest"):
        check_replaceable(folder / "manifest.json", kind="json")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["recheck", "STUDY", "--seed", "-5"], "--seed must be from 0"),
        (["recheck", "STUDY", "--max-trials", "-1"], "--max-trials must be >= 1"),
        (["paper", "palm", "FOLDER"], "not a palm-design study"),
    ],
)
def test_options_and_folders_of_the_wrong_kind_are_one_line(
    tmp_path: Path, args: list[str], message: str
) -> None:
    folder = results_folder(tmp_path)
    args = [str(folder) if a == "FOLDER" else str(tmp_path / "s.yaml") if a == "STUDY" else a for a in args]
    code, out = _invoke(*args, "--out", str(tmp_path / "o"))
    assert code == 2 and message in out, out


def test_a_trial_number_in_other_digits_is_not_an_index() -> None:
    """'²' passed str.isdigit() and then failed int()."""
    from somo_sweep.paper.grasp_trials import find_trial

    with pytest.raises(SomoError):
        find_trial([], "²")


def test_a_foreign_inferred_table_is_skipped_by_name(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    pd.DataFrame({"job_id": [1, 2], "inferred": [True, True]}).to_parquet(folder / "inferred.parquet")
    table, seen = _notes(folder)
    assert len(table) == 3 and seen == [
        "inferred.parquet: its 'job_id' column holds int64, not the text somo-sweep writes"
    ]


def test_an_earlier_copy_of_a_table_with_other_columns_is_still_ours(tmp_path: Path) -> None:
    """A rerun whose trials have another label set adds a column: its own table is replaced."""
    from somo_sweep.cli.output import check_output

    path = tmp_path / "fig6_contacts_summary.csv"
    path.write_text("distal_segment_ratio,object_width_m,no_grasp,pinch,power\n0.1,0.01,0,1,1\n")
    check_output(path, "distal_segment_ratio,object_width_m,no_grasp,pinch,power,unstable\n")
    path.write_text("notes\n")
    with pytest.raises(SomoError, match="is not an earlier copy of this output"):
        check_output(path, "distal_segment_ratio,object_width_m\n")


def test_fig6_compare_names_the_folder_that_is_not_a_pinch_study(tmp_path: Path) -> None:
    good = results_folder(tmp_path / "good")
    bad = results_folder(tmp_path / "bad")
    part = bad / "trials" / "part-0.parquet"
    pd.read_parquet(part).drop(columns=["task_distal_segment_ratio"]).to_parquet(part)
    code, out = _invoke("paper", "fig6-compare", str(good), str(bad), "--out", str(tmp_path / "o"))
    assert code == 2 and f"{bad}: results table lacks distal_segment_ratio" in out.replace("\n", "")


def test_classify_on_another_tasks_folder_names_the_folder_and_its_task(tmp_path: Path) -> None:
    """It listed some 50 missing columns, and neither the folder nor the task."""
    folder = results_folder(tmp_path)
    manifest = read_manifest(folder)
    manifest["study"] = {**manifest.get("study", {}), "task": "bench"}
    (folder / "manifest.json").write_text(json.dumps(manifest))
    table = pd.read_parquet(folder / "trials" / "part-0.parquet")
    table.drop(columns=[c for c in table.columns if c.startswith("hold_")]).to_parquet(
        folder / "trials" / "part-0.parquet"
    )
    code, out = _invoke("classify", str(folder))
    assert code == 2 and f"{folder} holds trials of task 'bench', not pinch_grasp" in out


def test_show_lists_the_latest_runs_of_a_folder_resumed_thousands_of_times(tmp_path: Path) -> None:
    folder = results_folder(tmp_path)
    manifest = read_manifest(folder)
    run = {
        "start_utc": "t0",
        "end_utc": "t1",
        "status": "interrupted",
        "trials_written": 0,
        "backend": "loky",
    }
    manifest["runs"] = [dict(run, start_utc=f"start{i}") for i in range(5000)]
    (folder / "manifest.json").write_text(json.dumps(manifest))
    code, out = _invoke("show", str(folder))
    assert code == 0 and "… 4990 earlier run(s) (all in manifest.json)" in out
    assert "start4999" in out and "start4989" not in out and out.count("  run start") == 10


def test_a_manifest_of_another_folder_is_named_not_the_parts_that_agree(tmp_path: Path) -> None:
    """Every part was blamed ("move that file away") when only the manifest was foreign."""
    folder = results_folder(tmp_path)
    manifest = read_manifest(folder)
    hash_of_parts = pd.read_parquet(folder / "trials")["study_hash"].iloc[0]
    manifest["study_hash"] = "0123456789abcdef"
    (folder / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(SomoError) as info:
        read_results(folder)
    text = str(info.value)
    assert "manifest.json records study hash 0123456789abcdef, but every trial" in text
    assert f"holds {hash_of_parts}" in text and "move the manifest away" in text


def test_a_manifest_nested_too_deeply_is_named_damaged(tmp_path: Path) -> None:
    """A 400 KB manifest nested 200,000 deep was a RecursionError in every reader."""
    folder = results_folder(tmp_path)
    (folder / "manifest.json").write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(SomoError, match=r"manifest.json is damaged \(nested too deeply for a manifest\)"):
        read_manifest(folder)
    code, out = _invoke("show", str(folder))
    assert code == 2 and "nested too deeply" in out


def test_trials_missing_because_a_part_file_is_damaged_are_not_blamed_on_a_run_cut_short(
    tmp_path: Path,
) -> None:
    """fig6 and classify said "(a run unfinished or still going)" of a folder whose runs completed."""
    folder = results_folder(tmp_path)
    runs = [{"status": "completed", "start_utc": "t"}]
    (folder / "manifest.json").write_text(json.dumps({"study_hash": "h", "n_trials": 6, "runs": runs}))
    (folder / "trials" / "part-1.parquet").write_bytes(b"PAR1 half a file")
    for command in (["paper", "fig6", str(folder), "--out", str(tmp_path / "f")], ["classify", str(folder)]):
        code, out = _invoke(*command)
        text = " ".join(out.split())
        assert code == 0, out
        assert "note: 3 of the study's 6 trials are readable: 1 damaged file(s) were left out" in text
        assert "unfinished" not in text and "cut short" not in text
    (folder / "trials" / "part-1.parquet").unlink()
    runs[0]["status"] = "aborted"
    (folder / "manifest.json").write_text(json.dumps({"study_hash": "h", "n_trials": 6, "runs": runs}))
    code, out = _invoke("classify", str(folder))
    assert "3 of the study's 6 trials are stored (the last run was killed)" in " ".join(out.split())


def test_plot_of_a_folder_without_a_readable_trial_says_so_and_writes_nothing(tmp_path: Path) -> None:
    """It wrote an empty plot and exited 0."""
    folder = results_folder(tmp_path)
    (folder / "trials" / "part-0.parquet").write_bytes(b"PAR1 half a file")
    code, out = _invoke("plot", str(folder))
    assert code == 2
    assert "no trial stored that can be read: 1 damaged file(s) were left out" in " ".join(out.split())
    assert not (folder / "plots").exists()
