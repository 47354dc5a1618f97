"""A sweep task of a description robot (any catalog robot but ``kuka_sdh``).

A cell of robot R, grasp g, sigma s, noise type k and seed is ``evaluate_robot_grasp(g,
sigma=s, n=samples, seed=seed, noise=k)``'s run, split into chunks: its draws are the rows of
the seed's chunked streams (:func:`~kinegrasp_env.sampling.noise_model.stream_rows`), and
chunk c closes rows ``offset .. offset + size`` of them
(:mod:`~kinegrasp_env.montecarlo.robot_chunks`). The rows do not depend on how many are
drawn, so a cell's counts equal ``kinegrasp evaluate --robot R`` with the same seed
whatever the chunk size, and cells of the same noise type share their draws (common random
numbers, as for the default robot). Each process keeps its engines for its later tasks.
"""

from __future__ import annotations

import time

import numpy as np

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, OUTCOMES
from kinegrasp_env.montecarlo.robot_chunks import RobotChunk, close_chunk
from kinegrasp_env.montecarlo.sweep_noise import cell_noise
from kinegrasp_env.sampling.stats import StreamingMoments


def run_robot_task(task) -> dict:
    """Evaluate one :class:`~kinegrasp_env.montecarlo.sweep_spec.SweepTask` of a description
    robot: outcome counts and Q moments of its chunk (the fields of ``sweep.run_task``)."""
    start = time.perf_counter()
    # a model cell's model has the cell's sigma as its joints'
    model = None if task.model is None else cell_noise(task.sigma, task.noise, task.model)
    draws = close_chunk(RobotChunk(task.robot, task.object, task.engine, task.q0, task.sigma,
                                   task.noise, task.seed, task.offset, task.size,
                                   task.friction), model)
    fc = draws.outcome == FORCE_CLOSURE
    moments = StreamingMoments(1).update(draws.quality[fc])
    counts = np.bincount(draws.outcome, minlength=len(OUTCOMES))
    return {"counts": [int(c) for c in counts], "q_n": int(moments.n),
            "q_mean": float(moments.mean[0]), "q_m2": float(moments.m2[0, 0]),
            "q_m3": float(moments.m3[0]), "seconds": time.perf_counter() - start}
