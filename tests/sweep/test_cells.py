"""Any list of cells: linked axes with repeated values, and a study's ``cells:`` table (inline or CSV).

The trials are selftest trials (milliseconds each); a cells table must give exactly the
trials (ids, seeds, order) of the linked axes it spells, so results and resume do not depend
on how the cells were written down.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from test_sweep import make_study

from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.run.sampling import describe
from somo_sweep.sweep.store.result_store import read_results
from somo_sweep.sweep.study import load_study

HEAD = "task: selftest_sleep\nmodel: models/ihm_finger.yaml\n"


def _problems(path: Path) -> list[str]:
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    return [p.render() for p in info.value.problems]


def test_linked_axes_may_repeat_values_when_their_combinations_differ(tmp_path: Path) -> None:
    path = make_study(
        tmp_path,
        HEAD
        + "sweep:\n  task.x: [0.16, 0.16, 0.20]\n  task.u: [0.02, 0.04, 0.02]\nlink:\n  - [task.x, task.u]\n",
    )
    frame = build_jobs(load_study(path)).frame()
    assert list(zip(frame["task_x"], frame["task_u"], strict=True)) == [
        (0.16, 0.02),
        (0.16, 0.04),
        (0.2, 0.02),
    ]
    assert frame["job_id"].is_unique


def test_a_repeated_combination_of_linked_values_is_refused_naming_both_entries(tmp_path: Path) -> None:
    path = make_study(
        tmp_path,
        HEAD + "sweep:\n  task.x: [0.16, 0.20, 0.16]\n  task.u: [2, 4, 2.0]\nlink:\n  - [task.x, task.u]\n",
    )
    assert _problems(path) == [
        "line 7: link[0]: entries 0 and 2 of its axes give the same values (task.x=0.16, task.u=2.0): "
        "the same trial twice; allowed: distinct combinations (a value may repeat in one axis)"
    ]


def test_an_axis_of_its_own_still_refuses_a_repeated_value(tmp_path: Path) -> None:
    path = make_study(tmp_path, HEAD + "sweep:\n  task.x: [1, 2, 1]\n  task.u: [1, 2, 3]\n")
    assert _problems(path) == [
        "line 4: sweep.task.x: value 1 is given twice (entries 0 and 2); allowed: distinct values"
    ]


CELLS = [(0.16, 0.02), (0.16, 0.04), (0.20, 0.02)]


def test_a_cells_table_gives_the_trials_of_the_linked_axes_it_spells(tmp_path: Path) -> None:
    xs, us = ", ".join(str(c[0]) for c in CELLS), ", ".join(str(c[1]) for c in CELLS)
    linked = make_study(
        tmp_path,
        HEAD + f"sweep:\n  task.x: [{xs}]\n  task.u: [{us}]\nlink:\n  - [task.x, task.u]\n",
        "l.yaml",
    )
    rows = "".join(f"  - {{task.x: {x}, task.u: {u}}}\n" for x, u in CELLS)
    inline = make_study(tmp_path, HEAD + "cells:\n" + rows, "inline.yaml")
    (tmp_path / "cells.csv").write_text(
        "# cells measured on the bench\ntask.x;task.u\n" + "".join(f"{x};{u}\n\n" for x, u in CELLS)
    )
    from_csv = make_study(tmp_path, HEAD + "cells: cells.csv\n", "csv.yaml")
    tables = [build_jobs(load_study(p)) for p in (linked, inline, from_csv)]
    assert len({t.study_hash for t in tables}) == 1
    assert [j.seed for j in tables[0].jobs] == [j.seed for j in tables[2].jobs]
    assert tables[1].resolved["cells"]["rows"] == 3 and tables[2].resolved["cells"]["file"] == "cells.csv"
    assert "cells" not in tables[0].resolved and tables[1].resolved["sweep"] == {}


def test_cells_cross_the_sweep_axes_and_resume_skips_every_finished_row(tmp_path: Path) -> None:
    rows = "".join(f"  - {{task.x: {x}, task.u: {u}}}\n" for x, u in CELLS)
    path = make_study(tmp_path, HEAD + "cells:\n" + rows + "sweep:\n  task.v: [1, 2]\n")
    study = load_study(path, tmp_path / "out")
    assert (study.n_points, study.n_trials) == (6, 6)
    first = run_sweep(study, RunOptions(n_jobs=1))
    assert first.by_status == {"ok": 6}
    df = read_results(tmp_path / "out")
    assert list(zip(df["task_x"], df["task_u"], df["task_v"], strict=True))[:3] == [
        (0.16, 0.02, 1.0),
        (0.16, 0.02, 2.0),
        (0.16, 0.04, 1.0),
    ]
    again = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert (again.skipped, again.run) == (6, 0)


def test_a_cells_csv_names_the_line_and_column_of_every_bad_field(tmp_path: Path) -> None:
    (tmp_path / "cells.csv").write_text("task.x,task.u\n0.1,0.2\n0.1,nan\n0.3,\n0.4,0.5,0.6\n")
    path = make_study(tmp_path, HEAD + "cells: cells.csv\n")
    assert _problems(path) == [
        "line 3: cells: cells.csv line 3: column 'task.u' must be a finite number, got nan",
        "line 3: cells: cells.csv line 4: column 'task.u' is empty; allowed: a value in every column",
        "line 3: cells: cells.csv line 5: 3 fields, the header (line 1) 2",
    ]


def test_a_cells_csv_refuses_a_repeated_row_an_unknown_key_and_a_bad_value_at_once(tmp_path: Path) -> None:
    (tmp_path / "cells.csv").write_text("task.x,task.uu\n1,2\n1.0,2\nabc,3\n")
    path = make_study(tmp_path, HEAD + "cells: cells.csv\n")
    found = _problems(path)
    assert found[0] == (
        "line 3: cells: cells.csv line 3: repeats cells.csv line 2 (task.x=1.0, task.uu=2): the same trial "
        "twice; allowed: distinct rows (repeats: runs every row more than once, each with its own seed)"
    )
    assert found[1].startswith(
        "line 3: cells: cells.csv line 2, column 'task.uu': unknown key 'uu' (did you mean 'u'?)"
    )
    assert found[2].startswith(
        "line 3: cells: cells.csv line 4, column 'task.x': expected a number, not text, got 'abc'"
    )


def test_inline_cells_name_the_row_and_key_and_suggest_the_key_path(tmp_path: Path) -> None:
    path = make_study(
        tmp_path,
        HEAD + "cells:\n  - {x: 1, task.u: 2}\n  - {task.u: 3}\n",
    )
    assert _problems(path) == [
        "line 4: cells[0].x: key path 'x' must start with 'model.' or 'task.' (did you mean 'task.x'?)",
        "line 5: cells[1]: misses 'x'; every row gives the keys of the first: x, task.u",
    ]
    bad = make_study(tmp_path, HEAD + "cells:\n  - {task.x: 1}\n  - {task.x: two}\n", "bad.yaml")
    assert _problems(bad) == ["line 5: cells[1].task.x: expected a number, not text, got 'two'"]


@pytest.mark.parametrize(
    ("cells", "message"),
    [
        ("missing.csv", "cells: missing.csv: file not found"),
        ("[]", "cells: needs at least one row, got []"),
        ("{task.x: 1}", "cells: cells is a list of rows (mappings of key path to value) or a CSV file name"),
        ("[1, 2]", "cells[0]: a row is a mapping of key path to value, got 1"),
    ],
)
def test_a_cells_value_that_is_no_table_is_refused(tmp_path: Path, cells: str, message: str) -> None:
    path = make_study(tmp_path, HEAD + f"cells: {cells}\n")
    assert message in "\n".join(_problems(path))


def test_a_key_given_in_cells_and_swept_is_refused(tmp_path: Path) -> None:
    path = make_study(tmp_path, HEAD + "cells:\n  - {task.x: 1}\n  - {task.x: 2}\nsweep:\n  task.x: [3, 4]\n")
    assert _problems(path) == [
        "line 7: sweep.task.x: overlaps cells column 'task.x' (line 4): both set task.x, and only one of "
        "the values would reach each trial; allowed: each field in one place: params, set, sweep or cells"
    ]


def test_adaptive_sampling_runs_every_row_and_refines_only_the_sweep_axes(tmp_path: Path) -> None:
    rows = "  - {task.u: 0.5}\n  - {task.u: -0.5}\n"
    only = make_study(tmp_path, HEAD + "cells:\n" + rows + "sampling: adaptive\n", "only.yaml")
    with pytest.raises(DescriptionError, match="adaptive sampling refines numeric sweep: axes"):
        run_sweep(load_study(only, tmp_path / "never"), RunOptions(n_jobs=1))
    assert not (tmp_path / "never").exists()
    crossed = make_study(
        tmp_path,
        HEAD + "cells:\n" + rows + "sweep:\n  task.x: {start: 1, stop: 9, step: 1}\nsampling: adaptive\n",
        "crossed.yaml",
    )
    study = load_study(crossed, tmp_path / "out")
    text = describe(study)
    assert "cells (task.u): 2 rows, every row (not refined)" in text
    assert "task.x: 9 values, refined, coarse: every 4th value and the last" in text
    summary = run_sweep(study, RunOptions(n_jobs=1))
    assert summary.run == 6 and summary.inferred == 12  # x = 1, 5, 9 in each row; the rest agree


def test_a_list_of_cells_gets_robustness_replicas_too(tmp_path: Path) -> None:
    # A cells: table is one dimension of the study (its rows in order), not a grid to refine.
    rows = "".join(f"  - {{task.x: {x}}}\n" for x in (-2, 0.5, 3))
    body = HEAD + "params: {jitter: 0.1}\ncells:\n" + rows + "robustness: {replicas: 2, where: all}\n"
    study = load_study(make_study(tmp_path, body + "simulation: {time_step_s: 1.0e-3}\n"), tmp_path / "out")
    summary = run_sweep(study, RunOptions(n_jobs=1))
    assert (summary.run, summary.replicas_run) == (3, 6)
    assert sorted(read_results(tmp_path / "out")["replica"]) == [0, 0, 0, 1, 1, 1, 2, 2, 2]


def _refused(path: Path) -> str:
    with pytest.raises(DescriptionError) as info:
        load_study(path, path.parent / "out")
    return str(info.value)


def test_a_broken_model_file_of_a_row_is_blamed_on_that_row(tmp_path: Path) -> None:
    """It was reported as ``sweep.model``, with no row named."""
    body = (
        "name: b\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\ncells:\n"
        "  - {task.x: 1, model: models/ihm_finger.yaml}\n  - {task.x: 2, model: models/bad.yaml}\n"
        "  - {task.x: 3, model: models/bad.yaml}\n"
    )
    path = make_study(tmp_path, body)
    good = (tmp_path / "models" / "ihm_finger.yaml").read_text()
    (tmp_path / "models" / "bad.yaml").write_text(good.replace("length_m: 0.", "length_m: -0.", 1))
    text = _refused(path)
    assert "line 6: cells[1].model: " in text and "bad.yaml: line 10: manipulator" in text
    assert "sweep.model" not in text and "cells[2]" not in text  # blamed once, on its first row


def test_an_unknown_key_in_an_inline_row_does_not_hide_the_rows_other_problems(tmp_path: Path) -> None:
    body = (
        "name: e\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\ncells:\n"
        "  - {task.x: 1, bogus: 3, task.sleep_s: -5}\n  - {task.x: 2, bogus: 3, task.sleep_s: 0}\n"
    )
    text = _refused(make_study(tmp_path, body))
    assert "line 5: cells[0].bogus: key path 'bogus' must start with 'model.' or 'task.'" in text
    assert "line 5: cells[0].task.sleep_s: Input should be greater than or equal to 0, got -5" in text
