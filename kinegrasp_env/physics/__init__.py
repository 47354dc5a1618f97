"""The simulated closing and holding protocols: the hand closed by finger motors under
dynamics, then the holding test of the closed grasp.

The protocol itself (phases, thresholds, the per-draw result) is simulator-independent
(``protocol``); each simulator executes it in modules of its own: pybullet's world
(``pybullet_world``: a free hand held by a constraint, the object as a rigid body), its
closing controller (``pybullet_closing``) and its holding test (``pybullet_lift``).
Uses ``closing`` (the kinematic closing's contact rules and result type), ``world`` and
``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "PhysicsWorld": "pybullet_world",
    "WorldSettings": "pybullet_world",
    "MotorSettings": "pybullet_closing",
    "physics_close": "pybullet_closing",
    "LiftProfile": "pybullet_lift",
    "lift_test": "pybullet_lift",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
