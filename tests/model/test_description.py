"""Descriptions: the schema accepts what SoMo describes and rejects broken files clearly."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import pytest
import yaml
from conftest import MODELS, load_yaml

from somo_sweep.errors import DescriptionError, MeasurementError, Problem, UnstableSimulation
from somo_sweep.model.description import Actuator, Link
from somo_sweep.model.load import load_model, model_from_dict
from somo_sweep.sim.planner import plan_assembly


def test_gripper_assembly_has_expected_links_and_joints() -> None:
    model = load_model(MODELS / "pinch_gripper.yaml")
    plans = plan_assembly(model.as_assembly())
    assert len(plans) == 1  # palm + two fingers form one multibody
    plan = plans[0]
    # palm + 2 x (finger base + 20 segments + fingertip)
    assert len(plan.links) == 1 + 2 * (1 + 20 + 1)
    assert len(plan.joints) == 2 * 20
    assert plan.inputs == ["left/proximal/grasp", "right/proximal/grasp"]
    assert plan.mode == "driven"
    # joints alternate grasp (axis 0) and side (axis 1) along each finger
    left = [j for j in plan.joints if j.manipulator == "left"]
    assert [j.axis for j in left[:4]] == [0, 1, 0, 1]
    assert sum(j.input_index >= 0 for j in plan.joints) == 2 * 8  # 8 driven grasp joints per finger


def test_yaml_json_and_dict_give_the_same_model(tmp_path: Path) -> None:
    data = load_yaml("ihm_finger.yaml")
    path = tmp_path / "finger.json"
    path.write_text(json.dumps(data))
    assert load_model(path) == load_model(MODELS / "ihm_finger.yaml") == model_from_dict(data)


def test_all_link_shapes_are_accepted() -> None:
    shapes = [
        {"shape": "box", "size_m": [0.02, 0.01]},
        {"shape": "stadium", "size_m": [0.03, 0.01]},
        {"shape": "cylinder", "radius_m": 0.01},
        {"shape": "capsule", "radius_m": 0.004},
        {"shape": "sphere", "radius_m": 0.005},
    ]
    for shape in shapes:
        act = Actuator.model_validate(
            {
                "length_m": 0.1,
                "n_segments": 10,
                "link": {**shape, "mass_kg": 0.01},
                "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": 1.0}],
            }
        )
        # every shape spans one 10 mm segment (a sphere of radius 5 mm fills it too)
        assert act.segment_link().length_z_m == pytest.approx(0.01)


def test_segment_length_rounds_within_tolerance() -> None:
    # 0.1 / 0.005 is 20.000000000000004 in floating point: must not trip an exact comparison
    act = Actuator.model_validate(
        {
            "length_m": 0.1,
            "segment_length_m": 0.005,
            "link": {"shape": "box", "size_m": [0.02, 0.01], "mass_kg": 0.01},
            "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": 1.0}],
        }
    )
    assert act.segments == 20
    for ratio in [i * 0.05 for i in range(15)]:  # every DSR of the study splits 20 links cleanly
        distal = round(20 * ratio)
        assert Actuator.model_validate(
            {
                "length_m": 0.005 * distal or 0.005,
                "segment_length_m": 0.005,
                "link": {"shape": "box", "size_m": [0.02, 0.01], "mass_kg": 0.01},
                "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": 1.0}],
            }
        )


def test_length_not_whole_number_of_segments_is_rejected_clearly() -> None:
    data = load_yaml("ihm_finger.yaml")
    act = data["manipulator"]["actuators"][0]
    del act["n_segments"]
    act["segment_length_m"] = 0.0075
    with pytest.raises(DescriptionError) as err:
        model_from_dict(data, "finger.yaml")
    text = str(err.value)
    assert "finger.yaml" in text and "manipulator.actuators[0]" in text
    assert "not a whole number of segments" in text and "13.3333" in text


def test_unknown_key_gets_did_you_mean_and_allowed_keys() -> None:
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"]["actuators"][0]["joints"][0]["stifness_n_m_per_rad"] = 1.0
    with pytest.raises(DescriptionError) as err:
        model_from_dict(data, "f.yaml")
    text = str(err.value)
    assert "manipulator.actuators[0].joints[0].stifness_n_m_per_rad: unknown key" in text
    assert "did you mean 'stiffness_n_m_per_rad'?" in text


def test_all_problems_are_reported_at_once_with_lines(tmp_path: Path) -> None:
    text = (MODELS / "ihm_finger.yaml").read_text()
    text = text.replace("mass_kg: 0.00294", "mass_kg: -1").replace("shape: box\n", "shape: cube\n")
    text = text.replace("length_m: 0.100", "lenght_m: 0.100")
    path = tmp_path / "broken.yaml"
    path.write_text(text)
    with pytest.raises(DescriptionError) as err:
        load_model(path)
    problems = err.value.problems
    rendered = str(err.value)
    assert str(path) in rendered
    assert len(problems) >= 3
    assert any("shape" in p.path and "'box'" in p.message for p in problems)  # allowed values listed
    assert any(
        p.path.endswith("mass_kg")
        and "greater than or equal to 0.000000001" in p.message
        and "-1" in p.message
        for p in problems
    )
    assert any("lenght_m" in p.message and "did you mean 'length_m'" in p.message for p in problems)
    assert all(p.line is not None for p in problems)


def test_joint_fields_must_match_joint_type() -> None:
    with pytest.raises(DescriptionError, match="prismatic joint does not take stiffness_n_m_per_rad"):
        model_from_dict(
            {
                "manipulator": {
                    "actuators": [
                        {
                            "length_m": 0.1,
                            "n_segments": 2,
                            "link": {"shape": "box", "size_m": [0.02, 0.01], "mass_kg": 0.01},
                            "joints": [
                                {
                                    "type": "prismatic",
                                    "axis": [0, 0, 1],
                                    "stiffness_n_m_per_rad": 1.0,
                                }
                            ],
                        }
                    ]
                }
            }
        )


def test_zero_axis_and_bad_limits_are_rejected() -> None:
    base = {
        "length_m": 0.1,
        "n_segments": 2,
        "link": {"shape": "box", "size_m": [0.02, 0.01], "mass_kg": 0.01},
    }
    with pytest.raises(DescriptionError, match="non-zero vector"):
        model_from_dict(
            {
                "manipulator": {
                    "actuators": [{**base, "joints": [{"axis": [0, 0, 0], "stiffness_n_m_per_rad": 1.0}]}]
                }
            }
        )
    with pytest.raises(DescriptionError, match="lower < upper"):
        model_from_dict(
            {
                "manipulator": {
                    "actuators": [
                        {
                            **base,
                            "joints": [
                                {
                                    "axis": [1, 0, 0],
                                    "stiffness_n_m_per_rad": 1.0,
                                    "limits_rad": [1.0, -1.0],
                                }
                            ],
                        }
                    ]
                }
            }
        )


def test_missing_include_names_the_key(tmp_path: Path) -> None:
    data = load_yaml("pinch_gripper.yaml")
    data["assembly"]["manipulators"][0]["file"] = "nope.yaml"
    with pytest.raises(DescriptionError, match=r"assembly.manipulators\[0\].file: cannot include"):
        model_from_dict(data, "g.yaml", MODELS)


def test_unparsable_yaml_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("manipulator:\n  name: [unclosed\n")
    with pytest.raises(DescriptionError, match=r"- line 3: <top level>: cannot parse: while parsing a flow"):
        load_model(path)


def test_stadium_inertia_and_extent() -> None:
    link = Link(shape="stadium", size_m=(0.03, 0.01, 0.02), mass_kg=0.01)
    assert link.half_extent_m(0) == pytest.approx(0.015)
    assert link.principal_inertia_kg_m2().shape == (3,)
    with pytest.raises(ValueError):
        Link(shape="stadium", size_m=(0.01, 0.03, 0.02), mass_kg=0.01)


def test_stiffness_profile_scales_joints() -> None:
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"]["actuators"][0]["stiffness_profile"] = [1.0 + 0.1 * i for i in range(10)]
    plan = plan_assembly(model_from_dict(data).as_assembly())[0]
    assert plan.joints[4].stiffness == pytest.approx(0.2186 * 1.4)
    bad = yaml.safe_load(yaml.safe_dump(data))
    bad["manipulator"]["actuators"][0]["stiffness_profile"] = [1.0] * 3
    with pytest.raises(DescriptionError, match="needs 10 entries"):
        model_from_dict(bad)


def test_four_finger_hand_with_palm_loads() -> None:
    model = load_model(MODELS / "ihm_hand.yaml")
    plans = plan_assembly(model.as_assembly())
    assert [p.name for p in plans] == ["ihm_hand", "palm"]  # hand body + the fixed palm the cube rests on
    hand = plans[0]
    assert len(hand.joints) == 4 * 10 and len(hand.inputs) == 8
    assert len(hand.links) == 1 + 4 * (1 + 10 + 1)


def test_rigid_arm_carries_soft_fingers_at_its_tip() -> None:
    import numpy as np

    from somo_sweep.sim.settings import WorldSettings
    from somo_sweep.sim.worlds import open_world

    model = load_model(MODELS / "arm_with_fingers.yaml")
    plan = plan_assembly(model.as_assembly())[0]
    assert plan.inputs[:2] == ["arm/shoulder/pitch", "arm/elbow/pitch"] and len(plan.joints) == 2 + 2 * 10
    with open_world(WorldSettings(gravity_m_s2=(0, 0, 0))) as world:
        handle = world.add_model(model)
        body = handle.bodies[0]
        arm_tip = world.tip_position(body, "arm")
        base = world.link_frame(body, "left__base")[0]
    assert np.linalg.norm(base - arm_tip) == pytest.approx(0.02, abs=1e-6)  # mounted 20 mm off the arm tip


def test_attach_to_must_name_an_earlier_manipulator() -> None:
    data = load_yaml("pinch_gripper.yaml")
    data["assembly"]["manipulators"][0]["attach_to"] = "right"
    with pytest.raises(DescriptionError, match="attach_to must name an earlier manipulator"):
        model_from_dict(data, "g.yaml", MODELS)


def test_top_level_underscore_keys_hold_yaml_anchors(tmp_path: Path) -> None:
    path = tmp_path / "anchored.yaml"
    path.write_text(
        "_link: &link {shape: box, size_m: [0.02, 0.01], mass_kg: 0.01}\n"
        "_joints: &joints [{axis: [1, 0, 0], stiffness_n_m_per_rad: 1.0}]\n"
        "manipulator:\n"
        "  actuators:\n"
        "    - {length_m: 0.1, n_segments: 5, link: *link, joints: *joints}\n"
        "    - {length_m: 0.05, n_segments: 5, link: *link, joints: *joints}\n"
    )
    model = load_model(path)
    assert model.manipulator is not None and len(model.manipulator.actuators) == 2
    assert model.manipulator.actuators[1].segment_m == pytest.approx(0.01)


@pytest.mark.parametrize(
    "error",
    [
        DescriptionError("study.yaml", [Problem("sweep.dsr.step", "must be > 0, got -0.05", line=7)]),
        MeasurementError("bench.csv", ["line 3, column pressure_kpa: 'abc' is not a number"]),
        UnstableSimulation("speed_cap", 0.25, "in body 'hand'"),
    ],
)
def test_errors_cross_process_boundaries_with_their_fields(error: Exception) -> None:
    # joblib and Dask pickle an exception raised in a worker; it must arrive whole.
    copy = pickle.loads(pickle.dumps(error))
    assert type(copy) is type(error) and str(copy) == str(error)
    assert vars(copy) == vars(error)


def _finger(link: dict | None = None, joint: dict | None = None, **actuator: object) -> dict:
    return {
        "manipulator": {
            "actuators": [
                {
                    "length_m": 0.1,
                    "n_segments": 5,
                    "link": {"shape": "box", "size_m": [0.02, 0.01], "mass_kg": 0.01, **(link or {})},
                    "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": 1.0, **(joint or {})}],
                    **actuator,
                }
            ]
        }
    }


@pytest.mark.parametrize(
    ("description", "where", "message"),
    [
        (_finger(link={"inertia_kg_m2": [0, 0, 0]}), "link.inertia_kg_m2", "> 0"),
        (_finger(link={"inertia_kg_m2": [-1e-6, 1e-9, 1e-9]}), "link.inertia_kg_m2", "> 0"),
        (_finger(link={"inertia_kg_m2": [1e30, 1e30, 1e30]}), "link.inertia_kg_m2", "<= 1e+10"),
        (_finger(link={"inertia_kg_m2": [1e-6, 1e-9, 1e-9]}), "link.inertia_kg_m2", "triangle inequality"),
        (
            _finger(link={"friction": {"anisotropic": [-1, 1e30, 0]}}),
            "friction.anisotropic",
            "from 0 to 1000",
        ),
        (_finger(link={"color_rgba": [2, -1, 0, 5]}), "link.color_rgba", "from 0 to 1"),
        (_finger(joint={"limits_rad": [-1e300, 1e300]}), "joints[0].limits_rad", "±1000 rad"),
        (_finger(joint={"stiffening_per_rad2": -1e300}), "joints[0].stiffening_per_rad2", "1000000"),
        (_finger(stiffness_gradient_per_m=1e300), "stiffness_gradient_per_m", "1000000"),
        (_finger(stiffness_gradient_per_m=1e6, length_m=10.0), "actuators[0]", "multiplies the last joint's"),
    ],
)
def test_physical_bounds_of_every_number_are_enforced(description: dict, where: str, message: str) -> None:
    """A value no real finger has was accepted and overflowed the modal estimate or Bullet."""
    with pytest.raises(DescriptionError) as err:
        model_from_dict(description)
    assert where in str(err.value) and message in str(err.value)


def test_a_friction_anchor_is_off_unless_asked_for_and_must_be_a_boolean() -> None:
    assert model_from_dict(_finger()).manipulator.actuators[0].link.friction.anchor is False
    anchored = model_from_dict(_finger(link={"friction": {"anchor": True}}))
    assert anchored.manipulator.actuators[0].link.friction.anchor is True
    with pytest.raises(DescriptionError, match=r"friction\.anchor"):
        model_from_dict(_finger(link={"friction": {"anchor": "sometimes"}}))


def test_a_real_inertia_and_anisotropic_friction_are_kept() -> None:
    model = model_from_dict(
        _finger(link={"inertia_kg_m2": [2e-7, 2e-7, 1e-7], "friction": {"anisotropic": [1, 0.1, 1]}})
    )
    link = model.manipulator.actuators[0].link
    assert link.inertia_kg_m2 == (2e-7, 2e-7, 1e-7) and link.friction.anisotropic == (1, 0.1, 1)


def test_automatic_numerics_of_a_heavy_chain_stay_bounded() -> None:
    """99-m links of 1000 t on the stiffest springs: the shaping search grew to inf (a traceback)."""
    from somo_sweep.model.description import MAX_ADDED_INERTIA_KG_M2
    from somo_sweep.sim.numerics import choose_numerics

    heavy = _finger(link={"size_m": [99, 99], "mass_kg": 999999.0}, joint={"stiffness_n_m_per_rad": 1e9})
    heavy["manipulator"]["actuators"][0]["length_m"] = 99.0
    chosen = choose_numerics(model_from_dict(heavy))
    assert 0 < chosen.time_step_s <= 4e-3
    assert all(0 <= c.added_inertia_kg_m2 <= MAX_ADDED_INERTIA_KG_M2 for c in chosen.chains.values())


def test_capsule_segments_shorter_than_their_caps_are_refused_when_the_length_is_left_out() -> None:
    """Written out, such a length was refused; left out, 12-mm capsules were built in 10-mm segments."""
    capsule = {"shape": "capsule", "radius_m": 0.006, "mass_kg": 0.002}
    with pytest.raises(DescriptionError) as err:
        model_from_dict(_finger(link=capsule | {"size_m": None}, length_m=0.06, n_segments=6))
    text = str(err.value)
    assert "manipulator.actuators[0]" in text and "at least 2 * radius_m = 0.012 m" in text
    assert "(301 characters)" not in text and "'link':" not in text  # the section is not echoed
    model_from_dict(_finger(link=capsule | {"size_m": None}, length_m=0.06, n_segments=5))  # 12 mm: fits


def test_inputs_with_the_same_name_are_refused() -> None:
    joint = {"name": "j", "axis": [1, 0, 0], "stiffness_n_m_per_rad": 1.0}
    act = {
        "name": "a",
        "length_m": 0.05,
        "n_segments": 5,
        "link": {"shape": "sphere", "radius_m": 0.004, "mass_kg": 0.001},
    }
    with pytest.raises(DescriptionError, match="repeated: a/j"):
        model_from_dict(
            {"manipulator": {"actuators": [act | {"joints": [joint]}, act | {"joints": [joint]}]}}
        )
    model_from_dict(
        {"manipulator": {"actuators": [act | {"joints": [joint]}, act | {"name": "b", "joints": [joint]}]}}
    )
