"""The engines of every catalog robot by name: the reference (pybullet closest points, draw
by draw: :class:`~kinegrasp_env.montecarlo.reference_engine.RobotReferenceEngine`), the
batched fast one
(:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`) and the physics closing
(:class:`~kinegrasp_env.montecarlo.physics_engine.RobotPhysicsEngine`: the hand's motors
from its description), all scoring as :class:`~kinegrasp_env.montecarlo.description_engine.
RobotEngine` does."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the engines' modules load pybullet and the compiled closings
    from kinegrasp_env.montecarlo.description_engine import RobotEngine
    from kinegrasp_env.robot.description import RobotDescription

__all__ = ["ENGINES", "engine_class", "error_engines", "make_engine"]

#: The engines of a robot, by name.
ENGINES = ("pybullet", "fast", "physics")


def engine_class(name: str) -> type[RobotEngine]:
    """The class of the engine named ``name`` (:data:`ENGINES`; ValueError otherwise)."""
    if name == "fast":
        from kinegrasp_env.montecarlo.batched_engine import RobotFastEngine

        return RobotFastEngine
    if name == "pybullet":
        from kinegrasp_env.montecarlo.reference_engine import RobotReferenceEngine

        return RobotReferenceEngine
    if name == "physics":
        from kinegrasp_env.montecarlo.physics_engine import RobotPhysicsEngine

        return RobotPhysicsEngine
    raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {name!r}")


def error_engines() -> tuple[str, ...]:
    """The engines that take palm, object and friction errors (their class's
    ``takes_errors``), in :data:`ENGINES` order."""
    return tuple(name for name in ENGINES if engine_class(name).takes_errors)


def make_engine(name: str, robot: str | RobotDescription, object_name: str,
                **kwargs) -> RobotEngine:
    """A new engine by name (:data:`ENGINES`) for ``robot`` and catalog ``object_name``
    (``kwargs``: the engine's settings, :class:`~kinegrasp_env.montecarlo.description_engine.
    RobotEngine`'s)."""
    return engine_class(name)(robot, object_name, **kwargs)
