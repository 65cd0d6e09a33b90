"""A finger's stiffness profile, gradient and taper survive the pinch task's re-split by DSR.

The task re-splits each finger into a driven proximal and a passive distal actuator at the DSR's
link boundary. The gradient and taper are measured from an actuator's start and over its length,
so they must be baked per joint, not left to be re-applied over the new actuators (which moved
them), nor dropped (a calibrated or diagnosed finger lost its taper in every grasp).
"""

from __future__ import annotations

import pytest
from conftest import MODELS

from somo_sweep.model.load import Model, load_model
from somo_sweep.tasks.pinch_grasp.gripper import gripper
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams


def _tapered(model: Model, **fields: object) -> Model:
    """The bundled gripper with every finger actuator's stiffness modifiers set to ``fields``."""
    assembly = model.as_assembly()
    fingers = []
    for m in assembly.manipulators:
        acts = [a.model_copy(update=fields) for a in m.manipulator.actuators]
        fingers.append(
            m.model_copy(update={"manipulator": m.manipulator.model_copy(update={"actuators": acts})})
        )
    return model.model_copy(update={"assembly": assembly.model_copy(update={"manipulators": fingers})})


def _factors(model: Model) -> list[float]:
    """Every finger's joint stiffness factors, finger by finger, link by link from its base."""
    return [
        a.stiffness_factor(i)
        for m in model.as_assembly().manipulators
        for a in m.manipulator.actuators
        for i in range(a.segments)
    ]


@pytest.mark.parametrize("dsr", [0.0, 0.05, 0.25, 0.5])
@pytest.mark.parametrize(
    "fields",
    [
        {"stiffness_tip_ratio": 3.0},
        {"stiffness_tip_ratio": 0.4, "stiffness_taper_shape": 0.0},
        {"stiffness_gradient_per_m": 8.0},
    ],
    ids=["taper", "exponential taper", "gradient"],
)
def test_every_joint_keeps_its_stiffness_factor_whatever_the_split(dsr: float, fields: dict) -> None:
    written = _tapered(load_model(MODELS / "pinch_gripper.yaml"), **fields)
    split = gripper(written, PinchGraspParams(distal_segment_ratio=dsr))
    assert _factors(split) == pytest.approx(_factors(written), rel=1e-12)
    assert any(f != pytest.approx(1.0) for f in _factors(split))  # the modifiers did something


def test_a_profile_is_kept_when_the_fingers_are_simulated_as_written() -> None:
    model = load_model(MODELS / "pinch_gripper.yaml")
    n = model.as_assembly().manipulators[0].manipulator.actuators[0].segments
    profiled = _tapered(model, stiffness_profile=[1.0 + 0.1 * i for i in range(n)])
    kept = gripper(profiled, PinchGraspParams(distal_segment_ratio=None))
    assert _factors(kept) == pytest.approx(_factors(profiled), rel=1e-12)


def test_a_finger_without_modifiers_gets_no_profile() -> None:
    """The bundled finger's split actuators are as before: no profile, no gradient, no taper."""
    split = gripper(load_model(MODELS / "pinch_gripper.yaml"), PinchGraspParams(distal_segment_ratio=0.2))
    for m in split.as_assembly().manipulators:
        for a in m.manipulator.actuators:
            assert a.stiffness_profile is None and a.stiffness_gradient_per_m == 0.0
            assert a.stiffness_tip_ratio == 1.0
