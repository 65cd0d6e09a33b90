"""The bundled 20-link finger keeps its labels: the MuJoCo quick study's cells, both rules.

``data/pinch_grasp_quick_mujoco_labels.csv`` holds every cell's labels of
``studies/pinch_grasp_quick_mujoco.yaml`` under both rules from a run of the code before
the contact metrics moved to positions along the finger. The default suite reruns one cell
of each (contacts, paper) label pair; the slow test reruns all 192.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.trial import run_job
from somo_sweep.sweep.study import load_study

LABELS = Path(__file__).parent / "data" / "pinch_grasp_quick_mujoco_labels.csv"


def _stored() -> pd.DataFrame:
    return pd.read_csv(LABELS, comment="#")


def _rerun(trials: list[int]) -> pd.DataFrame:
    table = build_jobs(load_study(bundled_path("pinch_grasp_quick_mujoco.yaml")))
    rows = []
    for trial in trials:
        job = table.maker.job(trial)
        result = run_job(job).result
        assert result.status == "ok", result.message
        rows.append(
            {
                "trial": trial,
                "grasp_contacts": result.labels["grasp"],
                "grasp_paper": result.labels["grasp_paper"],
            }
        )
    return pd.DataFrame(rows)


def _check(trials: list[int]) -> None:
    stored = _stored().set_index("trial").loc[trials, ["grasp_contacts", "grasp_paper"]]
    now = _rerun(trials).set_index("trial")
    differ = stored.compare(now)
    assert differ.empty, f"labels changed:\n{differ}"


def test_stored_labels_cover_every_cell_and_label_pair() -> None:
    stored = _stored()
    assert len(stored) == 192 and list(stored["trial"]) == list(range(192))
    assert stored.groupby(["grasp_contacts", "grasp_paper"]).ngroups == 7


def test_a_cell_of_each_label_pair_keeps_its_labels() -> None:
    stored = _stored()
    _check([int(g["trial"].iloc[0]) for _, g in stored.groupby(["grasp_contacts", "grasp_paper"])])


@pytest.mark.slow
def test_every_cell_of_the_quick_study_keeps_its_labels() -> None:
    _check(list(range(192)))
