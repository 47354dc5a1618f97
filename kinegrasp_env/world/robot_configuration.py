"""A robot's configuration as a grasp file gives it: the robot's model by catalog name, its
check against the joint limits, the words that say what it holds, and the palm it puts where
(forward kinematics of the robot's URDF)."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.catalog import DEFAULT_ROBOT, load_robot
from kinegrasp_env.robot.model import RobotModel


def palm_at(q0: np.ndarray, robot: str = DEFAULT_ROBOT) -> np.ndarray:
    """(4, 4) the palm frame at configuration ``q0`` (14,) (another ``robot``: its actuated
    vector), world frame (forward kinematics of the robot's URDF): a grasp entry's
    ``palm_pose`` when the file leaves it out."""
    from kinegrasp_env.robot.kinematics import Kinematics

    description = load_robot(robot)
    return Kinematics(description.model).pose(np.asarray(q0, dtype=float)[None],
                                              description.palm_link)[0]


def joints_words(robot: str, count: bool = True) -> str:
    """What a configuration of ``robot`` holds, in words: e.g. "14 joint values: 7 arm, then 7
    hand" (without ``count``: "7 arm + 7 hand")."""
    description = load_robot(robot)
    arm, hand = description.arm_dof, len(description.hand_joints)
    if not count:
        return f"{arm} arm + {hand} hand"
    return f"{arm + hand} joint values, radians or metres: {arm} arm, then {hand} hand"


def robot_model(robot, where: str = "robot") -> RobotModel:
    """The model of catalog robot ``robot``; ValueError (one line, naming ``where``) for an
    unknown one."""
    if not isinstance(robot, str):
        raise ValueError(f"{where}: expected a robot name, got {robot!r}")
    try:
        return load_robot(robot).model
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def check_configuration(q0: np.ndarray, where: str = "q0",
                        robot: str = DEFAULT_ROBOT) -> np.ndarray:
    """Validate the actuated configuration q0 of ``robot`` (its arm joints, then its hand
    joints: finite, within the joint limits)."""
    q0 = np.asarray(q0, dtype=float)
    model = robot_model(robot)
    if q0.shape != (model.dof,):
        raise ValueError(f"{where}: q0 must have {model.dof} entries ("
                         f"{joints_words(robot, count=False)}), got {q0.size}")
    if not np.all(np.isfinite(q0)):
        raise ValueError(f"{where}: q0 has non-finite entries")
    bad = np.flatnonzero((q0 < model.lower - 1e-9) | (q0 > model.upper + 1e-9))
    if bad.size:
        j = int(bad[0])
        raise ValueError(f"{where}: q0[{j}] ({model.actuated[j]}) = {q0[j]:.4f} is outside "
                         f"its limits [{model.lower[j]:.4f}, {model.upper[j]:.4f}]")
    return q0
