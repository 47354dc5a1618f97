"""The robot: the KUKA + SDH-like hand URDF model (``model``), batched forward kinematics
and Jacobians (``kinematics``), IK and the elbow's self-motion (``ik``), a grasp given as a
palm pose and its IK (``palm_pose``), planar arms (``planar``) and end-effector noise
statistics (``endeffector``); robots as data: a YAML description beside a URDF
(``description``), the robot catalog (``catalog``) and its pictures (``picture``). Uses
``sampling``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "RobotModel": "model",
    "kuka_sdh": "model",
    "load_urdf": "model",
    "urdf_path": "model",
    "Kinematics": "kinematics",
    "elbow_angle": "kinematics",
    "ArmIK": "ik",
    "IKResult": "ik",
    "PalmCandidate": "palm_pose",
    "parse_palm_pose": "palm_pose",
    "reach_palm_pose": "palm_pose",
    "PlanarArm": "planar",
    "sample_kuka_end_effector": "endeffector",
    "kuka_end_effector": "endeffector",
    "RobotDescription": "description",
    "RobotDescriptionError": "description",
    "load_description": "description",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
