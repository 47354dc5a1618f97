"""The robot: URDF models (``model``), the default robot's names and model read from its
description (``default_robot``), batched forward kinematics
and Jacobians (``kinematics``), IK and the elbow's self-motion (``ik``), a grasp given as a
palm pose (``palm_pose``) and every robot's IK of one (``palm_ik``), planar arms (``planar``)
and end-effector noise statistics (``endeffector``); robots as data: a YAML description
beside a URDF (``description``; its fields' checks in ``description_fields``), the robot
catalog (``catalog``) and its pictures (``picture``). Uses ``sampling``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "model": ("RobotModel", "load_urdf"),
    "default_robot": ("kuka_sdh", "urdf_path"),
    "kinematics": ("Kinematics", "elbow_angle"),
    "ik": ("ArmIK", "IKResult"),
    "palm_pose": ("PalmCandidate", "parse_palm_pose"),
    "palm_ik": ("reach_robot_palm_pose", "solve_palm_ik"),
    "planar": ("PlanarArm",),
    "endeffector": ("ArmEndEffector",),
    "description": ("RobotDescription", "RobotDescriptionError", "load_description"),
})
