"""The automatic step and shaping: the stability criterion against measured blow-ups, and the choice."""

from __future__ import annotations

import pytest

from somo_sweep.model.load import Model, load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.modes import chain_matrices, shaped
from somo_sweep.sim.numerics import (
    MAX_MODE_SHIFT,
    MAX_STEP_S,
    SAFETY,
    choose_numerics,
    stability_limit_s,
    tidy_floor,
)
from somo_sweep.sim.stability import is_stable

FINGER = bundled_path("models", "pinch_finger.yaml")


def _frictionless(model: Model, stiffness_factor: float = 1.0) -> Model:
    """The finger with its Coulomb motors off (the linear, undamped chain of the criterion)."""
    assert model.manipulator is not None
    acts = [
        a.model_copy(
            update={
                "joints": [
                    j.model_copy(
                        update={
                            "motor_limit_n_m": 0.0,
                            "stiffness_n_m_per_rad": j.stiffness * stiffness_factor,
                        }
                    )
                    for j in a.joints
                ]
            }
        )
        for a in model.manipulator.actuators
    ]
    return Model(manipulator=model.manipulator.model_copy(update={"actuators": acts}))


@pytest.mark.parametrize(("stiffness_factor", "added_kg_m2"), [(1.0, 2e-7), (10.0, 3e-5)])
def test_predicted_limit_brackets_the_measured_blow_up(stiffness_factor: float, added_kg_m2: float) -> None:
    """2/ω_max: stable 5 % below, blown up 5 % above (motors off; measured within 1 %)."""
    model = _frictionless(load_model(FINGER), stiffness_factor)
    assert model.manipulator is not None
    model = Model(manipulator=shaped(model.manipulator, added_kg_m2))
    assert model.manipulator is not None
    limit = stability_limit_s(chain_matrices(model.manipulator).frequencies_rad_s()[-1])
    assert is_stable(model, 0.95 * limit)
    assert not is_stable(model, 1.05 * limit)


def test_the_chosen_step_runs_stably_with_the_motors_off() -> None:
    model = _frictionless(load_model(FINGER))
    chosen = choose_numerics(model)
    assert is_stable(chosen.apply(model), chosen.time_step_s)


def test_bundled_gripper_choice_keeps_the_lowest_modes_within_one_percent() -> None:
    chosen = choose_numerics(load_model(bundled_path("models", "pinch_gripper.yaml")))
    assert set(chosen.chains) == {"left", "right"}
    for c in chosen.chains.values():
        assert c.kept_modes == 2
        assert 0 < c.lowest_shift <= MAX_MODE_SHIFT
        assert c.after.highest_rad_s < 0.75 * c.before.highest_rad_s
        assert chosen.time_step_s <= SAFETY * stability_limit_s(c.after.highest_rad_s)
    # Unshaped, 0.8·2/ω_max = 0.35 ms; shaped: 0.5 ms (tidy, below 0.8·0.625 ms).
    assert chosen.time_step_s == pytest.approx(5e-4)
    assert "stability" in chosen.reason


def test_a_soft_heavy_chain_is_capped_at_the_largest_validated_step() -> None:
    snake = load_model(bundled_path("models", "snake.yaml"))
    chosen = choose_numerics(snake, max_step_s=MAX_STEP_S)
    assert chosen.time_step_s == MAX_STEP_S
    assert "largest validated step" in chosen.reason


def test_shaping_is_cut_back_to_what_the_step_needs() -> None:
    snake = load_model(bundled_path("models", "snake.yaml"))
    lax = choose_numerics(snake, max_step_s=1e-3)
    assert lax.time_step_s == 1e-3
    (c,) = lax.chains.values()
    assert c.added_inertia_kg_m2 == 0.0  # 2.1 ms stable unshaped: nothing to add


def test_apply_adds_the_shaping_to_every_segment_link() -> None:
    gripper = load_model(bundled_path("models", "pinch_gripper.yaml"))
    chosen = choose_numerics(gripper)
    assert gripper.assembly is not None
    out = chosen.apply(gripper).assembly
    assert out is not None
    for mount in out.manipulators:
        j = chosen.chains[mount.name].added_inertia_kg_m2
        assert [a.link.added_inertia_kg_m2 for a in mount.manipulator.actuators] == [j, j]


@pytest.mark.parametrize(("value", "tidy"), [(7.3e-4, 6e-4), (6.25e-4, 6e-4), (1e-3, 1e-3), (2.49e-3, 2e-3)])
def test_tidy_floor_rounds_down(value: float, tidy: float) -> None:
    assert tidy_floor(value) == pytest.approx(tidy)


def _with_stiffness(model: Model, axis: int | None, stiffness: float) -> Model:
    """``model`` with joint ``axis`` (every axis when None) of every segment at ``stiffness``."""
    assert model.manipulator is not None
    acts = [
        a.model_copy(
            update={
                "joints": [
                    j.model_copy(update={"stiffness_n_m_per_rad": stiffness}) if axis in (None, i) else j
                    for i, j in enumerate(a.joints)
                ]
            }
        )
        for a in model.manipulator.actuators
    ]
    return Model(manipulator=model.manipulator.model_copy(update={"actuators": acts}))


@pytest.mark.parametrize("stiffness", [0.0, 1e-300])
def test_a_free_hinge_sets_no_limit_and_the_springs_still_decide(stiffness: float) -> None:
    """A joint without a spring has a zero-frequency mode: it was a division by zero."""
    # The finger's joint friction stays: a frictionless chain of 20 free hinges under gravity is a
    # whip whose tip reaches Bullet's speed cap at t = 0.092 s at any step from 0.4 ms to 25 µs
    # (measured): physics, not numerics.
    free = _with_stiffness(load_model(FINGER), 0, stiffness)
    assert free.manipulator is not None
    w = chain_matrices(free.manipulator).frequencies_rad_s()
    assert w[0] < 1e-6 * w[-1]  # the free hinges' modes
    chosen = choose_numerics(free)
    assert "stability" in chosen.reason  # the remaining springs decide
    assert tidy_floor(SAFETY * stability_limit_s(w[-1])) <= chosen.time_step_s <= MAX_STEP_S
    # No step effort: on a free hinge it would spin the links up to Bullet's speed cap for real.
    # Gravity swings the free hinges through large angles and excites the springs' modes.
    assert is_stable(chosen.apply(free), chosen.time_step_s, duration_s=1.0, input_n_m=0.0)


def test_a_chain_without_any_spring_gets_the_largest_validated_step() -> None:
    free = _with_stiffness(load_model(FINGER), None, 0.0)
    chosen = choose_numerics(free)
    assert chosen.time_step_s == MAX_STEP_S and "no spring" in chosen.reason
