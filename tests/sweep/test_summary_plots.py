"""The summary plot and the label maps as a designer reads them: units (lengths in mm), the
rules' thresholds drawn, what each point averages over, float noise never a panel or an axis,
and cells without replicas or awaiting them drawn apart from robust ones."""

from __future__ import annotations

import itertools

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from somo_sweep.sweep.views.label_maps import AWAITING_HATCH, UNCHECKED_ALPHA, draw_label_panel
from somo_sweep.sweep.views.plots import summary_figure
from somo_sweep.sweep.views.results import Results

AXES = {
    "task.distal_segment_ratio": "task_distal_segment_ratio",
    "task.object_width_m": "task_object_width_m",
    "task.centering_position_m": "task_centering_position_m",
}
MANIFEST = {"study_name": "grip", "study": {"task": "pinch_grasp"}, "axes": AXES}


def _trials() -> pd.DataFrame:
    rows = []
    for i, (d, w, c) in enumerate(itertools.product([0.1, 0.3], [0.02, 0.08], [0.07, 0.1, 0.13])):
        rows.append(
            {
                "trial": i,
                "status": "ok",
                "task_distal_segment_ratio": d,
                "task_object_width_m": w,
                "task_centering_position_m": c,
                "hold_force_fraction_proximal": 0.1 + d + c,
                "hold_mean_contact_position": 0.5 + d,
                # d = 200 mm − c, and a 1e-10 arithmetic offset: the mean over c is one value
                "base_distance_m": 0.2 - c + 1e-10 * i,
                "label_grasp": "pinch" if d > 0.2 else "power",
            }
        )
    return pd.DataFrame(rows)


def _panels(fig: matplotlib.figure.Figure) -> dict[str, matplotlib.axes.Axes]:
    return {ax.get_ylabel().split("\n")[0].split(" (")[0]: ax for ax in fig.axes if ax.get_visible()}


def test_metric_panels_say_what_they_average_over_and_draw_the_rules_thresholds() -> None:
    fig = summary_figure(Results.of_table(_trials(), MANIFEST))
    panels = _panels(fig)
    share = panels["hold_force_fraction_proximal"]
    assert "share of the hold force" in share.get_ylabel()
    assert (
        " ".join(share.get_title().split())
        == "each point: the mean over centering_position (3 values); band: min to max"
    )
    lines = [line for line in share.get_lines() if line.get_linestyle() == "--"]
    assert [line.get_ydata()[0] for line in lines] == [0.25]
    assert "pinch below 0.25 (contacts rule)" in [t.get_text() for t in share.get_legend().get_texts()]
    assert "0 base, 1 tip" in panels["hold_mean_contact_position"].get_ylabel()
    plt.close(fig)


def test_lengths_are_in_mm_and_float_noise_is_no_panel() -> None:
    fig = summary_figure(Results.of_table(_trials(), MANIFEST))
    panels = _panels(fig)
    assert "base_distance_m" not in panels  # its means per DSR and width differ by 1e-10 only
    share = panels["hold_force_fraction_proximal"]
    legend = share.get_legend()
    assert legend.get_title().get_text() == "object_width (mm)"
    assert [t.get_text() for t in legend.get_texts()][:2] == ["20", "80"]
    plt.close(fig)


def test_an_axis_of_one_value_within_float_noise_is_not_an_axis() -> None:
    trials = _trials()
    trials = trials[trials["task_distal_segment_ratio"] == 0.1].copy()
    trials["task_distal_segment_ratio"] += np.arange(len(trials)) * 1e-12
    fig = summary_figure(Results.of_table(trials, MANIFEST))
    assert fig.axes[0].get_xlabel() == "object_width (mm)"  # DSR is one value: not the x axis
    plt.close(fig)


def test_cells_without_replicas_and_awaiting_them_are_not_drawn_as_robust_ones() -> None:
    cells = pd.DataFrame(
        {
            "x": [1, 2, 3],
            "status": "ok",
            "label": ["pinch", "pinch", "power"],
            "replicas": [2, 0, 0],
            "replicas_awaited": [0, 0, 2],
            "robust": pd.array([True, pd.NA, pd.NA], dtype="boolean"),
        }
    )
    fig, ax = plt.subplots()
    draw_label_panel(ax, cells, "label", "x", None, {"pinch": "C0", "power": "C1"})
    robust, bare, waiting = ax.patches
    assert robust.get_alpha() in (None, 1.0) and robust.get_hatch() is None
    assert bare.get_alpha() == UNCHECKED_ALPHA and bare.get_hatch() is None
    assert waiting.get_hatch() == AWAITING_HATCH
    plt.close(fig)
