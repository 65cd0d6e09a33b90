"""Physics of the spring chain against closed forms, across scales and time steps."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest
from conftest import ihm_finger_dict

from somo_sweep.calibration.formulas import chain_tip_stiffness
from somo_sweep.errors import UnstableSimulation
from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import model_from_dict
from somo_sweep.sim.planner import plan_rigid_body
from somo_sweep.sim.settings import PyBulletSettings, WorldSettings
from somo_sweep.sim.worlds import open_world
from somo_sweep.statics.bench import BenchSettings, run_bench

K_GRASP = 0.2186  # N·m/rad, IHM finger grasp axis
SEGMENT_M = 0.010
TIP_SPHERE_M = 0.030  # diameter of the fingertip sphere


def _closed_form_tip_deflection_m(force_n: float) -> float:
    """Discrete chain: grasp joints at 0, 20, 40, 60, 80 mm, force and readout at the sphere's end."""
    x_force = 10 * SEGMENT_M + TIP_SPHERE_M
    return force_n / chain_tip_stiffness([K_GRASP] * 5, np.arange(0, 10, 2) * SEGMENT_M, x_force)


@pytest.mark.parametrize("force_n", [0.005, 0.02])
def test_tip_deflection_matches_discrete_chain_small_deflection(force_n: float) -> None:
    model = model_from_dict(ihm_finger_dict(motor_limit=0.0))
    result = run_bench(model, "tip_load", 0.0, force_n, BenchSettings(gravity_m_s2=0.0))
    expected_mm = 1e3 * _closed_form_tip_deflection_m(force_n)
    assert result.value == pytest.approx(expected_mm, rel=0.02)


def _settle_uniform_input(
    scale: float, time_step_s: float, duration_s: float = 2.0, u_n_m: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """Run the damped IHM finger (no gravity) under a uniform grasp input; joint angles and tip."""
    model = model_from_dict(ihm_finger_dict(motor_limit=0.0, damping=0.01, added_inertia=1e-5))
    with open_world(
        WorldSettings(
            time_step_s=time_step_s,
            gravity_m_s2=(0.0, 0.0, 0.0),
            engine_settings=PyBulletSettings(scale=scale),
        )
    ) as world:
        handle = world.add_model(model)
        handle.set_inputs([u_n_m, 0.0])
        world.step(round(duration_s / time_step_s))
        body = handle.bodies[0]
        return body.drive.positions_si(), world.tip_position(body)


def test_uniform_input_settles_every_grasp_joint_at_u_over_k() -> None:
    q, _ = _settle_uniform_input(20.0, 5e-4)
    u = 0.05
    np.testing.assert_allclose(q[0::2], u / K_GRASP, rtol=0.01)
    np.testing.assert_allclose(q[1::2], 0.0, atol=1e-6)  # passive side axis stays at its neutral


@pytest.mark.parametrize("scale", [1.0, 10.0])
def test_results_in_si_do_not_depend_on_world_scale(scale: float) -> None:
    q_ref, tip_ref = _settle_uniform_input(20.0, 5e-4, duration_s=0.3)
    q, tip = _settle_uniform_input(scale, 5e-4, duration_s=0.3)
    # mid-motion (not settled): the whole trajectory, not just the equilibrium, is scale-free
    np.testing.assert_allclose(tip, tip_ref, rtol=0.01, atol=1e-4)
    np.testing.assert_allclose(q, q_ref, rtol=0.01, atol=1e-4)


@pytest.mark.parametrize("scale", [1.0, 10.0, 20.0])
def test_bench_statics_do_not_depend_on_world_scale(scale: float) -> None:
    model = model_from_dict(ihm_finger_dict(motor_limit=0.0))
    ref = run_bench(model, "blocked_force", 100.0).value
    got = run_bench(model, "blocked_force", 100.0, settings=BenchSettings(scale=scale)).value
    assert got == pytest.approx(ref, rel=0.01)


def test_time_step_convergence_of_a_step_response() -> None:
    """Tip position 0.25 s into a step response converges at first order in the time step."""
    tips = {dt: _settle_uniform_input(20.0, dt, duration_s=0.25)[1] for dt in (2.5e-4, 5e-4, 1e-3)}
    e_fine = np.linalg.norm(tips[5e-4] - tips[2.5e-4])
    e_coarse = np.linalg.norm(tips[1e-3] - tips[5e-4])
    assert e_coarse < 2e-4  # under 0.2 mm on a 130 mm finger at 1 ms
    assert 1.5 < e_coarse / e_fine < 2.5  # halving the step halves the error: first order


def test_each_torque_is_applied_exactly_once_per_step() -> None:
    """A free joint (k = 0, no gravity, no damping) under input u gains u·dt/I of speed per step.

    PyBullet adds up every torque command given within a step; a second command
    would double the acceleration.
    """
    inertia = 2e-4  # kg·m² about the joint, from a heavy, well-defined rotor
    data = {
        "manipulator": {
            "name": "rotor",
            "actuators": [
                {
                    "length_m": 0.02,
                    "n_segments": 1,
                    "joint_placement": "start",  # one body of the given inertia on the joint
                    "link": {
                        "shape": "cylinder",
                        "radius_m": 0.01,
                        "mass_kg": 0.1,
                        "inertia_kg_m2": [1e-4, 1e-4, inertia],
                    },
                    "joints": [{"axis": [0, 0, 1], "stiffness_n_m_per_rad": 0.0, "motor_limit_n_m": 0.0}],
                }
            ],
        }
    }
    dt, u, steps = 1e-3, 0.01, 50
    with open_world(
        WorldSettings(time_step_s=dt, gravity_m_s2=(0, 0, 0), engine_settings=PyBulletSettings(scale=20.0))
    ) as world:
        handle = world.add_model(model_from_dict(data))
        handle.set_inputs([u])
        world.step(steps)
        drive = handle.bodies[0].drive
        drive.read()
        speed = drive.velocities_si()[0]
        assert drive.steps_applied == steps
    assert speed == pytest.approx(u * dt * steps / inertia, rel=1e-3)


def test_blow_up_is_detected_not_reported() -> None:
    """A stiff, undamped chain at a large step hits Bullet's speed cap: flagged as unstable."""
    model = model_from_dict(ihm_finger_dict(motor_limit=0.0))
    with open_world(WorldSettings(time_step_s=4e-3)) as world, pytest.raises(UnstableSimulation) as err:
        handle = world.add_model(model)
        handle.set_inputs([0.1, 0.0])
        world.step(2000)
    assert err.value.reason in ("speed_cap", "nan")


@pytest.mark.parametrize(("speed_m_s", "reason"), [(4.0, "thrown"), (50.0, "speed_cap")])
def test_thrown_or_capped_body_is_detected(speed_m_s: float, reason: str) -> None:
    box = RigidBody(name="b", link=Link(shape="box", size_m=(0.01, 0.01, 0.01), mass_kg=0.01))
    with open_world(WorldSettings(time_step_s=1e-3, gravity_m_s2=(0, 0, 0))) as world:
        body = world.load_plan(plan_rigid_body(box), Pose())
        p.resetBaseVelocity(body.id, [speed_m_s * world.scale, 0, 0], physicsClientId=world.client)
        with pytest.raises(UnstableSimulation) as err:
            world.step(4000)
        assert err.value.reason == reason


def _rotor(stiffness: float, motor_limit: float, inertia: float) -> dict[str, object]:
    """One revolute joint carrying a cylinder of the given inertia about it."""
    return {
        "manipulator": {
            "name": "rotor",
            "actuators": [
                {
                    "length_m": 0.02,
                    "n_segments": 1,
                    "joint_placement": "start",
                    "link": {
                        "shape": "cylinder",
                        "radius_m": 0.01,
                        "mass_kg": 0.1,
                        "inertia_kg_m2": [1e-4, 1e-4, inertia],
                    },
                    "joints": [
                        {
                            "axis": [0, 0, 1],
                            "stiffness_n_m_per_rad": stiffness,
                            "motor_limit_n_m": motor_limit,
                        }
                    ],
                }
            ],
        }
    }


@pytest.mark.parametrize("every", [1, 2])
@pytest.mark.parametrize("time_step_s", [1e-3, 4e-3])
def test_coulomb_joint_friction_decays_an_oscillation_by_two_f_over_k_per_swing(
    every: int, time_step_s: float
) -> None:
    """Spring k, Coulomb friction F, input u stepped on at rest: the swings about u/k shrink by
    2F/k each (the classical Coulomb-damped oscillator), so the turning points are
    u/k ± (1 − 0.2), ∓ (1 − 0.4), ± (1 − 0.6) rad for u/k = 1 rad and 2F/k = 0.2 rad, and the
    joint comes to rest within F/k of u/k. Friction solved every step and every other step
    (the kept torque on the step between) must both give it: a kept torque of the wrong sign
    would pump the swing up, none at all would halve the decay."""
    k, f, inertia, u = 0.05, 0.005, 2e-4, 0.05
    settings = WorldSettings(
        time_step_s=time_step_s,
        gravity_m_s2=(0, 0, 0),
        engine_settings=PyBulletSettings(friction_rows_every=every),
    )
    with open_world(settings) as world:
        handle = world.add_model(model_from_dict(_rotor(k, f, inertia)))
        handle.set_inputs([u])
        drive = handle.bodies[0].drive
        angles = []
        for _ in range(round(2.0 / time_step_s)):
            world.step()
            drive.read()
            angles.append(drive.positions_si()[0])
    q = np.array(angles)
    turning = [q[i] for i in range(1, len(q) - 1) if (q[i] - q[i - 1]) * (q[i + 1] - q[i]) < 0]
    np.testing.assert_allclose(turning[:3], [1.8, 0.4, 1.4], atol=2e-3)
    assert abs(q[-1] - u / k) <= f / k
    assert np.ptp(q[-50:]) < 1e-6  # at rest: stuck by static friction, not creeping


@pytest.mark.parametrize("every", [1, 2])
def test_a_load_below_the_friction_limit_never_moves_the_joint(every: int) -> None:
    """Static friction holds a free joint (k = 0) under a torque below its limit, without creep,
    and lets it slide at (u − F)/I above it."""
    f, inertia, dt, steps = 0.005, 2e-4, 1e-3, 200
    for u, expected in ((0.004, 0.0), (0.008, 0.5 * (0.008 - f) / inertia * (dt * steps) ** 2)):
        settings = WorldSettings(
            time_step_s=dt,
            gravity_m_s2=(0, 0, 0),
            engine_settings=PyBulletSettings(friction_rows_every=every),
        )
        with open_world(settings) as world:
            handle = world.add_model(model_from_dict(_rotor(0.0, f, inertia)))
            handle.set_inputs([u])
            world.step(steps)
            drive = handle.bodies[0].drive
            drive.read()
            angle = drive.positions_si()[0]
        # explicit Euler's first-order lag: ½·a·dt·T on top of ½·a·T², 0.5 % here
        assert angle == pytest.approx(expected, rel=6e-3, abs=1e-9)


@pytest.mark.parametrize("every", [0, 3])
def test_friction_solved_other_than_every_step_or_every_other_is_refused(every: int) -> None:
    with pytest.raises(ValueError, match="friction_rows_every must be 1 or 2"):
        WorldSettings(engine_settings=PyBulletSettings(friction_rows_every=every))
