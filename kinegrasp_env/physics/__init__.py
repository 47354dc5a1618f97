"""The simulated closing and holding protocols: the hand closed by finger motors under
dynamics, then the holding test of the closed grasp, in pybullet (and other simulators
registered in ``simulators``).

The protocol itself (phases, thresholds, the per-draw result) is simulator-independent
(``protocol``; its sequence: ``hold_runner``; the hand's lift and shake motion: ``motion``;
the grip's balanced forces: ``grip_forces``, ``balanced_grip``). Each simulator executes it
in modules of its own: pybullet's world (``pybullet_world``: a free hand held by a
constraint, the object as a rigid body that can be pinned), a robot's hand cut from its URDF
(``robot_world``), its contacts (``pybullet_contacts``), its closing motors (``jaw_motors``),
the holding test's primitives (``pybullet_hold``) and the holding test (``robot_hold``) and
its closing against the kinematic one (``robot_agreement``); MuJoCo's world
(``mujoco_model``, ``mujoco_world``), primitives (``mujoco_hold``) and holding test
(``mujoco_robot_hold``); the motors of a robot's hand in either simulator
(``hand_motors``). ``simulators`` names them and states the
interface a simulator implements. Uses ``closing`` (the kinematic closing's
contact rules and a description robot's closing result), ``world`` and ``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "pybullet_world": ("WorldSettings",),
    "robot_world": ("RobotPhysicsWorld",),
    "protocol": ("HoldProtocol", "HoldResult", "PHASES", "HOLD_OUTCOMES"),
    "simulators": ("SIMULATORS", "simulator_class"),
    "robot_hold": ("RobotHold",),
    "mujoco_robot_hold": ("MujocoRobotHold",),
    "hand_motors": ("JointMotor", "motor_efforts"),
})
