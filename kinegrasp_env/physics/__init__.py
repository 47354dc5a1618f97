"""The simulated closing and holding protocols: the hand closed by finger motors under
dynamics, then the holding test of the closed grasp, in pybullet (and other simulators
registered in ``simulators``).

The protocol itself (phases, thresholds, stated torque assumptions, the per-draw result) is
simulator-independent (``protocol``; the hand's lift and shake motion: ``motion``); each
simulator executes it in modules of its own: pybullet's world (``pybullet_world``: a free
hand held by a constraint, the object as a rigid body that can be pinned), its closing
controller (``pybullet_closing``) and its holding test (``pybullet_hold``). ``simulators``
names them and states the interface a simulator implements. Uses ``closing`` (the kinematic
closing's contact rules and result type), ``world`` and ``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "PhysicsWorld": "pybullet_world",
    "WorldSettings": "pybullet_world",
    "MotorSettings": "pybullet_closing",
    "physics_close": "pybullet_closing",
    "HoldProtocol": "protocol",
    "HoldResult": "protocol",
    "ASSUMED_TORQUES": "protocol",
    "PHASES": "protocol",
    "HOLD_OUTCOMES": "protocol",
    "PybulletHold": "pybullet_hold",
    "SIMULATORS": "simulators",
    "simulator_class": "simulators",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
