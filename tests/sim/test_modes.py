"""The modal estimate against closed forms, and the bundled pinch finger against the facts sheet."""

from __future__ import annotations

import math

import numpy as np
import pytest

from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model, load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.modes import chain_matrices, model_chains

K_N_M_PER_RAD = 0.5
MASS_KG = 0.01
LINK_M = 0.01
WIDTH_M = 0.02


def _chain(n: int, added_kg_m2: float = 0.0) -> Manipulator:
    """``n`` box links of 10 mm on grasp-axis springs, a joint at each link's start, clamped."""
    return Manipulator.model_validate(
        {
            "name": "chain",
            "actuators": [
                {
                    "length_m": n * LINK_M,
                    "n_segments": n,
                    "joint_placement": "start",
                    "link": {
                        "shape": "box",
                        "size_m": [WIDTH_M, WIDTH_M],
                        "mass_kg": MASS_KG,
                        "added_inertia_kg_m2": added_kg_m2,
                    },
                    "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": K_N_M_PER_RAD}],
                }
            ],
        }
    )


def _i_cm() -> float:
    return MASS_KG / 12 * (WIDTH_M**2 + LINK_M**2)  # box about its x axis


def test_one_link_on_a_spring_is_sqrt_k_over_pivot_inertia() -> None:
    i_pivot = _i_cm() + MASS_KG * (LINK_M / 2) ** 2
    w = chain_matrices(_chain(1)).frequencies_rad_s()
    assert w == pytest.approx([math.sqrt(K_N_M_PER_RAD / i_pivot)], rel=1e-9)


def test_added_inertia_adds_to_the_pivot_inertia() -> None:
    j = 3e-6
    i_pivot = _i_cm() + MASS_KG * (LINK_M / 2) ** 2 + j
    assert chain_matrices(_chain(1)).frequencies_rad_s(j) == pytest.approx(
        [math.sqrt(K_N_M_PER_RAD / i_pivot)], rel=1e-9
    )
    # ... and M is linear in J: the shaped file gives the same frequencies.
    assert chain_matrices(_chain(1, j)).frequencies_rad_s() == pytest.approx(
        chain_matrices(_chain(1)).frequencies_rad_s(j), rel=1e-9
    )


def test_two_link_chain_matches_the_hand_derived_mass_matrix() -> None:
    i, m, d, c = _i_cm(), MASS_KG, LINK_M, LINK_M / 2  # d: joint spacing, c: joint to centre of mass
    mass = np.array(
        [
            [i + m * c**2 + i + m * (d + c) ** 2, i + m * c * (d + c)],
            [i + m * c * (d + c), i + m * c**2],
        ]
    )
    chain = chain_matrices(_chain(2))
    assert chain.mass == pytest.approx(mass, rel=1e-9)
    w2 = np.linalg.eigvals(np.linalg.solve(mass, K_N_M_PER_RAD * np.eye(2)))
    assert chain.frequencies_rad_s() == pytest.approx(np.sqrt(np.sort(w2.real)), rel=1e-9)


def test_bundled_pinch_finger_against_the_facts_sheet() -> None:
    """Facts sheet: ~7,200 rad/s highest, ~21 rad/s lowest (their finger, doubled springs).

    Ours (the YAML stiffness, half the original's effective one; SoMo's joint layout; 1.5-g
    distal links): 4,573 and 28.6 rad/s. The highest mode scales as √k: √2·4,573 = 6,467,
    within 11 % of 7,200; the lowest does not match (√2·28.6 = 40 rad/s vs 21).
    """
    finger = load_model(bundled_path("models", "pinch_finger.yaml"))
    ((manip, floating),) = model_chains(finger)
    w = chain_matrices(manip, floating).frequencies_rad_s()
    assert len(w) == 20
    assert w[-1] == pytest.approx(4573, rel=0.01)
    assert w[0] == pytest.approx(28.56, rel=0.01)
    assert math.sqrt(2) * w[-1] == pytest.approx(7200, rel=0.12)


def test_a_free_chain_drops_its_six_rigid_body_modes() -> None:
    snake = load_model(bundled_path("models", "snake.yaml"))
    ((manip, floating),) = model_chains(snake)
    chain = chain_matrices(manip, floating)
    assert floating and chain.rigid_modes == 6
    w = chain.frequencies_rad_s()
    assert len(w) == len(chain.joints) and w[0] > 0.5


def test_every_mount_of_an_assembly_is_a_chain() -> None:
    gripper = load_model(bundled_path("models", "pinch_gripper.yaml"))
    assert [m.name for m, _ in model_chains(gripper)] == ["left", "right"]
    assert isinstance(gripper, Model)


def _without_anisotropy(manip: Manipulator) -> Manipulator:
    """The snake as MuJoCo can express it: its scales' anisotropic friction dropped (no mass change)."""
    acts = []
    for act in manip.actuators:
        friction = act.link.friction.model_copy(update={"anisotropic": None})
        acts.append(act.model_copy(update={"link": act.link.model_copy(update={"friction": friction})}))
    return manip.model_copy(update={"actuators": acts})


def test_both_engines_give_the_bundled_finger_one_mass_matrix() -> None:
    """PyBullet's ``calculateMassMatrix`` and MuJoCo's ``mj_fullM`` of one SI plan agree to 1e-9 of
    the largest entry (measured: 2e-12; PyBullet reads the plan's ten-digit URDF), so a study's
    modes are the same whichever engine it runs on."""
    pytest.importorskip("mujoco")
    finger = load_model(bundled_path("models", "pinch_finger.yaml"))
    ((manip, floating),) = model_chains(finger)
    bullet, mujoco = chain_matrices(manip, floating, "pybullet"), chain_matrices(manip, floating, "mujoco")
    assert bullet.joints == mujoco.joints and mujoco.mass.shape == (20, 20)
    assert np.abs(bullet.mass - mujoco.mass).max() < 1e-9 * np.abs(bullet.mass).max()
    assert mujoco.frequencies_rad_s() == pytest.approx(bullet.frequencies_rad_s(), rel=1e-8)


def test_mujoco_modes_leave_inertia_shaping_out_as_its_scenes_do() -> None:
    """The IHM finger carries 2e-6 kg·m² of shaping: PyBullet's matrix holds it, MuJoCo's does not
    (its implicit springs need none), so MuJoCo's equals PyBullet's with the shaping taken out."""
    pytest.importorskip("mujoco")
    finger = load_model(bundled_path("models", "ihm_finger.yaml"))
    ((manip, floating),) = model_chains(finger)
    added = manip.actuators[0].link.added_inertia_kg_m2
    assert added > 0
    bullet, mujoco = chain_matrices(manip, floating, "pybullet"), chain_matrices(manip, floating, "mujoco")
    unshaped = bullet.mass - added * bullet.inertia_gain
    assert np.abs(unshaped - mujoco.mass).max() < 1e-9 * np.abs(unshaped).max()
    assert np.abs(mujoco.inertia_gain).max() < 1e-9 * np.abs(bullet.inertia_gain).max()


def test_both_engines_give_a_free_chain_the_same_elastic_modes() -> None:
    """A floating base's six coordinates differ between the engines (PyBullet's base frame is its
    centre of mass); the spring joints' block and every elastic frequency do not."""
    pytest.importorskip("mujoco")
    snake = load_model(bundled_path("models", "snake.yaml"))
    ((manip, floating),) = model_chains(snake)
    manip = _without_anisotropy(manip)
    bullet, mujoco = chain_matrices(manip, floating, "pybullet"), chain_matrices(manip, floating, "mujoco")
    assert floating and bullet.mass.shape == mujoco.mass.shape == (6 + len(bullet.joints),) * 2
    block = np.abs(bullet.mass[6:, 6:] - mujoco.mass[6:, 6:]).max()
    assert block < 1e-9 * np.abs(bullet.mass[6:, 6:]).max()
    assert mujoco.frequencies_rad_s() == pytest.approx(bullet.frequencies_rad_s(), rel=1e-7)
