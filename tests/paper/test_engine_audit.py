"""The Fig. 6 engine audit: agreement counted on cells robust on both engines, each disagreement
with what decides it."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import SomoError
from somo_sweep.paper.engine_audit import engine_audit


def _run(cells: list[tuple[float, float, float, list[str], float]]) -> pd.DataFrame:
    """A results table: per cell (DSR, width, c, labels of its own trial then replicas, proximal share)."""
    rows = []
    for trial, (dsr, width, c, labels, proximal) in enumerate(cells):
        for replica, label in enumerate(labels):
            rows.append(
                {
                    "job_id": f"job{trial}-{replica}",
                    "study_hash": "h",
                    "trial": trial,
                    "replica": replica,
                    "status": "ok",
                    "task_distal_segment_ratio": dsr,
                    "task_object_width_m": width,
                    "task_centering_position_m": c,
                    "label_grasp": label,
                    "label_grasp_paper": label,
                    "lift_height_m": 0.07 if label != "no_grasp" else 0.0,
                    "hold_ground_contact_fraction": 0.0 if label != "no_grasp" else 1.0,
                    "hold_contact_fraction_both_fingers": 1.0,
                    "hold_force_fraction_proximal": proximal,
                    "object_z_m": 0.1 if label != "no_grasp" else 0.03,
                    "final_mean_link_paper": 17.0,
                }
            )
    return pd.DataFrame(rows)


def test_agreement_is_counted_on_cells_robust_on_both_engines() -> None:
    pybullet = _run(
        [
            (0.2, 0.04, 0.1, ["pinch"] * 3, 0.1),  # robust on both, agree
            (0.2, 0.04, 0.105, ["power"] * 3, 0.4),  # robust on both, disagree
            (0.3, 0.04, 0.1, ["pinch", "power", "pinch"], 0.2),  # not robust on PyBullet: left out
            (0.3, 0.06, 0.1, ["no_grasp"] * 3, float("nan")),  # only on PyBullet: left out
        ]
    )
    mujoco = _run(
        [
            (0.2, 0.04, 0.1, ["pinch"] * 3, 0.05),
            (0.2, 0.04, 0.105, ["pinch"] * 3, 0.12),
            (0.3, 0.04, 0.1, ["power"] * 3, 0.5),
        ]
    )
    info = engine_audit(pybullet, mujoco, "contacts")
    assert (info["cells"], info["robust_on_both"], info["agree"]) == (3, 2, 1)
    assert info["agreement"] == 0.5
    assert info["agree_all_cells"] == 1  # the non-robust cell's PyBullet majority (pinch) differs
    (d,) = info["disagreements"]
    assert (d["centering_position_m"], d["pybullet"], d["mujoco"]) == (0.105, "power", "pinch")
    assert (
        d["decided_by"]
        == "proximal share of the hold force 0.4 (PyBullet) vs 0.12 (MuJoCo); pinch below 0.25"
    )
    paper = engine_audit(pybullet, mujoco, "paper")
    assert (
        "final mean contact position 0.85 (PyBullet) vs 0.85 (MuJoCo) of the finger; "
        "pinch above 1 − DSR = 0.80" in (paper["disagreements"][0]["decided_by"])
    )


def test_a_held_box_against_a_dropped_one_names_the_held_test() -> None:
    pybullet = _run([(0.2, 0.04, 0.1, ["pinch"] * 3, 0.1)])
    mujoco = _run([(0.2, 0.04, 0.1, ["no_grasp"] * 3, float("nan"))])
    (d,) = engine_audit(pybullet, mujoco, "contacts")["disagreements"]
    assert d["decided_by"].startswith("held or not: lift 0.07 (PyBullet) vs 0 (MuJoCo) m (held needs ≥ 0.01)")


def test_a_table_that_is_not_a_grasp_run_is_refused() -> None:
    with pytest.raises(SomoError, match="no label_grasp column"):
        engine_audit(pd.DataFrame({"trial": [0], "status": ["ok"]}), _run([]), "contacts")
    with pytest.raises(SomoError, match="unknown grasp rule 'nope'; allowed: contacts, paper"):
        engine_audit(_run([]), _run([]), "nope")


def test_fig6_with_an_audit_prints_it_and_stores_it_in_its_json(tmp_path: Path) -> None:
    from test_fig6 import results_folder

    folder = results_folder(tmp_path)
    audit = tmp_path / "audit"
    cells = [(0.2, 0.04, 0.1, ["pinch"] * 3, 0.1), (0.2, 0.04, 0.105, ["power"] * 3, 0.4)]
    for engine, table in (
        ("pybullet", _run(cells)),
        ("mujoco", _run([*cells[:1], (0.2, 0.04, 0.105, ["pinch"] * 3, 0.1)])),
    ):
        (audit / engine / "trials").mkdir(parents=True)
        (audit / engine / "manifest.json").write_text(json.dumps({"study_hash": "h"}))
        table.to_parquet(audit / engine / "trials" / "part-0.parquet")
    args = ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig"), "--audit", str(audit)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert (
        "engine audit (contacts rule): PyBullet and MuJoCo agree on 1 of the 2 cells robust on both (50.0%"
        in text
    )
    assert "DSR 0.2, width 40 mm, c 105 mm: PyBullet power, MuJoCo pinch; proximal share" in text
    stored = json.loads((folder / "fig6_contacts.json").read_text())["engine_audit"]
    assert (stored["robust_on_both"], stored["agree"], len(stored["disagreements"])) == (2, 1, 1)
    missing = CliRunner().invoke(app, [*args[:-1], str(tmp_path / "nowhere")])
    assert missing.exit_code == 2 and "--audit" in missing.output


def test_an_audit_of_other_cells_or_another_gripper_is_refused(tmp_path: Path) -> None:
    """An audit of another study ("agree on 2 of 2 … 100 %") was accepted and stored."""
    from test_fig6 import results_folder

    folder = results_folder(tmp_path)
    trials = pd.read_parquet(folder / "trials").assign(model_hash="gripper-a")
    trials.to_parquet(folder / "trials" / "part-0.parquet")

    def audit_of(name: str, cells: list[tuple[float, float, float, list[str], float]], model: str) -> Path:
        audit = tmp_path / name
        for engine in ("pybullet", "mujoco"):
            (audit / engine / "trials").mkdir(parents=True)
            (audit / engine / "manifest.json").write_text(json.dumps({"study_hash": "h"}))
            _run(cells).assign(model_hash=model).to_parquet(audit / engine / "trials" / "part-0.parquet")
        return audit

    def fig6(audit: Path) -> tuple[int, str]:
        args = ["paper", "fig6", str(folder), "--out", str(tmp_path / "fig"), "--audit", str(audit)]
        result = CliRunner().invoke(app, args)
        return result.exit_code, " ".join(result.output.split())

    here = [(0.2, 0.04, 0.1, ["pinch"] * 3, 0.1), (0.2, 0.04, 0.105, ["power"] * 3, 0.4)]
    elsewhere = [(0.3, 0.08, 0.15, ["pinch"] * 3, 0.1), (0.3, 0.08, 0.16, ["pinch"] * 3, 0.1)]
    code, text = fig6(audit_of("other_cells", elsewhere, "gripper-a"))
    assert code == 2 and "2 of its 2 PyBullet cells are not cells of these results" in text
    assert "the results have no cell there" in text and not (folder / "fig6_contacts.json").exists()
    code, text = fig6(audit_of("other_gripper", here, "gripper-b"))
    assert code == 2 and "model_hash gripper-b (the results: gripper-a)" in text
    code, text = fig6(audit_of("this_one", here, "gripper-a"))
    assert code == 0 and "agree on 2 of the 2 cells robust on both" in text
