"""The engine-neutral plan: SI data each engine builds its own world from."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.planner import plan_assembly, plan_manipulator
from somo_sweep.sim.pybullet.urdf import urdf_text

#: A mass with more digits than the URDF's ten (0.1 / 12 kg per link).
MASS_KG = 0.1 / 12


def _finger(shape: dict[str, object]) -> Manipulator:
    return Manipulator.model_validate(
        {
            "name": "finger",
            "base": {"link": {"shape": "box", "size_m": [0.02, 0.02, 0.01], "mass_kg": 0.05}},
            "actuators": [
                {
                    "length_m": 0.07,
                    "n_segments": 7,
                    "link": {**shape, "mass_kg": MASS_KG, "offset_m": [0.0, 0.001, 0.0]},
                    "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": 0.3, "limits_rad": [-1.0, 1.5]}],
                }
            ],
        }
    )


def test_a_plan_is_a_tree_in_si() -> None:
    """Every link but the root hangs from an earlier one by one joint; masses and lengths are SI."""
    plan = plan_assembly(load_model(bundled_path("models", "pinch_gripper.yaml")).as_assembly())[0]
    names = [info.name for info in plan.links]
    assert [j.child for j in plan.tree] == names[1:]
    assert all(names.index(j.parent) < names.index(j.child) for j in plan.tree)
    springs = [j for j in plan.tree if j.kind != "fixed"]
    assert [j.name for j in springs] == [sj.name for sj in plan.joints]
    palm = plan.links[0]
    assert palm.mass_kg == 0.2 and palm.shapes[0].size_m == (0.020, 0.090, 0.032)
    mount = next(j for j in plan.tree if j.name == "left__mount")
    assert mount.xyz_m == (-0.015, 0.0262941, 0.0)


def test_a_stadium_link_is_a_box_between_two_cylinders() -> None:
    finger = _finger({"shape": "stadium", "size_m": [0.016, 0.006]})
    link = plan_manipulator(finger).links[2]
    box, left, right = link.shapes
    assert (box.kind, left.kind, right.kind) == ("box", "cylinder", "cylinder")
    assert box.size_m == pytest.approx((0.010, 0.006, 0.010))
    assert left.size_m == pytest.approx((0.003, 0.010)) and right.size_m == left.size_m
    assert right.centre_m[0] - left.centre_m[0] == pytest.approx(0.010)
    assert box.centre_m == link.com_m and link.com_m[1] == pytest.approx(0.001)  # the link's offset


def _numbers(root: ET.Element, path: str, key: str) -> np.ndarray:
    element = root.find(path)
    assert element is not None, path
    return np.array([float(v) for v in element.get(key, "").split()])


def test_pybullet_writes_the_plan_in_its_scaled_world() -> None:
    """Lengths ×Y, inertias ×Y², masses ×1 (paper Sec. III-B.4), ten significant digits."""
    plan = plan_manipulator(_finger({"shape": "capsule", "radius_m": 0.004}))
    link = plan.links[2]
    at = f"link[@name='{link.name}']/"
    for s in (1.0, 20.0):
        root = ET.fromstring(urdf_text(plan, s))
        assert _numbers(root, at + "inertial/mass", "value")[0] == pytest.approx(MASS_KG, rel=1e-10)
        np.testing.assert_allclose(_numbers(root, at + "inertial/origin", "xyz"), np.array(link.com_m) * s)
        ixx = _numbers(root, at + "inertial/inertia", "ixx")[0]
        assert ixx == pytest.approx(link.inertia_kg_m2[0] * s * s, rel=1e-9)
        assert _numbers(root, at + "collision/geometry/capsule", "radius")[0] == pytest.approx(0.004 * s)
        # the cylindrical part: the 10-mm link less its two caps
        assert _numbers(root, at + "collision/geometry/capsule", "length")[0] == pytest.approx(0.002 * s)
        joint = "joint[@name='finger__a0_j1']/"
        assert _numbers(root, joint + "origin", "xyz")[2] == pytest.approx(0.010 * s)
        assert _numbers(root, joint + "limit", "lower")[0] == -1.0  # radians: never scaled


def test_mujoco_builds_its_scene_from_the_si_plan_not_from_text() -> None:
    """MuJoCo's bodies get the description's numbers exactly, not their ten-digit URDF text."""
    pytest.importorskip("mujoco")
    from somo_sweep.sim.settings import WorldSettings
    from somo_sweep.sim.worlds import open_world

    finger = _finger({"shape": "box", "size_m": [0.016, 0.006]})
    plan = plan_manipulator(finger)
    with open_world(WorldSettings.on("mujoco")) as world:
        body = world.load_plan(plan)
        world.link_rotations(body)  # compiles
        ids = world.link_bodies(body)
        masses = [float(world.model.body_mass[i]) for i in ids]
        ipos = np.array([world.model.body_ipos[i] for i in ids])
    assert masses == [info.mass_kg for info in plan.links]
    assert MASS_KG in masses and float(f"{MASS_KG:.10g}") != MASS_KG  # ten-digit text would round it
    np.testing.assert_array_equal(ipos, np.array([info.com_m for info in plan.links]))
