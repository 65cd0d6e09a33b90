"""Answers from a map: per value of the other axes, the smallest (largest) value of one axis with
a robust label at every object; and the ``somo-sweep answer`` command's errors."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest
from test_robustness import sign_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.sweep.run.replica_state import ReplicaState
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.answers import Question, answer
from somo_sweep.sweep.views.axes import axis_text


def cells(grid: dict[tuple[float, float], list[str]], **columns: list[object]) -> pd.DataFrame:
    """{(stiffness, dsr): labels over widths 20, 40 mm} as one row per cell."""
    rows = [
        {"stiffness": k, "dsr": d, "width_m": 0.02 * (i + 1), "label": lab}
        for (k, d), labs in grid.items()
        for i, lab in enumerate(labs)
    ]
    table = pd.DataFrame(rows)
    for name, values in columns.items():
        table[name] = values
    return table


QUESTION = Question("dsr", "label", "pinch", every=("width_m",), per=("stiffness",))


def test_each_value_of_the_other_axis_gets_its_smallest_value_with_the_label_at_every_object() -> None:
    table = cells(
        {
            (0.4, 0.1): ["pinch", "power"],
            (0.4, 0.3): ["pinch", "pinch"],
            (0.8, 0.1): ["pinch", "pinch"],
            (0.8, 0.3): ["power", "pinch"],
        }
    )
    result = answer(table, QUESTION)
    assert result.table["stiffness"].tolist() == [0.4, 0.8]
    assert result.table["answer"].tolist() == [0.3, 0.1]
    assert result.table["checked"].tolist() == [False, False] and result.table["complete"].all()
    largest = answer(table, Question("dsr", "label", "pinch", ("width_m",), (), ("stiffness",), True))
    assert largest.table["answer"].tolist() == [0.3, 0.1]
    assert result.lines()[1:] == ["stiffness 0.4: 0.3", "stiffness 0.8: 0.1"]


def test_only_robust_cells_count_and_a_cell_awaiting_replicas_makes_the_answer_provisional() -> None:
    table = cells(
        {(1.0, 0.1): ["pinch", "pinch"], (1.0, 0.3): ["pinch", "pinch"]},
        replicas=[2, 0, 2, 2],
        replicas_awaited=[0, 2, 0, 0],
        robust=pd.array([True, pd.NA, True, True], dtype="boolean"),
        label_agreement=[1.0, 1.0, 1.0, 1.0],
    )
    state = ReplicaState(replicas=2, chosen=frozenset({1}), settled=False)
    row = answer(table, QUESTION, state).table.iloc[0]
    assert row["answer"] == 0.3 and row["answer_if_awaited_hold"] == 0.1 and row["answer_every_cell"] == 0.1
    assert not row["complete"] and row["awaiting"] == 1 and row["not_robust"] == 0
    text = answer(table, QUESTION, state).lines()[1]
    assert (
        text == "stiffness 1: 0.3 (0.1 counting every cell); "
        "provisional: 1 cell(s) await replicas (0.1 if they hold)"
    )


def test_an_unreplicated_cell_counts_only_inside_a_region_along_every_axis_the_other_axis_too() -> None:
    # The (0.4, 0.1, 20 mm) cell has no replicas; its neighbour along stiffness is power.
    table = cells(
        {(0.4, 0.1): ["pinch", "pinch"], (0.8, 0.1): ["power", "pinch"]},
        replicas=[0, 2, 2, 2],
        robust=pd.array([pd.NA, True, True, True], dtype="boolean"),
    )
    assert math.isnan(answer(table, QUESTION).table["answer"].iloc[0])


def test_some_axes_need_the_label_at_one_of_their_values_only() -> None:
    table = cells({(1.0, 0.1): ["pinch", "power"], (1.0, 0.2): ["power", "pinch"]}, place=[0, 0, 1, 1])
    table["dsr"] = 0.1  # one DSR, two places: width 20 mm pinched at place 0, 40 mm at place 1
    asked = Question("dsr", "label", "pinch", ("width_m",), ("place",), ("stiffness",))
    assert answer(table, asked).table["answer"].tolist() == [0.1]
    every = Question("dsr", "label", "pinch", ("width_m", "place"), (), ("stiffness",))
    assert math.isnan(answer(table, every).table["answer"].iloc[0])


def test_values_equal_within_float_noise_are_one_value() -> None:
    table = cells({(0.4, 0.1): ["pinch", "pinch"], (0.4 + 1e-12, 0.3): ["pinch", "pinch"]})
    assert answer(table, QUESTION).table["stiffness"].tolist() == [0.4]


def test_a_question_the_table_cannot_answer_is_refused_by_name() -> None:
    table = cells({(0.4, 0.1): ["pinch", "pinch"]}, name=["a", "b"])
    with pytest.raises(SomoError, match="named twice"):
        answer(table, Question("dsr", "label", "pinch", ("dsr",)))
    with pytest.raises(SomoError, match="no column nope in the cells"):
        answer(table, Question("nope", "label", "pinch", ("width_m",)))
    with pytest.raises(SomoError, match="name is not numeric"):
        answer(table, Question("name", "label", "pinch", ("width_m",)))
    with pytest.raises(SomoError, match="at least one object axis"):
        answer(table, Question("dsr", "label", "pinch", ()))


def test_axis_values_read_with_their_units() -> None:
    assert axis_text("task_pressure_kpa", 40.0) == "pressure 40 kPa"
    assert axis_text("task_object_width_m", 0.02) == "object_width 20 mm"
    assert axis_text("model_manipulators_0_actuators_0_stiffness_n_m_per_rad", 0.4) == "stiffness 0.4 N·m/rad"


def _answer(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["answer", *args])
    return result.exit_code, " ".join(result.output.split())


def test_the_answer_command_names_what_is_wrong(tmp_path: Path) -> None:
    path = sign_study(tmp_path, "  task.u: [0.0, 1.0]", xs="[-1, 1]")
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    out = str(tmp_path / "out")
    code, text = _answer(out, "--smallest", "nope", "--every", "x")
    assert code == 2 and "--smallest nope: not a swept axis of these results; allowed: task.x, task.u" in text
    code, text = _answer(out, "--smallest", "x", "--largest", "x", "--every", "x")
    assert code == 2 and "give one of --smallest AXIS or --largest AXIS" in text
    code, text = _answer(out, "--smallest", "x")
    assert code == 2 and "give the object axes with --every" in text
    code, text = _answer(out, "--smallest", "x", "--every", "x")
    assert code == 2 and "axis task_x is named twice" in text
    code, text = _answer(out, "--smallest", "task.x", "--every", "u", "--label", "sgn=positive")
    assert code == 2 and "no label 'sgn' (did you mean 'sign'?)" in text
    code, text = _answer(out, "--smallest", "task.x", "--every", "u", "--label", "sign=positive")
    assert code == 0 and text.endswith("positive at every u, unchecked: no robustness replicas ran answer: 1")
    code, text = _answer(str(tmp_path / "nowhere"), "--smallest", "x", "--every", "x")
    assert code == 2 and "not a somo-sweep results folder" in text
