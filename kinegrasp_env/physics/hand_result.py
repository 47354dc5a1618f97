"""What the default robot's physics closing (:mod:`~kinegrasp_env.physics.pybullet_closing`,
MuJoCo's in :mod:`~kinegrasp_env.physics.mujoco_hold`) returns: its contacts by finger and
phalanx (:class:`Contact`) and its outcome (:class:`CloseResult`), which every robot's engine
scores as the description's closing (:meth:`CloseResult.robot_result`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult, RobotContact
from kinegrasp_env.robot.default_robot import HAND_JOINTS


@dataclass(frozen=True)
class Contact:
    """One finger-object contact (object frame).

    Attributes:
        finger: 0, 1, 2 (fingers f1, f2, f3).
        link: 0 proximal, 1 distal.
        point: (3,) on the object's surface, metres.
        normal: (3,) inward unit surface normal.
    """

    finger: int
    link: int
    point: np.ndarray
    normal: np.ndarray


@dataclass
class CloseResult:
    """Outcome of one auto-close.

    Attributes:
        start_collision: the hand penetrated the object before closing.
        contacts: contacts found (at most one per link).
        missed: per finger, True if it closed to its limits without touching.
        joints: final hand DOF (7,) in ``HAND_JOINTS`` order.
        iterations: collision queries used.
    """

    start_collision: bool
    contacts: list[Contact] = field(default_factory=list)
    missed: tuple[bool, bool, bool] = (False, False, False)
    joints: np.ndarray | None = None
    iterations: int = 0

    def robot_result(self) -> RobotCloseResult:
        """The same closing as a closing of the default robot's description (what every
        robot's engine scores: :func:`~kinegrasp_env.montecarlo.description_engine.score_batch`):
        the contacts in their order (each finger's links as the description lists them,
        proximal then distal), the final hand joints by name."""
        fingers = len(self.missed)
        joints = {} if self.joints is None else dict(zip(HAND_JOINTS, self.joints.tolist(),
                                                         strict=True))
        return RobotCloseResult(
            self.start_collision,
            [RobotContact(c.finger, c.link, c.point, c.normal, 0.0) for c in self.contacts],
            tuple(self.missed), np.full(fingers, np.nan), np.zeros(fingers), joints,
            self.iterations)
