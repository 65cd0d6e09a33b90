"""Task parameters given by the names they had before they moved: read at their new place, the same
trials as the new names, one notice naming each old key; given by both names, refused naming both.

The pinch task's original-code choices (``restitution``, ``lift_profile``, ``object_shape``,
``clamp_speed_cap``, ``finger_spinning_friction_m``) live under ``task.original`` today.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest
from test_sweep import make_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.study import derive_study, load_study
from somo_sweep.tasks.pinch_grasp.original import Original
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams

HEAD = "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\nsimulation: {time_step_s: 4.0e-3}\n"
PROFILE = "[[0.2, 0.0666666666666667], [0.8, 0.9333333333333333]]"
#: A results folder written before the parameters moved, by that code (its study: study.yaml in it):
#: ``task.restitution`` swept, ``object_shape`` in params, ``task.clamp_speed_cap`` set.
OLD_FOLDER = Path(__file__).parent / "data" / "old_names"


def _jobs(path: Path) -> list[tuple[str, dict[str, object]]]:
    return [(j.job_id, j.params.model_dump(mode="json")) for j in build_jobs(load_study(path)).jobs]


def _problems(path: Path) -> list[str]:
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    return [p.render() for p in info.value.problems]


def test_old_names_in_params_give_the_trials_of_the_new_names_and_one_notice(tmp_path: Path) -> None:
    old = make_study(
        tmp_path,
        HEAD + "params:\n  spring_scale: 2.0\n  finger_spinning_friction_m: 0.0\n  restitution: 0.0\n"
        f"  lift_profile: {PROFILE}\n  object_shape: original_hull\n  clamp_speed_cap: true\n"
        "sweep:\n  task.distal_segment_ratio: [0.1, 0.3]\n",
        "old.yaml",
    )
    new = make_study(
        tmp_path,
        HEAD + "params:\n  spring_scale: 2.0\n  original:\n    finger_spinning_friction_m: 0.0\n"
        f"    restitution: 0.0\n    lift_profile: {PROFILE}\n    object_shape: original_hull\n"
        "    clamp_speed_cap: true\nsweep:\n  task.distal_segment_ratio: [0.1, 0.3]\n",
        "new.yaml",
    )
    assert _jobs(old) == _jobs(new)
    params = build_jobs(load_study(old)).jobs[0].params
    assert isinstance(params, PinchGraspParams)
    assert params.original == Original(
        finger_spinning_friction_m=0.0,
        restitution=0.0,
        lift_profile=((0.2, 0.0666666666666667), (0.8, 0.9333333333333333)),
        object_shape="original_hull",
        clamp_speed_cap=True,
    )
    assert params.spring_scale == 2.0  # a designer's parameter: not moved
    assert load_study(old).notices == (
        f"{old}: old parameter names read at their new place: params.finger_spinning_friction_m "
        "(line 6) → task.original.finger_spinning_friction_m; params.restitution (line 7) → "
        "task.original.restitution; params.lift_profile (line 8) → task.original.lift_profile; "
        "params.object_shape (line 9) → task.original.object_shape; params.clamp_speed_cap (line 10) "
        "→ task.original.clamp_speed_cap; write the new key paths to silence this note",
    )
    assert load_study(new).notices == ()
    assert load_study(old).record() == {**load_study(new).record(), "name": "old"}


def test_old_keys_of_set_sweep_link_and_cells_are_read_at_their_new_place(tmp_path: Path) -> None:
    body = (
        "set:\n  task.@clamp_speed_cap: true\n"
        "sweep:\n  task.@restitution: [null, 0.5]\n  task.distal_segment_ratio: [0.1, 0.3]\n"
        "link:\n  - [task.@restitution, task.distal_segment_ratio]\n"
        "cells:\n  - {task.@finger_spinning_friction_m: 0.0, task.object_width_m: 0.04}\n"
        "  - {task.@finger_spinning_friction_m: 0.001, task.object_width_m: 0.08}\n"
    )
    old = make_study(tmp_path, HEAD + body.replace("@", ""), "old.yaml")
    new = make_study(tmp_path, HEAD + body.replace("@", "original."), "new.yaml")
    assert _jobs(old) == _jobs(new)
    study = load_study(old)
    assert [a.key for a in study.axes] == [
        "task.original.finger_spinning_friction_m",
        "task.object_width_m",
        "task.original.restitution",
        "task.distal_segment_ratio",
    ]
    assert study.fixed == {"task.original.clamp_speed_cap": True}
    (notice,) = study.notices
    assert notice == (
        f"{old}: old parameter names read at their new place: set.task.clamp_speed_cap (line 5) → "
        "task.original.clamp_speed_cap; sweep.task.restitution (line 7) → task.original.restitution; "
        "cells column 'task.finger_spinning_friction_m' (line 12) → "
        "task.original.finger_spinning_friction_m; write the new key paths to silence this note"
    )
    columns = build_jobs(study).frame().columns
    assert {"task_original_restitution", "task_original_clamp_speed_cap"} <= set(columns)
    assert not {"task_restitution", "task_clamp_speed_cap"} & set(columns)


def test_an_old_column_of_a_cells_csv_is_named_with_its_file_and_header_line(tmp_path: Path) -> None:
    (tmp_path / "cells.csv").write_text(
        "# two cells\ntask.restitution,task.object_width_m\n0.0,0.04\n0.5,0.08\n"
    )
    path = make_study(tmp_path, HEAD + "cells: cells.csv\n")
    study = load_study(path)
    assert study.cells is not None and study.cells.keys == (
        "task.original.restitution",
        "task.object_width_m",
    )
    (notice,) = study.notices
    assert (
        f"cells column 'task.restitution' ({tmp_path / 'cells.csv'} line 2) → task.original.restitution"
        in notice
    )


def test_a_bad_value_under_an_old_key_is_blamed_on_that_key_and_its_line(tmp_path: Path) -> None:
    path = make_study(tmp_path, HEAD + "sweep:\n  task.object_shape: [box, hull]\n")
    assert _problems(path) == [
        "line 5: sweep.task.object_shape (task.original.object_shape today): Input should be 'box' or "
        "'original_hull', got 'hull'"
    ]


@pytest.mark.parametrize(
    ("body", "problem"),
    [
        (
            "params:\n  restitution: 0.1\n  original: {restitution: 0.2}\n",
            "line 6: params.original.restitution: overlaps params.restitution (line 5): both set "
            "task.original.restitution, and only one of the values would reach each trial; allowed: "
            "task.original.restitution alone (params.restitution gives it by the name it had before it "
            "moved)",
        ),
        (
            "set:\n  task.original.lift_profile: []\nsweep:\n  task.lift_profile: [[], [[0.5, 0.5]]]\n",
            "line 7: sweep.task.lift_profile: overlaps set.task.original.lift_profile (line 5): both set "
            "task.original.lift_profile, and only one of the values would reach each trial; allowed: "
            "task.original.lift_profile alone (sweep.task.lift_profile gives it by the name it had before "
            "it moved)",
        ),
        (
            "sweep:\n  task.restitution: [0.1]\n  task.original.restitution: [0.2]\n",
            "line 6: sweep.task.original.restitution: overlaps sweep.task.restitution (line 5): both set "
            "task.original.restitution",
        ),
        (
            "cells:\n  - {task.object_shape: box, task.original.object_shape: box}\n",
            "line 5: cells: column 'task.original.object_shape' overlaps cells column 'task.object_shape' "
            "(line 5): both set task.original.object_shape",
        ),
    ],
    ids=["params", "set-and-sweep", "sweep", "cells"],
)
def test_a_parameter_given_by_both_names_is_refused_naming_both(
    tmp_path: Path, body: str, problem: str
) -> None:
    (found,) = _problems(make_study(tmp_path, HEAD + body))
    assert found.startswith(problem)


def test_an_old_name_and_the_model_field_it_replaces_are_refused_naming_the_old_key(tmp_path: Path) -> None:
    tip = "model.assembly.manipulators[0].manipulator.tip_links[0].restitution"
    path = make_study(tmp_path, HEAD + f"set:\n  {tip}: 0.2\nsweep:\n  task.restitution: [null, 0.5]\n")
    (problem,) = _problems(path)
    assert problem.startswith(
        f"line 5: set.{tip}: sets {tip}, which task.original.restitution, given by "
        "sweep.task.restitution on line 7, replaces in the simulated model when it is not null"
    )


def test_the_new_nested_key_paths_work_in_sweep_set_and_cells(tmp_path: Path) -> None:
    path = make_study(
        tmp_path,
        HEAD + "set:\n  task.original.clamp_speed_cap: true\n"
        "sweep:\n  task.original.restitution: [0.0, 0.5]\n"
        "cells:\n  - {task.original.lift_profile: [], task.original.object_shape: box}\n"
        f"  - {{task.original.lift_profile: {PROFILE}, task.original.object_shape: original_hull}}\n",
    )
    jobs = build_jobs(load_study(path)).jobs
    seen = {(j.params.original.restitution, j.params.original.object_shape) for j in jobs}  # type: ignore[attr-defined]
    assert seen == {(r, s) for r in (0.0, 0.5) for s in ("box", "original_hull")}
    assert all(j.params.original.clamp_speed_cap for j in jobs)  # type: ignore[attr-defined]
    assert jobs[2].columns["task_original_lift_profile"] == PROFILE


def test_the_python_model_and_a_derived_study_refuse_an_old_name_saying_where_it_went(
    tmp_path: Path,
) -> None:
    with pytest.raises(ValueError, match=r"'restitution' is now 'original\.restitution'"):
        PinchGraspParams(restitution=0.5)  # type: ignore[call-arg]
    study = load_study(make_study(tmp_path, HEAD))
    with pytest.raises(DescriptionError) as info:
        derive_study(study, {"task.restitution": 0.5}, name="variant", output=tmp_path / "variant")
    assert [p.render() for p in info.value.problems] == [
        "set.task.restitution: is the name task.original.restitution had before it moved; allowed: "
        "task.original.restitution"
    ]


def test_run_dry_run_and_check_print_the_notice_once_on_stderr(tmp_path: Path) -> None:
    old = make_study(
        tmp_path, HEAD + "params: {restitution: 0.0}\nsweep:\n  task.distal_segment_ratio: [0.1]\n"
    )
    runner = CliRunner()
    for args in (["run", str(old), "--dry-run"], ["check", str(old)]):
        result = runner.invoke(app, args)
        assert result.exit_code == 0, result.output
        notes = [line for line in result.stderr.splitlines() if line.startswith("note: ")]
        assert notes == [
            f"note: {old}: old parameter names read at their new place: params.restitution (line 4) → "
            "task.original.restitution; write the new key paths to silence this note"
        ]
        assert "note:" not in result.stdout
    new = make_study(tmp_path, HEAD + "params: {original: {restitution: 0.0}}\n", "new.yaml")
    result = runner.invoke(app, ["run", str(new), "--dry-run"])
    assert result.exit_code == 0 and "note:" not in result.output
    assert "task_original_restitution" in result.stdout


def test_a_folder_written_before_the_move_reads_as_stored_and_show_says_so(tmp_path: Path) -> None:
    folder = tmp_path / "old_names"
    shutil.copytree(OLD_FOLDER, folder)
    runner = CliRunner()
    result = runner.invoke(app, ["show", str(folder)])
    assert result.exit_code == 0, result.output
    assert result.stderr.splitlines() == [
        f"note: {folder} was written before these parameters moved; its columns keep their old names: "
        "task_finger_spinning_friction_m is task.original.finger_spinning_friction_m, task_restitution is "
        "task.original.restitution, task_lift_profile is task.original.lift_profile, task_object_shape is "
        "task.original.object_shape, task_clamp_speed_cap is task.original.clamp_speed_cap"
    ]
    assert "by task.restitution: grasp" in result.stdout  # its manifest's axis, its own column
    for args in (["plot", str(folder)], ["classify", str(folder)], ["paper", "fig6", str(folder)]):
        result = runner.invoke(app, [*args])
        assert result.exit_code == 0, (args, result.output)
    labels = pd.read_csv(folder / "grasp_labels_contacts.csv")
    assert labels["grasp_contacts"].tolist() == ["pinch", "pinch"]  # as stored by the old code
    assert pd.read_parquet(next((folder / "trials").glob("*.parquet")))["label_grasp"].tolist() == [
        "pinch",
        "pinch",
    ]


def test_a_folder_written_with_the_new_names_has_no_note(tmp_path: Path) -> None:
    path = make_study(
        tmp_path,
        "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\nsimulation: {engine: mujoco}\n"
        "params: {early_stop: true, hold_s: 0.1}\nsweep:\n  task.original.restitution: [0.0]\n",
    )
    runner = CliRunner()
    assert runner.invoke(app, ["run", str(path), "--out", str(tmp_path / "new"), "--no-plots"]).exit_code == 0
    result = runner.invoke(app, ["show", str(tmp_path / "new")])
    assert result.exit_code == 0 and result.stderr == ""
    assert "by task.original.restitution: grasp" in result.stdout
