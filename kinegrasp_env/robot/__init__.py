"""The robot: the KUKA + SDH-like hand URDF model (``model``), batched forward kinematics
and Jacobians (``kinematics``), IK and the elbow's self-motion (``ik``), a grasp given as a
palm pose and its IK (``palm_pose``), planar arms (``planar``) and end-effector noise
statistics (``endeffector``). Uses ``sampling``.
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
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
