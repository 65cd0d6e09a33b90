"""Label maps over whatever a study swept, and the summary's choice of metric panels."""

from __future__ import annotations

import itertools

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pandas as pd
import pytest

from somo_sweep.sweep.views.label_maps import (
    INFERRED_HATCH,
    MAX_PANELS,
    NOT_ROBUST_HATCH,
    label_map_figure,
    label_maps,
    map_axes,
)
from somo_sweep.sweep.views.plots import summary_metrics
from somo_sweep.sweep.views.results import Results


def _cells(shape: dict[str, list[float]], robust: bool | None = True) -> pd.DataFrame:
    rows = [dict(zip(shape, values, strict=True)) for values in itertools.product(*shape.values())]
    cells = pd.DataFrame(rows)
    cells["status"] = "ok"
    cells["label_grasp"] = np.where(
        cells[next(iter(shape))] > np.median(cells[next(iter(shape))]), "pinch", "power"
    )
    cells["robust"] = pd.array([robust] * len(cells), dtype="boolean")
    return cells


def test_the_axis_with_most_values_runs_along_x_the_next_along_y_and_the_rest_make_panels() -> None:
    cells = _cells({"a": [1, 2], "b": [1, 2, 3, 4, 5], "c": [1, 2, 3]})
    assert map_axes(cells, ["a", "b", "c"]) == ("b", "c", ["a"])
    assert map_axes(cells[cells["a"] == 1], ["b"]) == ("b", None, [])
    with pytest.raises(ValueError, match="at least one"):
        map_axes(cells, ["nope"])


def _hatched(fig: matplotlib.figure.Figure) -> int:
    return sum(p.get_hatch() == NOT_ROBUST_HATCH for ax in fig.axes for p in ax.patches)


def test_a_cell_whose_replicas_disagree_is_hatched_and_counted_in_the_legend() -> None:
    cells = _cells({"task_x_m": [0.07, 0.1, 0.13], "task_w_m": [0.02, 0.08]})
    cells.loc[2, "robust"] = False
    fig = label_map_figure(cells, "label_grasp", ["task_x_m", "task_w_m"], {}, "study")
    assert _hatched(fig) == 1
    assert sum(len(ax.patches) for ax in fig.axes) == len(cells)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "not robust (1: replicas disagree; majority drawn)" in legend
    assert {"pinch", "power"} <= set(legend)


def test_a_cell_an_adaptive_run_inferred_is_grey_hatched() -> None:
    cells = _cells({"task_x_m": [0.07, 0.1, 0.13], "task_w_m": [0.02, 0.08]})
    cells["inferred"] = np.array([True, False, False, False, False, True])  # numpy booleans
    fig = label_map_figure(cells, "label_grasp", ["task_x_m", "task_w_m"], {}, "study")
    assert sum(p.get_hatch() == INFERRED_HATCH for ax in fig.axes for p in ax.patches) == 2
    assert "inferred (2: not simulated)" in [t.get_text() for t in fig.legends[0].get_texts()]


def test_panels_beyond_the_limit_are_left_out_and_the_title_says_how_many() -> None:
    few = _cells({"x": list(range(10)), "y": list(range(8)), "p": [0, 1]})
    fig = label_map_figure(few, "label_grasp", ["x", "y", "p"], {}, "s")
    assert len([ax for ax in fig.axes if ax.patches]) == 2
    assert "left out" not in fig._suptitle.get_text()  # type: ignore[union-attr]
    many = _cells({"x": list(range(10)), "y": list(range(8)), "p": list(range(5)), "q": list(range(6))})
    fig = label_map_figure(many, "label_grasp", ["x", "y", "p", "q"], {}, "s")
    assert len([ax for ax in fig.axes if ax.patches]) == MAX_PANELS
    assert f"{5 * 6 - MAX_PANELS} more panels left out" in fig._suptitle.get_text()  # type: ignore[union-attr]


def test_every_label_column_gets_a_map_and_a_study_without_axes_none() -> None:
    cells = _cells({"task_c_m": [0.07, 0.1], "task_dsr": [0.1, 0.3]})
    cells["trial"] = range(len(cells))
    cells["label_grasp_paper"] = "pinch"
    manifest = {"study_name": "s", "axes": {"task.c_m": "task_c_m", "task.dsr": "task_dsr"}}
    assert [name for name, _ in label_maps(Results.of_table(cells, manifest))] == [
        "label_map_grasp",
        "label_map_grasp_paper",
    ]
    assert label_maps(Results.of_table(cells, {"study_name": "s", "axes": {}})) == []
    cells["label_dt"] = [f"{v:g}" for v in range(len(cells))]  # a label of its own per cell: drawn
    assert "label_map_dt" in [name for name, _ in label_maps(Results.of_table(cells, manifest))]
    many = pd.concat([cells] * 4, ignore_index=True)
    many["trial"] = range(len(many))
    many["label_dt"] = [f"{v:g}" for v in range(len(many))]  # 16 values: no map
    assert "label_map_dt" not in [name for name, _ in label_maps(Results.of_table(many, manifest))]


def test_the_summary_draws_the_tasks_metrics_first_and_none_without_a_spread() -> None:
    n = 6
    df = pd.DataFrame(
        {
            "status": ["ok"] * n,
            "base_distance_m": 0.085 + np.arange(n) * 1e-10,  # rounding noise: one value
            "ended_early_s": [np.nan] * n,  # never set
            "final_contact_count_link01": [0] * n,  # all zero
            "lift_slip_m": np.linspace(0, 1e-3, n),
            "hold_normal_force_n_left": np.linspace(1, 3, n),
            "held": [True, False] * (n // 2),
        }
    )
    chosen = summary_metrics(df, ("held", "hold_normal_force_n_left", "not_a_column"))
    assert chosen == ["held", "hold_normal_force_n_left", "lift_slip_m"]
