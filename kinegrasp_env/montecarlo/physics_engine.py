"""The physics engine of a description robot: its hand closed under pybullet dynamics, draw by
draw, scored exactly as the kinematic engines score their closings
(:func:`~kinegrasp_env.montecarlo.description_engine.score`).

The closing is the holding test's (:meth:`~kinegrasp_env.physics.robot_hold.RobotHold.
close_hand`: the hand cut from the URDF, free-floating and held at the palm pose the draw's
arm joints give, each finger closed by a velocity motor at its URDF effort until it stalls),
with the object **free** while the hand closes (a dynamic body under its support damping,
gravity off) and the jaws one actuator moves coupled as the gripper couples them (the first
to touch pushes the object until the other meets it); the contacts are in the object's frame
where the object ended. The draws are the other engines' (the same
configurations for the same seed: :func:`~kinegrasp_env.montecarlo.evaluate.
evaluate_grasp`); every draw starts from the world's saved state, so a draw's result
depends only on its configuration.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.physics.protocol import HoldProtocol
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.physics.robot_hold import RobotHold, RobotMotorSettings
from kinegrasp_env.robot.description import RobotDescription


class RobotPhysicsEngine(RobotEngine):
    """Closing under pybullet dynamics of a description robot (see the module docstring).

    Args:
        robot, object_name, kwargs: :class:`~kinegrasp_env.montecarlo.description_engine.
            RobotEngine` (``friction`` is also the simulated finger-object friction).
        world: :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings` (density, time
            step; the object must be free); its friction is replaced by ``friction``.
        motors: :class:`~kinegrasp_env.physics.robot_hold.RobotMotorSettings` (the
            closing's end).
    """

    name = "physics"

    def __init__(self, robot: str | RobotDescription, object_name: str, *,
                 world: WorldSettings | None = None, motors: RobotMotorSettings | None = None,
                 **kwargs) -> None:
        super().__init__(robot, object_name, **kwargs)
        self.settings = {key: value for key, value in (("world", world), ("motors", motors))
                         if value is not None}
        self.jaw_speeds = None  # coupled jaws push the free object here: no push to report
        self.hold = RobotHold(self.description, self.obj, self.friction, HoldProtocol(),
                              world, motors)

    def options(self) -> dict[str, object]:
        return {**super().options(), **self.settings}

    def close(self) -> None:
        self.hold.close()

    def close_one(self, q: np.ndarray) -> RobotCloseResult:
        """One closing at configuration q (dof,) (the world is left at its final state)."""
        return self.hold.close_hand(self.check(q)[0], pin=False)[0]

    def close_all(self, q: np.ndarray) -> list[RobotCloseResult]:
        """One closing per configuration of q (n, dof); a draw whose robot starts in the
        object's support table (:attr:`in_table`: the arm is not simulated) is a start
        collision, not simulated."""
        in_table = self.in_table(q)
        fingers = len(self.description.fingers)
        return [RobotCloseResult.collided(fingers) if hit
                else self.hold.close_hand(row, pin=False)[0]
                for row, hit in zip(q, in_table, strict=True)]
