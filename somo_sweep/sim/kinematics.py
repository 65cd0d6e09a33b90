"""A chain's kinematics on an engine: its fixed structure and one forward-kinematics call, in SI.

:class:`ChainKinematics` is the interface each engine implements: PyBullet's
(:class:`~somo_sweep.sim.pybullet.kinematics.PyBulletChainKinematics`: joint states set with
``resetJointStatesMultiDof``, every link frame read back with one ``getLinkStates`` call) and
MuJoCo's (:class:`~somo_sweep.sim.mujoco.kinematics.MujocoChainKinematics`: ``qpos`` set, one
``mj_kinematics``), each on a body loaded from a plan in a world of its own (gravity off; the
world never steps). :func:`somo_sweep.sim.worlds.open_chain_kinematics` opens the one an engine
name names. The bench statics (:mod:`somo_sweep.statics`) build their forces, Jacobians and
plate contacts on it. This module imports no engine.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from somo_sweep.sim.world import Body, World

__all__ = ["ChainKinematics", "Kin"]


@dataclass
class Kin:
    """One forward-kinematics evaluation, SI, world frame."""

    com: np.ndarray  # (L, 3) link centres of mass
    frame: np.ndarray  # (L, 3) link (joint) frame origins
    rot: np.ndarray  # (L, 3, 3) link frame orientations
    omega: np.ndarray  # (N, 3) revolute joint axes (0 for prismatic)
    vel: np.ndarray  # (N, 3) prismatic joint axes (0 for revolute)
    origin: np.ndarray  # (N, 3) joint origins


class ChainKinematics(ABC):
    """One loaded body, its fixed kinematic structure and its forward kinematics.

    Each engine's subclass loads the body in a world of its own, sets the structural arrays
    below (:meth:`_set_tree` the two that follow from the links' parents) and implements
    :meth:`kinematics`.

    Attributes:
        world: The world holding the body.
        body: The loaded body.
        scale: The engine's length scale (PyBullet's Y; 1 for MuJoCo).
        n_links: Links besides the base (link indices 0 … n_links − 1).
        indices: Link (= joint) index of each spring joint.
        mass: Mass of each link, kg.
        subtree: (joints, links) 1 where the link moves with the joint.
        joint_below: (joints, joints) 1 where joint j is i or below it.
        revolute: Per spring joint, revolute (else prismatic); ``all_revolute``.
        zero_axes: (joints, 3) zeros (the axes of the other kind when all joints are of one).
        axis_local: (joints, 3) each spring joint's axis in its link's frame.
        pos_scale: Per spring joint, the engine's position unit per SI unit (rad: 1; m: the scale).
        limited, limits: Spring joints with limits, and the (lower, upper) limits in SI.
        base_rot: Rotation of the base frame.
    """

    world: World
    body: Body
    scale: float
    n_links: int
    indices: list[int]
    mass: np.ndarray
    subtree: np.ndarray
    joint_below: np.ndarray
    revolute: np.ndarray
    all_revolute: bool
    zero_axes: np.ndarray
    axis_local: np.ndarray
    pos_scale: np.ndarray
    limited: np.ndarray
    limits: tuple[np.ndarray, np.ndarray]
    base_rot: np.ndarray

    def _set_tree(self, parent: np.ndarray) -> None:
        """``subtree`` and ``joint_below`` from each link's parent link (−1: the base)."""
        n = len(parent)
        # subtree[j, l]: link l moves with joint j (l is j's child link or below it).
        sub = np.zeros((n, n), bool)
        for link in range(n):
            a = link
            while a >= 0:
                sub[a, link] = True
                a = parent[a]
        idx = np.array(self.indices, int)
        self.subtree = sub[idx].astype(float)  # (N joints, L links)
        self.joint_below = sub[np.ix_(idx, idx)].astype(float)  # (N, N): joint j is i or below it

    @property
    def is_open(self) -> bool:
        """Whether the body's world is still open (a closed one is loaded again)."""
        return self.world.is_open

    def close(self) -> None:
        """Close the body's world."""
        self.world.close()

    @abstractmethod
    def kinematics(self, q: np.ndarray) -> Kin:
        """Set the joints to ``q`` (SI) and read every link frame back (SI, world frame)."""
