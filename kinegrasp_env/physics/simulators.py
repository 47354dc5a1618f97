"""The simulators that run the holding test, by name, and the interface each implements.

A simulator is a class registered in :data:`SIMULATORS` (name -> (module, class, the Python
package it needs)); the module is imported only when the simulator is used, so a missing
package fails with one line (:func:`simulator_class`), not at import. ``pybullet`` is
:class:`~kinegrasp_env.physics.robot_hold.RobotHold`, ``mujoco``
:class:`~kinegrasp_env.physics.mujoco_robot_hold.MujocoRobotHold`. A further simulator adds
its entry here and implements :class:`HoldSimulator`:

* ``__init__(description, obj, friction, protocol, world=None, settings=None)``: the robot's
  description (its hand, cut from the URDF, is simulated with the motors its description
  gives: :mod:`~kinegrasp_env.physics.hand_motors`), the catalog object (its convex parts,
  pose, centre of mass and mass), the finger-object friction mu, the
  :class:`~kinegrasp_env.physics.protocol.HoldProtocol`, and optionally the world's and the
  motors' settings;
* ``run_draw(q)``: the robot's actuated configuration q (dof,) (radians; the palm pose from
  its forward kinematics); closes the hand on the pinned object and runs the protocol's
  phases in order; returns the closing (contacts in the object frame, normals into the
  object) and a :class:`~kinegrasp_env.physics.protocol.HoldResult` built with the
  protocol's rules. A draw's result depends only on its inputs;
* ``close_hand(q, pin)``: the closing alone (the object pinned or free);
* ``close()``: frees the simulator (idempotent).
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import TYPE_CHECKING, ClassVar, Protocol

if TYPE_CHECKING:  # the registry stays cheap to import (the CLI's parser reads it)
    import numpy as np

    from kinegrasp_env.closing.close_result import RobotCloseResult
    from kinegrasp_env.physics.protocol import HoldProtocol, HoldResult
    from kinegrasp_env.robot.description import RobotDescription
    from kinegrasp_env.world.objects import GraspObject

#: What the physics closings and holding tests of this version simulate, recorded beside
#: results that they made (a sweep store, a ranking log, a ``validate`` cache), so that the
#: results of another version's physics are not taken for this one's.
PHYSICS_MODEL = ("every robot's hand by its description's motors; the object's exact "
                 "convex parts, mass and inertia")
#: name -> (module, class name, the Python package it needs).
SIMULATORS: dict[str, tuple[str, str, str]] = {
    "pybullet": ("kinegrasp_env.physics.robot_hold", "RobotHold", "pybullet"),
    "mujoco": ("kinegrasp_env.physics.mujoco_robot_hold", "MujocoRobotHold", "mujoco"),
}


class HoldSimulator(Protocol):
    """What a registered simulator implements (module docstring)."""

    name: ClassVar[str]

    def __init__(self, description: RobotDescription, obj: GraspObject, friction: float,
                 protocol: HoldProtocol, world=None, settings=None) -> None: ...

    def run_draw(self, q: np.ndarray) -> tuple[RobotCloseResult, HoldResult]: ...

    def close_hand(self, q: np.ndarray, pin: bool = True) -> tuple: ...

    def close(self) -> None: ...


def simulator_names() -> tuple[str, ...]:
    return tuple(SIMULATORS)


def check_simulator(name: str) -> None:
    """Raise ValueError (one line) for an unknown simulator or one whose package is not
    installed."""
    if name not in SIMULATORS:
        raise ValueError(f"unknown simulator {name!r}; choose from {', '.join(SIMULATORS)}")
    package = SIMULATORS[name][2]
    if importlib.util.find_spec(package) is None:
        raise ValueError(f"simulator {name!r} needs the Python package {package!r} "
                         f"(pip install {package})")


def simulator_class(name: str) -> type[HoldSimulator]:
    """The class of simulator ``name`` (checked: :func:`check_simulator`)."""
    check_simulator(name)
    module, cls, _ = SIMULATORS[name]
    return getattr(importlib.import_module(module), cls)
