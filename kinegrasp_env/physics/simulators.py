"""The simulators that run the holding test, by name, and the interface each implements.

A simulator is a class registered in :data:`SIMULATORS` (name -> (module, class, the Python
package it needs)); the module is imported only when the simulator is used, so a missing
package fails with one line (:func:`simulator_class`), not at import. ``pybullet`` is
:class:`~kinegrasp_env.physics.pybullet_hold.PybulletHold`. A second simulator adds its
entry here and implements :class:`HoldSimulator`:

* ``__init__(obj, friction, protocol)``: the catalog object (its convex parts, pose,
  centre of mass, mass from density 500 kg/m^3 as :func:`~kinegrasp_env.physics.
  pybullet_world.mass_properties`), the finger-object friction mu, and the
  :class:`~kinegrasp_env.physics.protocol.HoldProtocol` (torque limits:
  ``protocol.torques``);
* ``run_draw(root_pose (4, 4), preshape (7,))``: the hand root (the arm's flange frame,
  world) at ``root_pose``, the hand DOF at ``preshape`` (``HAND_JOINTS`` order, radians);
  closes the hand on the pinned object and runs the protocol's phases in order
  (:mod:`~kinegrasp_env.physics.protocol`); returns the closing as a
  :class:`~kinegrasp_env.physics.hand_result.CloseResult` (contacts in the object frame,
  normals into the object, one per touching finger link) and a
  :class:`~kinegrasp_env.physics.protocol.HoldResult` built with the protocol's rules
  (:func:`~kinegrasp_env.physics.protocol.grip_verdict`, ``pose_change``, ``within``,
  ``final_outcome``). A draw's result depends only on its inputs;
* ``close()``: frees the simulator (idempotent).

These simulators hold the default robot's hand. A description robot (any other catalog
robot) is held by the classes of :data:`DESCRIPTION_ROBOT_SIMULATORS`
(:func:`robot_simulator_class`): :class:`~kinegrasp_env.physics.robot_hold.RobotHold` in
pybullet and :class:`~kinegrasp_env.physics.mujoco_robot_hold.MujocoRobotHold` in MuJoCo,
each ``__init__(description, obj, friction, protocol, world=None, settings=None)`` and
``run_draw(q)`` (the robot's actuated configuration; the palm pose from its forward
kinematics), ``close_hand(q, pin)`` (the closing alone), ``motors`` and ``close()``.
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import TYPE_CHECKING, ClassVar, Protocol

if TYPE_CHECKING:  # the registry stays cheap to import (the CLI's parser reads it)
    import numpy as np

    from kinegrasp_env.physics.hand_result import CloseResult
    from kinegrasp_env.physics.protocol import HoldProtocol, HoldResult
    from kinegrasp_env.world.objects import GraspObject

#: name -> (module, class name, the Python package it needs).
SIMULATORS: dict[str, tuple[str, str, str]] = {
    "pybullet": ("kinegrasp_env.physics.pybullet_hold", "PybulletHold", "pybullet"),
    "mujoco": ("kinegrasp_env.physics.mujoco_hold", "MujocoHold", "mujoco"),
}


#: The simulators that hold a description robot's hand: name -> (module, class name).
DESCRIPTION_ROBOT_SIMULATORS: dict[str, tuple[str, str]] = {
    "pybullet": ("kinegrasp_env.physics.robot_hold", "RobotHold"),
    "mujoco": ("kinegrasp_env.physics.mujoco_robot_hold", "MujocoRobotHold"),
}


class HoldSimulator(Protocol):
    """What a registered simulator implements (module docstring)."""

    name: ClassVar[str]

    def __init__(self, obj: GraspObject, friction: float, protocol: HoldProtocol) -> None: ...

    def run_draw(self, root_pose: np.ndarray, preshape: np.ndarray
                 ) -> tuple[CloseResult, HoldResult]: ...

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


def robot_simulator_class(name: str) -> type:
    """The class that holds a description robot's hand in simulator ``name`` (checked as
    :func:`check_simulator` checks it)."""
    check_simulator(name)
    module, cls = DESCRIPTION_ROBOT_SIMULATORS[name]
    return getattr(importlib.import_module(module), cls)
