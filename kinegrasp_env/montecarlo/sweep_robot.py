"""A sweep task of a description robot (any catalog robot but ``kuka_sdh``).

A cell of robot R, grasp g, sigma s, noise type k and seed is ``evaluate_robot_grasp(g,
sigma=s, n=samples, seed=seed, noise=k)``'s run, split into chunks: its draws are the rows of
one stream, ``JointNoise(s, k).sample(samples, arm_dof, default_rng(seed))`` (arm joints
noisy, the hand at its pre-shape exactly), and chunk c closes rows ``offset .. offset + size``
of it. The rows of a stream do not depend on how many are drawn, so a cell's counts equal
``kinegrasp evaluate --robot R`` with the same seed whatever the chunk size, and cells of the
same noise type share their draws (common random numbers, as for the default robot).

Engines (:func:`~kinegrasp_env.montecarlo.robot_evaluate.make_engine`) are built once per
process and robot, object and engine name, and reused by its later tasks.
"""

from __future__ import annotations

import time

import numpy as np

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, OUTCOMES
from kinegrasp_env.montecarlo.robot_engine import RobotEngine
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.stats import StreamingMoments

#: Engines a process keeps (the oldest is closed when one more is needed).
MAX_ENGINES = 4
_ENGINES: dict[tuple[str, str, str, float], RobotEngine] = {}


def robot_engine(engine: str, robot: str, object_name: str,
                 friction: float = 0.5) -> RobotEngine:
    """This process's engine ``engine`` of ``robot`` and ``object_name`` at friction mu
    ``friction`` (built on first use)."""
    key = (engine, robot, object_name, float(friction))
    if key not in _ENGINES:
        from kinegrasp_env.montecarlo.robot_evaluate import make_engine

        while len(_ENGINES) >= MAX_ENGINES:
            _ENGINES.pop(next(iter(_ENGINES))).close()
        _ENGINES[key] = make_engine(engine, robot, object_name, friction=friction)
    return _ENGINES[key]


def close_engines() -> None:
    """Close every engine this process keeps."""
    while _ENGINES:
        _ENGINES.popitem()[1].close()


def chunk_configurations(q0: np.ndarray, arm_dof: int, sigma: float, noise: str, seed: int,
                         offset: int, size: int) -> np.ndarray:
    """(size, dof) configurations: q0 (dof,) with rows ``offset .. offset + size`` of the
    cell's stream added to its first ``arm_dof`` entries (radians or metres)."""
    eps = JointNoise(sigma, noise).sample(offset + size, arm_dof,
                                          np.random.default_rng(seed))[offset:]
    q = np.repeat(np.asarray(q0, dtype=float)[None], size, axis=0)
    q[:, :arm_dof] += eps
    return q


def run_robot_task(task) -> dict:
    """Evaluate one :class:`~kinegrasp_env.montecarlo.sweep_spec.SweepTask` of a description
    robot: outcome counts and Q moments of its chunk (the fields of ``sweep.run_task``)."""
    start = time.perf_counter()
    engine = robot_engine(task.engine, task.robot, task.object, task.friction)
    q = chunk_configurations(np.asarray(task.q0, dtype=float), engine.description.arm_dof,
                             task.sigma, task.noise, task.seed, task.offset, task.size)
    draws = engine.run(q)
    fc = draws.outcome == FORCE_CLOSURE
    moments = StreamingMoments(1).update(draws.quality[fc])
    counts = np.bincount(draws.outcome, minlength=len(OUTCOMES))
    return {"counts": [int(c) for c in counts], "q_n": int(moments.n),
            "q_mean": float(moments.mean[0]), "q_m2": float(moments.m2[0, 0]),
            "q_m3": float(moments.m3[0]), "seconds": time.perf_counter() - start}
