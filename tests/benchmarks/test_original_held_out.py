"""The held-out sample of the original-code check: a fixed draw that never touches a tuned cell,
and a report that counts the original's robust cells and ours' agreement on them."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from benchmarks.original_fig6 import held_out

TUNED = Path(held_out.REPO, "results/reference/original_cells.csv")


def test_the_draw_is_fixed_off_the_tuned_cells_and_split_in_two_halves() -> None:
    tuned = held_out.tuned_cells(TUNED)
    rows = held_out.draw(tuned)
    assert rows == held_out.draw(tuned)  # seeded
    cells = [c for c, _, _ in rows]
    assert len(cells) == len(set(cells)) == held_out.SAMPLE_CELLS
    assert not set(cells) & tuned and len(tuned) == 78
    grid = {
        (d, w, float(c))
        for d in held_out.DSR_VALUES
        for w in held_out.WIDTHS_MM
        for c in held_out.CENTERINGS_MM
    }
    assert set(cells) <= grid
    for half in ("tuning", "check"):
        orders = [n for _, h, n in rows if h == half]
        assert orders == list(range(held_out.SAMPLE_CELLS // 2))
    # the first cell of the check half's run order, as run
    assert rows[held_out.SAMPLE_CELLS // 2][:2] == ((0.15, 20, 110.0), "check")


def _write(path: Path, rows: list[dict[str, object]]) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return path


def test_the_report_counts_only_cells_whose_original_label_survives_the_move(tmp_path: Path) -> None:
    sample = [((0.2, 40, 100.0), "check", 0), ((0.3, 60, 120.0), "check", 1), ((0.4, 80, 90.0), "check", 2)]
    labels = {  # c, c - 0.1, c + 0.1 mm
        (0.2, 40): ["pinch", "pinch", "pinch"],  # robust; ours agrees
        (0.3, 60): ["power", "power", "power"],  # robust; ours drops it
        (0.4, 80): ["pinch", "no_grasp", "pinch"],  # not robust
    }
    original, ours = [], []
    for (d, w, c), _, _ in sample:
        for (_, _, cc), label in zip(held_out.shifted((d, w, c)), labels[(d, w)], strict=True):
            original.append({"dsr": d, "width_mm": w, "c_mm": cc, "orig_label": label, "orig_z_m": 0.1})
        mine = "no_grasp" if (d, w) == (0.3, 60) else labels[(d, w)][0]
        ours.append(
            {"dsr": d, "width_mm": w, "c_mm": c, "ours_label": mine, "ours_status": "ok", "ours_z_m": 0.1}
        )
    lines = held_out.report(
        sample,
        held_out._rows([_write(tmp_path / "o.csv", original)]),
        held_out._rows([_write(tmp_path / "u.csv", ours)]),
    )
    check = next(line for line in lines if line.startswith("check:"))
    assert "3 of 3 cells run" in check and "ours = original on 2 of 3" in check
    assert "the original robust on 2, ours = original there on 1 (50.0 %)" in check
    assert any("DSR 0.30 width 60 mm c 120 mm: original power" in line for line in lines)
    assert lines[0].startswith("tuning: 0 of 0 cells run")


@pytest.mark.parametrize("half", ["tuning", "check"])
def test_cells_prints_each_cell_at_c_and_a_tenth_of_a_millimetre_either_side(
    tmp_path: Path, half: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sample.csv"
    held_out.main(["draw", "--out", str(out)])
    capsys.readouterr()
    held_out.main(["cells", str(out), "--half", half])
    printed = capsys.readouterr().out.split()
    assert len(printed) == 2 * 3 * held_out.SAMPLE_CELLS // 2 and printed[0] == "--cell"


def test_stability_counts_the_originals_robust_labels_it_keeps_under_a_change(tmp_path: Path) -> None:
    sample = [
        ((0.2, 40, 100.0), "tuning", 0),
        ((0.3, 60, 120.0), "tuning", 1),
        ((0.4, 80, 90.0), "tuning", 2),
    ]
    labels = {(0.2, 40): ["pinch"] * 3, (0.3, 60): ["power"] * 3, (0.4, 80): ["pinch", "pinch", "no_grasp"]}
    changed_label = {(0.2, 40): "pinch", (0.3, 60): "no_grasp", (0.4, 80): "pinch"}
    original, changed = [], []
    for (d, w, c), _, _ in sample:
        for (_, _, cc), label in zip(held_out.shifted((d, w, c)), labels[(d, w)], strict=True):
            original.append({"dsr": d, "width_mm": w, "c_mm": cc, "orig_label": label})
        changed.append({"dsr": d, "width_mm": w, "c_mm": c, "orig_label": changed_label[(d, w)]})
    lines = held_out.stability(
        sample,
        held_out._rows([_write(tmp_path / "o.csv", original)]),
        held_out._rows([_write(tmp_path / "c.csv", changed)]),
    )
    assert (
        lines[0]
        == "tuning: the original under the change keeps its label on 1 of the 2 robust cells run (50.0 %)"
    )
    assert lines[1].strip() == "DSR 0.30 width 60 mm c 120 mm: power -> no_grasp"
    assert lines[2].startswith("check: the original under the change keeps its label on 0 of the 0")


STORED = Path(held_out.REPO, "results/reference/original_held_out")


def test_the_stored_sample_is_the_draw() -> None:
    assert held_out.read_sample(STORED / "sample.csv") == held_out.draw(held_out.tuned_cells(TUNED))


# (step, half): (the original's robust cells, ours = the original there, share), as the docs quote them
QUOTED = {
    ("0p5ms", "tuning"): (33, 27, "81.8 %"),
    ("0p5ms", "check"): (30, 25, "83.3 %"),
    ("0p25ms", "tuning"): (39, 34, "87.2 %"),
    ("0p25ms", "check"): (35, 31, "88.6 %"),
}


@pytest.mark.parametrize("step", sorted({step for step, _ in QUOTED}))
def test_the_stored_runs_give_the_agreements_the_docs_quote(step: str) -> None:
    lines = held_out.report(
        held_out.read_sample(STORED / "sample.csv"),
        held_out._rows([STORED / f"original_{step}.csv"]),
        held_out._rows([STORED / f"ours_{step}.csv"]),
    )
    docs = Path(held_out.REPO, "docs/paper_figures.md").read_text()
    for half in ("tuning", "check"):
        robust, same, share = QUOTED[(step, half)]
        line = next(line for line in lines if line.startswith(f"{half}:"))
        assert f"the original robust on {robust}, ours = original there on {same} ({share})" in line
        assert f"{same} of {robust} ({share})" in docs
