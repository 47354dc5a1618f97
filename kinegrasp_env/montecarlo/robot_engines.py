"""The engines of every catalog robot by name: the reference (pybullet closest points, draw
by draw: :class:`RobotReferenceEngine`), the batched fast one
(:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`) and the physics closing
(:class:`~kinegrasp_env.montecarlo.robot_physics.RobotPhysicsEngine`: the hand's motors
from its description), all scoring as :class:`~kinegrasp_env.montecarlo.description_engine.
RobotEngine` does."""

from __future__ import annotations

from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.reference_engine import RobotReferenceEngine
from kinegrasp_env.robot.description import RobotDescription

__all__ = ["ENGINES", "RobotReferenceEngine", "make_engine"]


#: The engines of a description robot, by name.
ENGINES = ("pybullet", "fast", "physics")


def make_engine(name: str, robot: str | RobotDescription, object_name: str,
                **kwargs) -> RobotEngine:
    """A new engine by name (:data:`ENGINES`) for ``robot`` and catalog ``object_name``."""
    if name == "fast":
        from kinegrasp_env.montecarlo.batched_engine import RobotFastEngine

        return RobotFastEngine(robot, object_name, **kwargs)
    if name == "pybullet":
        return RobotReferenceEngine(robot, object_name, **kwargs)
    if name == "physics":
        from kinegrasp_env.montecarlo.robot_physics import RobotPhysicsEngine

        return RobotPhysicsEngine(robot, object_name, **kwargs)
    raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {name!r}")
