"""A gripper of the user's own fingers in a grasp study: any link count, DSR as a length fraction,
pressure through each finger's gain, a finger's fields swept through the gripper, every problem at
once, and the starter folder that runs as written."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.model.load import model_from_dict
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.pinch_grasp.checks import check_gripper
from somo_sweep.tasks.pinch_grasp.links import distal_split_problem
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams
from somo_sweep.tasks.pinch_grasp.starter import STARTER_FILES, grasp_study_files
from somo_sweep.tasks.pinch_grasp.task import drive_n_m

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "own_gripper"


def _finger(
    n_links: int = 12, length_m: float = 0.070, gain: float | None = 8e-4, name: str = "finger"
) -> dict:
    finger = {
        "name": name,
        "base": {"mode": "fixed", "link": {"shape": "box", "size_m": [0.03, 0.03, 0.01], "mass_kg": 0.05}},
        "actuators": [
            {
                "name": "finger",
                "length_m": length_m,
                "n_segments": n_links,
                "link": {"shape": "box", "size_m": [0.02, 0.015], "mass_kg": 0.001},
                "joints": [{"name": "grasp", "axis": [1, 0, 0], "stiffness_n_m_per_rad": 0.58}],
            }
        ],
    }
    if gain is not None:
        finger["actuation"] = {"pressure_gain_n_m_per_kpa": gain}
    return finger


def _gripper(fingers: list[dict], mode: str = "driven") -> dict:
    mounts = [  # each finger turned so that its grasp axis [1, 0, 0] bends it toward y = 0
        {
            "name": f"f{i}",
            "manipulator": f,
            "pose": {
                "position_m": [-0.015, 0.03 * (i - 0.5), 0.0],
                "rpy_rad": [0.0, 0.0, math.pi * (i == 0)],
            },
        }
        for i, f in enumerate(fingers)
    ]
    box = {"shape": "box", "size_m": [0.02, 0.09, 0.032], "mass_kg": 0.2}
    return {"assembly": {"name": "g", "base": {"mode": mode, "link": box}, "manipulators": mounts}}


def _study(tmp_path: Path, gripper: dict, params: dict, sweep: dict | None = None) -> Path:
    (tmp_path / "gripper.yaml").write_text(yaml.safe_dump(gripper))
    study = {"name": "own", "task": "pinch_grasp", "model": "gripper.yaml", "params": params, "seed": 0}
    study["sweep"] = sweep or {"task.object_width_m": [0.04]}
    study["simulation"] = {"engine": "mujoco", "time_step_s": 4e-3}
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(study))
    return path


def test_a_ratio_off_a_link_boundary_is_refused_naming_the_nearest_ones(tmp_path: Path) -> None:
    assert distal_split_problem(0.25, 12, 0.07 / 12) is None
    assert distal_split_problem(0.35, 20, 0.005) is None  # 20 * 0.35 = 7.000000000000001
    path = _study(tmp_path, _gripper([_finger(), _finger()]), {"distal_segment_ratio": 0.2})
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    text = " ".join(str(info.value).split())
    assert "distal_segment_ratio 0.2 cannot be expressed by a finger of 12 links of 5.833 mm" in text
    assert "nearest: 0.1667 (2 distal links), 0.25 (3 distal links)" in text


def test_every_problem_of_a_gripper_is_reported_at_once() -> None:
    one_link = _finger(n_links=1)
    bad = model_from_dict(_gripper([one_link], mode="fixed"))
    needs = check_gripper(bad)
    assert len(needs) == 3, needs
    assert "base must be driven; got base mode 'fixed'" in needs[0]
    assert "got 1 manipulator(s) ('f0'); allowed: an assembly with 2 or more manipulators" in needs[1]
    assert "finger 'f0' has 1 link(s); allowed: 2 or more" in needs[2]
    mixed = model_from_dict(_gripper([_finger(12), _finger(10)]))
    assert check_gripper(mixed) == [
        "the fingers have different link counts ('f0' 12, 'f1' 10); allowed: one link count for all"
    ]
    three = model_from_dict(_gripper([_finger(), _finger(), _finger()]))
    assert check_gripper(three) == []


def test_pressure_and_torque_together_are_refused(tmp_path: Path) -> None:
    path = _study(tmp_path, _gripper([_finger(), _finger()]), {"pressure_kpa": 100, "torque_n_m": 0.1})
    with pytest.raises(DescriptionError, match=r"task.torque_n_m .* or task.pressure_kpa .*, not both"):
        load_study(path)


def test_pressure_on_a_finger_without_a_gain_is_refused_naming_it(tmp_path: Path) -> None:
    gripper = _gripper([_finger(), _finger(gain=None, name="plain")])
    with pytest.raises(DescriptionError) as info:
        load_study(_study(tmp_path, gripper, {"pressure_kpa": 100, "distal_segment_ratio": 0.25}))
    text = " ".join(str(info.value).split())
    assert "finger 'f1' has none; allowed: a finger with an actuation block" in text


def test_pressure_drives_each_finger_through_its_own_gain() -> None:
    hand = model_from_dict(_gripper([_finger(gain=1e-3), _finger(gain=5e-4)]))
    names = ["f0/finger/grasp", "f1/finger/grasp"]
    assert drive_n_m(hand, PinchGraspParams(pressure_kpa=120), names) == pytest.approx([0.12, 0.06])
    assert drive_n_m(hand, PinchGraspParams(), names) == [0.15, 0.15]  # the paper's torque
    assert drive_n_m(hand, PinchGraspParams(torque_n_m=0.1), names) == [0.1, 0.1]


def test_a_finger_field_is_swept_through_the_gripper_on_every_finger(tmp_path: Path) -> None:
    key = "model.assembly.manipulators[*].manipulator.actuators[0].n_segments"
    study = load_study(
        _study(tmp_path, _gripper([_finger(), _finger()]), {"distal_segment_ratio": 0.5}, {key: [10, 12]})
    )
    resolver = study.resolver()
    for n in (10, 12):
        _, model = resolver.model({key: n})
        assert [
            sum(a.segments for a in m.manipulator.actuators) for m in model.as_assembly().manipulators
        ] == [
            n,
            n,
        ]


def test_the_starter_folder_loads_refuses_to_overwrite_and_names_its_finger(tmp_path: Path) -> None:
    runner = CliRunner()
    out = tmp_path / "mine"
    result = runner.invoke(app, ["new", "grasp-study", str(out)])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == sorted(STARTER_FILES)
    study = load_study(out / "study.yaml")  # every cell's finger, ratio and pressure pass the checks
    assert study.n_trials == 180  # 3 ratios × 3 stiffness scales × 4 widths × 5 centering positions
    bench = (out / "bench.csv").read_text().splitlines()
    assert "# finger: {length_mm: 70, segments: 12, mass_g: 12, width_mm: 20, thickness_mm: 15}" in bench
    header = next(line for line in bench if not line.startswith("#"))
    assert header.split(",") == [
        "test",
        "pressure_kpa",
        "tip_load_n",
        "tip_deflection_mm",
        "blocked_force_n",
        "tip_x_mm",
        "tip_z_mm",
    ]
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    again = runner.invoke(app, ["new", "grasp-study", str(out)])
    assert again.exit_code == 2
    held = "finger.yaml, gripper.yaml, bench.csv, study.yaml, design.yaml"
    assert f"already holds {held}; nothing was written" in again.output
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_starter_for_a_twenty_link_finger_sweeps_ratios_it_can_express(tmp_path: Path) -> None:
    files = grasp_study_files(ROOT / "studies" / "models" / "pinch_finger.yaml")
    assert "task.distal_segment_ratio: [0, 0.25, 0.5]" in files["study.yaml"]
    assert "segments: 20, mass_g: 46" in files["bench.csv"]
    seven_links = tmp_path / "finger.yaml"
    seven_links.write_text(yaml.safe_dump({"manipulator": _finger(n_links=7)}))
    seven = grasp_study_files(seven_links)
    assert "task.distal_segment_ratio: [0, 0.285714285714, 0.571428571429]" in seven["study.yaml"]


def test_tasks_name_lists_every_parameter_with_its_default_and_meaning() -> None:
    result = CliRunner().invoke(app, ["tasks", "pinch_grasp"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert "  pressure_kpa: null" in lines
    assert "  distal_segment_ratio: 0.2" in lines
    assert "  numerics.added_inertia_kg_m2: null" in lines
    assert "Giving both is refused." in " ".join(result.output.split())
    assert max(len(line) for line in lines) <= 80
    wrong = CliRunner().invoke(app, ["tasks", "pinch_grap"])
    assert wrong.exit_code == 2 and "did you mean 'pinch_grasp'" in wrong.output


def test_tasks_name_lists_the_designers_parameters_first_and_the_original_block_apart() -> None:
    lines = CliRunner().invoke(app, ["tasks", "pinch_grasp"]).output.splitlines()
    lines = lines[: next(n for n, line in enumerate(lines) if line.startswith("metrics"))]
    keys = [line.split(":")[0].strip() for line in lines if re.fullmatch(r"  [a-z_.]+: .*", line)]
    moved = [
        "original.finger_spinning_friction_m",
        "original.restitution",
        "original.lift_profile",
        "original.object_shape",
        "original.clamp_speed_cap",
    ]
    assert keys[-5:] == moved and "spring_scale" in keys[:-5] and not any("original" in k for k in keys[:-5])
    heading = next(n for n, line in enumerate(lines) if line.startswith("task.original: "))
    assert lines[heading - 1] == ""
    assert "kept to reproduce its study, not to design with" in " ".join(lines[heading : heading + 2])
    assert lines.index("  original.finger_spinning_friction_m: null") > heading


def test_a_study_whose_fingers_reach_the_box_in_no_cell_is_refused(tmp_path: Path) -> None:
    short = _gripper([_finger(n_links=6, length_m=0.030), _finger(n_links=6, length_m=0.030)])
    sweep = {"task.centering_position_m": [0.08, 0.1], "task.object_width_m": [0.02, 0.04]}
    with pytest.raises(DescriptionError) as info:
        load_study(_study(tmp_path, short, {"distal_segment_ratio": 0.5}, sweep))
    text = " ".join(str(info.value).split())
    assert "the fingers reach at most 40.0 mm from their mounts" in text
    assert (
        "the nearest, centering_position_m 0.1 with object_width_m 0.04, leaves its near face 40.0 mm" in text
    )
    assert "allowed: centering_position_m of at least 0.140 for that width, or longer fingers" in text
    # One cell in reach is enough: the others are no-grasp results, as in the paper's grid.
    sweep["task.centering_position_m"] = [0.08, 0.15]
    load_study(_study(tmp_path, short, {"distal_segment_ratio": 0.5}, sweep))


def test_a_three_finger_gripper_of_two_actuator_fingers_runs_as_written() -> None:
    pytest.importorskip("mujoco")
    from somo_sweep.sim.settings import WorldSettings
    from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

    finger = _finger(n_links=8, length_m=0.060)
    act = finger["actuators"][0]
    finger["actuators"] = [
        {**act, "name": "base_half", "length_m": 0.030, "n_segments": 4},
        {**act, "name": "tip_half", "length_m": 0.030, "n_segments": 4},
    ]
    hand = model_from_dict(_gripper([finger, finger, finger]))
    params = PinchGraspParams(distal_segment_ratio=None, pressure_kpa=100, centering_position_m=0.15)
    result = run_pinch_grasp(hand, params, WorldSettings.on("mujoco", time_step_s=4e-3))
    assert result.status == "ok", result.message
    m = result.metrics
    assert m["n_finger_links"] == 8 and m["n_distal_links"] == 4  # the last actuator, as written
    assert m["finger_length_m"] == pytest.approx(0.060)
    assert result.labels["grasp"] in {"pinch", "power", "no_grasp"}


def test_a_ratio_finer_than_a_link_and_fingers_out_of_reach_are_reported_together(tmp_path: Path) -> None:
    short = _gripper([_finger(n_links=6, length_m=0.030), _finger(n_links=6, length_m=0.030)])
    sweep = {"task.centering_position_m": [0.08], "task.distal_segment_ratio": [0.1]}
    with pytest.raises(DescriptionError) as info:
        load_study(_study(tmp_path, short, {}, sweep))
    text = " ".join(str(info.value).split())
    assert "2 problem(s)" in text
    assert "distal_segment_ratio 0.1 cannot be expressed by a finger of 6 links of 5 mm" in text
    assert "nearest: 0 (0 distal links), 0.1667 (1 distal link)" in text
    assert "the fingers reach at most 40.0 mm from their mounts" in text
