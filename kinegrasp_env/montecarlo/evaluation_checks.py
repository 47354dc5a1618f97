"""The checks of :func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`'s arguments, made
before any closing, each a one-line ``ValueError`` naming the bad value
(:func:`check_evaluation`), and the rules they share with other runs: an engine of the
grasp's robot and object (:func:`check_engine_grasp`), an integer seed for a run drawn by
rows of its streams (:func:`integer_seed`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.counts import check_count
from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.engines import ENGINES, engine_class
from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.robot.catalog import as_description, load_robot
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import (
    METHODS,
    JointNoise,
    SeedLike,
    check_seed,
    is_integer_seed,
)
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.noise_spec import NO_SOURCE
from kinegrasp_env.world.grasps import Grasp, check_grasp, check_robot
from kinegrasp_env.world.robot_configuration import check_configuration


def check_evaluation(grasp: Grasp, *, sigma, n, seed, noise, engine, robot, static_hold,
                     friction, executor, noise_model, offset, method, progress,
                     keep_draws) -> tuple[str, float | tuple[float, ...], float]:
    """:func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`'s arguments (the same
    keywords) checked before any work (its ``Raises``; one line each): (the robot's name, the
    joint noise's sigma (0 under a noise model, whose joints source replaces it), the run's
    mu (a friction source's nominal one))."""
    check_grasp(grasp)
    check_count(n, "n")
    check_count(offset, "offset", least=0)  # a row number
    if offset:
        if not isinstance(seed, (int, np.integer, np.random.SeedSequence)):
            raise ValueError("draws from row offset > 0 take an integer or SeedSequence "
                             f"seed, got {type(seed).__name__}")
    check_seed(seed)
    if noise_model is not None and not isinstance(noise_model, NoiseModel):
        raise ValueError(f"noise_model must be a NoiseModel (e.g. kinegrasp_env.sampling."
                         f"noise_spec.load_noise_model), got {type(noise_model).__name__}; "
                         "joint noise alone is sigma= and noise=")
    if noise_model is not None and not noise_model.sources:
        raise ValueError(f"noise_model {NO_SOURCE}")
    if noise_model is None:
        if sigma is None:
            raise ValueError("give the joint noise's sigma (radians) or a noise_model")
        JointNoise(sigma, noise)  # sigma and noise checked before any work
    elif sigma is not None or noise != "gaussian":
        raise ValueError("give sigma and noise, or a noise_model, not both: the model's "
                         "joints source is its joint noise")
    else:
        sigma = 0.0  # the model's joints source replaces it
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    for flag, value in (("keep_draws", keep_draws), ("static_hold", static_hold)):
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"{flag} must be True or False, got {value!r}")
    if progress is not None and not callable(progress):
        raise ValueError(f"progress must be a function progress(done, n), got {progress!r}")
    if executor is not None and not isinstance(executor, Executor):
        raise ValueError("executor must be an Executor (kinegrasp_env.montecarlo.execution: "
                         f"LocalExecutor(processes), RayExecutor()), got {executor!r}")
    if isinstance(engine, str) and engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if not isinstance(engine, str):
        kind = getattr(engine, "name", None)
        if kind not in ENGINES or type(engine) is not engine_class(kind):
            raise ValueError(f"engine must be a name ({', '.join(ENGINES)}) or an engine "
                             f"make_engine builds, got {type(engine).__name__}")
        name = engine.description.name
        if robot is not None and getattr(robot, "name", robot) != name:
            raise ValueError(f"robot {getattr(robot, 'name', robot)!r} is not the engine's "
                             f"robot {name!r}: give the robot or an engine of it")
        check_engine_grasp(grasp, engine)
    else:
        name = grasp.robot if robot is None else as_description(robot).name
        check_robot(grasp, name)
    check_configuration(grasp.q0, f"grasp {grasp.id!r}", robot=name)
    if noise_model is not None:
        from kinegrasp_env.montecarlo.noise_rows import check_robot_noise
        from kinegrasp_env.sampling.noise_model import nominal_friction

        friction = nominal_friction(noise_model, friction)

        integer_seed(seed, "a noise model's run")
        description = (robot if isinstance(robot, RobotDescription) else load_robot(name)
                       ) if isinstance(engine, str) else engine.description
        check_robot_noise(noise_model, description, description.arm_dof,
                          engine if isinstance(engine, str) else engine.name,
                          static_hold if isinstance(engine, str)
                          else engine.hold_check is not None)
    return name, sigma, friction


def check_engine_grasp(grasp: Grasp, engine: RobotEngine) -> None:
    """ValueError (one line) unless ``engine`` holds the grasp's robot and object."""
    check_robot(grasp, engine.description.name)
    if engine.obj.name != grasp.object:
        raise ValueError(f"grasp {grasp.id!r} is a grasp of {grasp.object!r}, the engine "
                         f"holds {engine.obj.name!r}")


def integer_seed(seed: SeedLike, what: str) -> None:
    """ValueError unless ``seed`` is an integer >= 0 (a run drawn by rows of its streams)."""
    if not is_integer_seed(seed):
        raise ValueError(f"{what} takes an integer seed >= 0 (its draws are rows of the "
                         f"seed's streams), got {seed!r}")
