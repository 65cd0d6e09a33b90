"""``somo-sweep show`` of a grasp study fits an 80-column terminal without cutting a header."""

from __future__ import annotations

import io

import pandas as pd
import pytest
from rich.console import Console

from somo_sweep.cli.summary import print_results
from somo_sweep.sweep.views.results import Results


def test_a_two_rule_grasp_study_is_shown_in_80_columns_with_every_header_whole() -> None:
    n = 12
    df = pd.DataFrame(
        {
            "trial": range(n),
            "status": ["ok"] * n,
            "replica": 0,
            "wall_time_s": 1.0,
            "message": "",
            "task_distal_segment_ratio": [0.1, 0.2, 0.3] * 4,
            "task_object_width_m": [0.02] * 6 + [0.08] * 6,
            "label_grasp": ["pinch", "power", "no_grasp"] * 4,
            "label_grasp_paper": ["power", "pinch", "no_grasp"] * 4,
        }
    )
    manifest = {
        "study_name": "grasp",
        "study_hash": "0" * 16,
        "n_trials": n,
        "runs": [],
        "axes": {
            "task.distal_segment_ratio": "task_distal_segment_ratio",
            "task.object_width_m": "task_object_width_m",
        },
    }
    out = io.StringIO()
    print_results(Console(file=out, width=80), Results.of_table(df, manifest))
    text = out.getvalue()
    assert max(len(line) for line in text.splitlines()) <= 80
    assert "…" not in text
    assert "by task.distal_segment_ratio: grasp_paper" in text
    assert "no_grasp" in text and "distal_segment_ratio" in text


def test_a_long_star_key_path_is_named_once_whole_and_no_title_wraps() -> None:
    """A ``[*]`` stiffness axis's title "by model.assembly.manipulators[*]…" wrapped over 3 lines."""
    key = "model.assembly.manipulators[*].manipulator.actuators[0].joints[0].stiffness_n_m_per_rad"
    column = "model_assembly_manipulators_all_manipulator_actuators_0_joints_0_stiffness_n_m_per_rad"
    df = pd.DataFrame(
        {
            "trial": range(4),
            "status": "ok",
            "replica": 0,
            "wall_time_s": 1.0,
            "message": "",
            column: [0.4, 0.4, 0.6, 0.6],
            "label_grasp": ["pinch", "power"] * 2,
        }
    )
    manifest = {"study_name": "g", "study_hash": "0" * 16, "n_trials": 4, "runs": [], "axes": {key: column}}
    out = io.StringIO()
    print_results(Console(file=out, width=80), Results.of_table(df, manifest))
    lines = out.getvalue().splitlines()
    assert f"stiffness_n_m_per_rad: the axis {key}" in lines  # once, whole, on one line
    assert any(line.strip() == "by stiffness_n_m_per_rad: grasp" for line in lines)
    assert max(len(line) for line in lines if key not in line) <= 80


def test_the_command_lines_consoles_take_the_width_of_now(monkeypatch: pytest.MonkeyPatch) -> None:
    """The consoles are made when used: one made at import kept the COLUMNS of that moment (80 when
    another test had set it), and ``show`` wrapped at 80 a table asked for at 300."""
    from somo_sweep.cli import results, sweep

    for columns in ("300", "77"):
        monkeypatch.setenv("COLUMNS", columns)
        assert results._out().width == sweep._out().width == sweep._err().width == int(columns)
