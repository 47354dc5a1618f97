"""The simulated closing and holding protocols: the hand closed by finger motors under
dynamics, then the holding test of the closed grasp, in pybullet (and other simulators
registered in ``simulators``).

The protocol itself (phases, thresholds, stated torque assumptions, the per-draw result) is
simulator-independent (``protocol``; the hand's lift and shake motion: ``motion``); each
simulator executes it in modules of its own: pybullet's world (``pybullet_world``: a free
hand held by a constraint, the object as a rigid body that can be pinned), its closing
controller (``pybullet_closing``; its result: ``hand_result``) and its holding test
(``pybullet_hold``); any other
catalog robot's hand cut from its URDF (``robot_world``), its closing motors
(``jaw_motors``), its holding test (``robot_hold``)
and its closing against the kinematic one (``robot_agreement``); MuJoCo's world
(``mujoco_model``, ``mujoco_world``) and holding tests of the default robot's hand
(``mujoco_hold``) and of any other robot's (``mujoco_robot_hold``); the motors of a robot's
hand in either simulator (``hand_motors``). ``simulators`` names them and states the
interface a simulator implements. Uses ``closing`` (the kinematic closing's
contact rules and a description robot's closing result), ``world`` and ``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "pybullet_world": ("PhysicsWorld", "WorldSettings"),
    "pybullet_closing": ("MotorSettings", "physics_close"),
    "protocol": ("HoldProtocol", "HoldResult", "ASSUMED_TORQUES", "PHASES", "HOLD_OUTCOMES"),
    "pybullet_hold": ("PybulletHold",),
    "simulators": ("SIMULATORS", "simulator_class", "DESCRIPTION_ROBOT_SIMULATORS",
                   "robot_simulator_class"),
    "robot_hold": ("RobotHold",),
    "mujoco_robot_hold": ("MujocoRobotHold",),
    "hand_motors": ("JointMotor", "motor_efforts"),
})
