"""The MuJoCo world's interface: Bullet's pair friction, collision rules, contacts, snapshots."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.mujoco.surfaces import Surface, combined, condim, contact_plan
from somo_sweep.sim.render import Camera, snapshot
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.worlds import open_world

mujoco = pytest.importorskip("mujoco")

#: Friction (lateral, spinning m) of the boxes stacked in the mixing test: pairs whose Bullet
#: product is their maximum, and pairs whose is not (2 on 2 gives 4, not 2).
SURFACES = [(2.0, 0.004), (2.0, 0.0), (1.0, 0.0), (0.5, 0.002), (3.0, 0.0)]


def _box(name: str, z_m: float, lateral: float, spinning: float) -> RigidBody:
    link = Link(
        shape="box",
        size_m=(0.05, 0.05, 0.02),
        mass_kg=0.05,
        friction={"lateral": lateral, "spinning": spinning},
    )
    return RigidBody(name=name, link=link, pose=Pose(position_m=(0.0, 0.0, z_m)))


@pytest.mark.parametrize("order", list(itertools.permutations(range(len(SURFACES)), 3))[::7])
def test_every_contact_gets_bullets_combined_friction(order: tuple[int, ...]) -> None:
    """Boxes stacked on the ground: MuJoCo's own contacts carry Bullet's product (sliding) and
    s_a·μ_b + s_b·μ_a (torsion), read back from MuJoCo, for every pair in the stack."""
    with open_world(WorldSettings.on("mujoco", time_step_s=2e-3)) as world:
        ground_friction = 1.0
        ground = world.add_ground(friction=ground_friction)
        bodies = [
            world.add_rigid_body(_box(f"b{i}", 0.0101 + 0.0201 * k, *SURFACES[i]))
            for k, i in enumerate(order)
        ]
        world.step(50)
        data, model = world.data, world.model
        owner = {b.id: Surface(*SURFACES[i]) for b, i in zip(bodies, order, strict=True)}
        owner[ground] = Surface(ground_friction)
        checked = set()
        for c in range(data.ncon):
            con = data.contact[c]
            a, b = (int(world._geom_owner[g]) for g in con.geom)
            want = combined(owner[a], owner[b])
            assert con.dim == condim(want)
            np.testing.assert_allclose(
                con.friction[[0, 2]], [want[0], max(want[1], 1e-5) if con.dim >= 4 else con.friction[2]]
            )
            checked.add(frozenset((a, b)))
        assert len(checked) == len(order)  # ground–bottom and every box on the next
        del model


def test_the_contact_plan_keeps_mujocos_own_detection_where_it_can() -> None:
    """The pinch gripper's surfaces: three classes, and only the pairs MuJoCo's mixing cannot give
    (object and base boxes among themselves, palm on ground, bases and object on ground) are explicit."""
    a, b, c = Surface(2.0, 0.004), Surface(2.0), Surface(1.0)
    surfaces = [a] * 42 + [b] * 3 + [c] * 2

    def may_touch(i: int, j: int) -> bool:
        return not (i < 21 and j < 21) and not (21 <= i < 42 and 21 <= j < 42)

    plan = contact_plan(surfaces, may_touch)
    touching = sum(may_touch(i, j) for i in range(47) for j in range(i + 1, 47))
    assert 0 < len(plan.pairs) <= 10 < touching
    for i, j, friction, dim in plan.pairs:
        assert friction == combined(surfaces[i], surfaces[j]) and dim == condim(friction)


def test_links_never_touch_their_ancestors_but_two_fingers_touch_each_other() -> None:
    gripper = load_model(bundled_path("models", "pinch_gripper.yaml"))
    with open_world(WorldSettings.on("mujoco")) as world:
        hand = world.add_model(gripper)
        world._ready()
        body = hand.bodies[0]
        names = [i.name for i in body.plan.links]
        model = world.model
        excluded = {
            frozenset((model.exclude_signature[k] >> 16, model.exclude_signature[k] & 0xFFFF))
            for k in range(model.nexclude)
        }
        ids = world.link_bodies(body)
        left_tip, left_first = ids[names.index("left__tip0")], ids[names.index("left__a0_s0")]
        right_tip = ids[names.index("right__tip0")]
        assert frozenset((left_first, left_tip)) in excluded  # ancestor, 20 links apart
        assert frozenset((left_tip, right_tip)) not in excluded  # two branches of one hand


def test_contacts_report_links_forces_and_normals_in_si() -> None:
    box = RigidBody(
        name="box",
        link=Link(shape="box", size_m=(0.04, 0.04, 0.04), mass_kg=0.1),
        pose=Pose(position_m=(0.0, 0.0, 0.0201)),
    )
    with open_world(WorldSettings.on("mujoco", time_step_s=2e-3)) as world:
        ground = world.add_ground()
        body = world.add_rigid_body(box)
        world.step(100)
        c = world.contacts(body.id, ground)
        swapped = world.contacts(ground, body.id)
        counts = (world.contact_count(body.id, ground), world.contact_count(ground, body.id))
        own = world.contact_count(body.id, body.id)
    assert len(c["link_a"]) == 4 and set(c["link_a"]) == {-1}
    assert c["normal_force_n"].sum() == pytest.approx(0.1 * 9.81, rel=1e-3)
    np.testing.assert_allclose(c["normal_b_to_a"], [[0, 0, 1]] * 4, atol=1e-9)  # ground pushes the box up
    np.testing.assert_allclose(swapped["normal_b_to_a"], -c["normal_b_to_a"])
    assert np.all(np.abs(c["position_on_a_m"][:, 2]) < 5e-4)  # the box's bottom face
    assert counts == (4, 4) and own == 0  # counted without building the arrays


def test_a_snapshot_of_each_engine_shows_the_scene_from_the_same_eye() -> None:
    box = RigidBody(
        name="box",
        link=Link(shape="box", size_m=(0.04, 0.04, 0.04), mass_kg=0.1, color_rgba=(1.0, 0.0, 0.0, 1.0)),
        pose=Pose(position_m=(0.0, 0.0, 0.02)),
    )
    camera = Camera(target_m=(0.0, 0.0, 0.02), distance_m=0.3, width_px=160, height_px=120)
    red = {}
    for engine in ("pybullet", "mujoco"):
        with open_world(WorldSettings.on(engine)) as world:
            world.add_ground()
            world.add_rigid_body(box)
            try:
                image = snapshot(world, camera)
            except SimulationError as exc:  # no OpenGL library on this machine
                pytest.skip(str(exc))
        assert image.shape == (120, 160, 3) and image.dtype == np.uint8
        r, g, b = (image[:, :, k].astype(float) for k in range(3))
        red[engine] = (r > 50) & (r > 2 * g) & (r > 2 * b)  # lit or shaded faces of the box
    # The red box covers about the same pixels on both engines (same target, distance, angles).
    overlap = (red["pybullet"] & red["mujoco"]).sum() / max(red["pybullet"].sum(), 1)
    assert red["pybullet"].sum() > 200 and overlap > 0.9
