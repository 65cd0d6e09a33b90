"""The README's "Your own gripper" lines, run literally in a fresh folder: a finger of one's own
(85 mm, 17 links), a three-finger starter, its bench CSV filled with rows measured on an
independent elastica (not on our chain), calibration in place, the robust map, its plots and
the answer per stiffness.

The default suite runs the map on a tiny grid (the study's axes cut to one cell per stiffness);
the slow test runs the study as written.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from io import StringIO
from pathlib import Path

import pandas as pd
import pytest
import yaml

from somo_sweep.model.load import load_model
from tests.reference.rod import Rod, bench_rows

ROOT = Path(__file__).resolve().parents[1]
SOMO = Path(sys.executable).with_name("somo-sweep")
#: The user's finger as designed: 85 mm over 17 links; its stiffness and gain are first guesses.
MY_FINGER = """\
manipulator:
  name: my_finger
  base:
    mode: fixed
    link: {shape: box, size_m: [0.030, 0.030, 0.010], mass_kg: 0.05, friction: {lateral: 2.0}}
  actuators:
    - name: finger
      length_m: 0.085
      n_segments: 17
      link: {shape: box, size_m: [0.020, 0.015], mass_kg: 0.0012, friction: {lateral: 2.0, spinning: 0.004}}
      joints:
        - {name: grasp, axis: [1, 0, 0], stiffness_n_m_per_rad: 0.5, motor_limit_n_m: 0.002}
  actuation: {pressure_gain_n_m_per_kpa: 1.0e-3}
"""
#: The real finger the bench measures: a continuum of that length, tip stiffness and mass (SI).
TRUTH = {
    "length_m": 0.085,
    "tip_stiffness_n_m": 20.0,
    "mass_kg": 0.0204,
    "half_thickness_m": 0.0075,
    "gain_n_m_per_kpa": 8e-4,
}


def readme_lines() -> list[list[str]]:
    """The commands of the README's own-gripper block, as argv lists (comments dropped)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Your own gripper", 1)[1].split("\n## ", 1)[0]
    block = re.search(r"```bash\n(.*?)```", section, flags=re.S)
    assert block is not None, "the README's own-gripper section has no bash block"
    return [argv for line in block.group(1).splitlines() if (argv := shlex.split(line, comments=True))]


def _fill_bench(csv: Path) -> None:
    """What the user does by hand: measure the rows the template lists and write them in."""
    lines = csv.read_text(encoding="utf-8").splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    plan = pd.read_csv(StringIO("\n".join(ln for ln in lines if not ln.startswith("#"))))
    rows = bench_rows(Rod.from_tip_stiffness(**TRUTH), plan, noise_rel=0.01, seed=0)[list(plan.columns)]
    text = "\n".join(comments) + "\n" + rows.to_csv(index=False, float_format="%.6g")
    csv.write_text(text, encoding="utf-8")


def _tiny_grid(study: Path) -> None:
    """One cell per stiffness: the middle ratio, a 40-mm box, the middle centering position; two
    replicas a cell."""
    data = yaml.safe_load(study.read_text(encoding="utf-8"))
    sweep = data["sweep"]
    ratios = sweep["task.distal_segment_ratio"]
    c = sweep["task.centering_position_m"]
    data["sweep"] = {
        "task.distal_segment_ratio": [ratios[len(ratios) // 2]],
        "task.spring_scale": sweep["task.spring_scale"],
        "task.object_width_m": [0.04],
        "task.centering_position_m": [round(c["start"] + 2 * c["step"], 6)],
    }
    data["robustness"] = {"replicas": 2}
    study.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")


def _chain(folder: Path, tiny: bool) -> tuple[pd.DataFrame, str]:
    """Run the README's lines in ``folder`` as typed; returns the map's trials and what the last
    line (the answer) printed."""
    (folder / "my_finger.yaml").write_text(MY_FINGER, encoding="utf-8")
    lines = readme_lines()
    assert [argv[:2] for argv in lines] == [
        ["somo-sweep", "new"],
        ["somo-sweep", "calibrate"],
        ["somo-sweep", "run"],
        ["somo-sweep", "plot"],
        ["somo-sweep", "answer"],
    ]
    for argv in lines:
        if argv[1] == "calibrate":
            _fill_bench(folder / "mine" / "bench.csv")
        if argv[1] == "run" and tiny:
            _tiny_grid(folder / "mine" / "study.yaml")
        command = [str(SOMO), *argv[1:]]
        done = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=3000)
        assert done.returncode == 0, f"{shlex.join(argv)}\n{done.stdout}\n{done.stderr}"
    return pd.read_parquet(folder / "results" / "my_grasp_study" / "trials"), done.stdout


def _check_calibrated_three_finger_map(folder: Path, table: pd.DataFrame) -> None:
    finger = load_model(folder / "mine" / "finger.yaml").manipulator
    assert finger is not None and finger.actuation is not None
    assert finger.actuation.pressure_gain_n_m_per_kpa == pytest.approx(TRUTH["gain_n_m_per_kpa"], rel=0.03)
    fingers = load_model(folder / "mine" / "gripper.yaml").as_assembly().manipulators
    assert [m.name for m in fingers] == ["finger1", "finger2", "finger3"]
    assert (table["status"] == "ok").all()
    assert sorted(set(table["task_spring_scale"])) == [0.5, 1.0, 2.0]
    for k in (1, 2, 3):
        assert table[f"hold_normal_force_finger{k}_n"].notna().all()
    assert (folder / "results" / "my_grasp_study" / "plots" / "label_map_grasp.png").stat().st_size > 0


def _check_an_answer_per_stiffness(answer: str, table: pd.DataFrame) -> None:
    """The last line answers once per stiffness scale, each answer a ratio of the map or none."""
    print(answer)
    ratios = {f"{v:g}" for v in table["task_distal_segment_ratio"]}
    for scale in ("0.5", "1", "2"):
        line = next(
            (
                ln
                for ln in answer.splitlines()
                if f"spring_scale {scale}" in ln or f"spring_scale={scale}" in ln
            ),
            None,
        )
        assert line is not None, answer
        assert any(r in line for r in ratios) or "none" in line, line


def test_the_readmes_own_gripper_lines_run_as_typed_on_a_tiny_grid(tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    table, answer = _chain(tmp_path, tiny=True)
    _check_calibrated_three_finger_map(tmp_path, table)
    _check_an_answer_per_stiffness(answer, table)
    assert len(table[table["replica"] == 0]) == 3  # one cell per stiffness


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_the_readmes_own_gripper_chain_runs_whole(tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    table, answer = _chain(tmp_path, tiny=False)
    _check_calibrated_three_finger_map(tmp_path, table)
    _check_an_answer_per_stiffness(answer, table)
    trials = table[table["replica"] == 0]
    assert len(trials) == 180  # 3 ratios x 3 stiffness scales x 4 widths x 5 centering positions
    pinched = trials[trials["label_grasp"] == "pinch"]
    assert len(pinched) > 0  # the gripper pinches somewhere: the answer is not empty
    for k in (1, 2, 3):  # and in a pinch every finger presses on the box
        assert (pinched[f"hold_normal_force_finger{k}_n"] > 0).all()
