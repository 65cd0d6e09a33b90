"""What of a description the mujoco engine cannot express, found without importing MuJoCo.

A study on ``engine: mujoco`` is checked with :func:`unsupported` when it is loaded, so a field
MuJoCo cannot express is refused before any trial runs, by its key path. The world checks the
links it loads the same way (:func:`somo_sweep.sim.mujoco.scene.unsupported_link`), for bodies a
task adds itself.

* ``friction.anisotropic``: MuJoCo's contact friction directions follow the contact normal (two
  tangents it picks), not the link's own axes, so friction scaled along a link's axes (a snake's
  scales) has no equivalent.
* ``friction.anchor``: MuJoCo solves friction afresh each step from the contact's velocity; it
  keeps no point a contact first touched to pull back to, so Bullet's friction anchor has no
  equivalent.
* ``restitution`` > 0: MuJoCo's contacts are soft, critically damped springs without a
  restitution coefficient.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterator

from somo_sweep.model.description import Link, Manipulator
from somo_sweep.model.load import Model

__all__ = ["ANCHOR_WHY", "ENGINE", "INSTALL", "WARP_INSTALL", "missing", "unsupported", "warp_missing"]

ENGINE = "mujoco"
#: How a user gets the engine.
INSTALL = 'pip install "somo-sweep[mujoco]"'
#: How a user gets the mujoco_warp engine.
WARP_INSTALL = 'pip install "somo-sweep[warp]"'
#: Why ``friction.anchor: true`` is refused (after the value, in every message that names it).
ANCHOR_WHY = (
    f"cannot be expressed on engine {ENGINE} (it solves friction afresh each step from the contact "
    "velocity, with no anchor point to pull back to); allowed: false, or engine pybullet"
)


def missing() -> str | None:
    """Why the mujoco engine cannot run in this Python (MuJoCo not installed), or None if it can."""
    if importlib.util.find_spec("mujoco") is not None:
        return None
    return (
        f"engine {ENGINE} needs MuJoCo, which is not installed in this Python; install the optional "
        f"extra ({INSTALL}), or use engine: pybullet"
    )


def warp_missing() -> str | None:
    """Why the mujoco_warp engine cannot run in this Python (MuJoCo Warp or MuJoCo not
    installed), or None if it can."""
    absent = [name for name in ("mujoco", "mujoco_warp", "warp") if importlib.util.find_spec(name) is None]
    if not absent:
        return None
    return (
        f"engine mujoco_warp needs MuJoCo Warp, which is not installed in this Python (missing: "
        f"{', '.join(absent)}); install the optional extra ({WARP_INSTALL}), or use engine: mujoco"
    )


def _manipulator_links(manip: Manipulator, prefix: str) -> Iterator[tuple[str, Link]]:
    if manip.base.link is not None:
        yield f"{prefix}.base.link", manip.base.link
    for i, act in enumerate(manip.actuators):
        yield f"{prefix}.actuators[{i}].link", act.link
    for i, tip in enumerate(manip.tip_links):
        yield f"{prefix}.tip_links[{i}]", tip


def _links(model: Model) -> Iterator[tuple[str, Link]]:
    if model.manipulator is not None:
        yield from _manipulator_links(model.manipulator, "manipulator")
        return
    assembly = model.as_assembly()
    if assembly.base.link is not None:
        yield "assembly.base.link", assembly.base.link
    for i, mount in enumerate(assembly.manipulators):
        yield from _manipulator_links(mount.manipulator, f"assembly.manipulators[{i}].manipulator")
    for i, body in enumerate(assembly.bodies):
        yield f"assembly.bodies[{i}].link", body.link


def unsupported(model: Model) -> list[tuple[str, str]]:
    """Every field of ``model`` the mujoco engine cannot express: (key path, why and what is allowed)."""
    out = []
    for path, link in _links(model):
        if link.friction.anisotropic is not None:
            out.append(
                (
                    f"{path}.friction.anisotropic",
                    f"{list(link.friction.anisotropic)} cannot be expressed on engine {ENGINE} (its contact "
                    "friction directions follow the contact normal, not the link's axes); allowed: null, or "
                    "engine pybullet",
                )
            )
        if link.friction.anchor:
            out.append((f"{path}.friction.anchor", f"true {ANCHOR_WHY}"))
        if link.restitution > 0:
            out.append(
                (
                    f"{path}.restitution",
                    f"{link.restitution:g} cannot be expressed on engine {ENGINE} (its soft contacts are "
                    "critically damped, without a restitution coefficient); allowed: 0, or engine pybullet",
                )
            )
    return out
