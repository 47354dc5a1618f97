"""The reference engine of every catalog robot: its hand closed in one pybullet world, draw
by draw, at pybullet's closest points (:class:`~kinegrasp_env.closing.generic_reference.
RobotWorld`), scored as :class:`~kinegrasp_env.montecarlo.description_engine.RobotEngine`
scores."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.robot.description import RobotDescription


class RobotReferenceEngine(RobotEngine):
    """The reference engine for a description robot: one pybullet world, draw by draw
    (arguments: :class:`RobotEngine`)."""

    name = "pybullet"
    takes_errors = True

    def __init__(self, robot: str | RobotDescription, object_name: str, **kwargs) -> None:
        super().__init__(robot, object_name, **kwargs)
        self.world = RobotWorld(self.description, self.obj)

    def close(self) -> None:
        self.world.close()

    def close_one(self, q: np.ndarray) -> RobotCloseResult:
        """One closing at configuration q (dof,) (the world is left at its final state)."""
        return self.world.auto_close(self.check(q)[0])

    def close_all(self, q: np.ndarray, palm: np.ndarray | None = None,
                  object_offset: np.ndarray | None = None) -> list[RobotCloseResult]:
        """One closing per row of q (n, dof), with its palm and object errors (n, 4, 4)."""
        return [self.world.auto_close(row, palm=None if palm is None else palm[i],
                                      object_offset=None if object_offset is None
                                      else object_offset[i])
                for i, row in enumerate(q)]
