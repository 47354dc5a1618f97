"""The fast engine of a description robot against its reference engine, per draw and on a pool
of warm worker processes; used by ``bench_engines.py`` (the Panda on its shipped cube grasps).
"""

from __future__ import annotations

import multiprocessing
import time

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import make_engine
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import shipped_grasps

_WORKER: dict = {}


def draws_of(q0: np.ndarray, arm: int, sigma: float, n: int, seed) -> np.ndarray:
    """(n, dof): q0 with Gaussian noise of sigma (radians) on its first ``arm`` joints."""
    q = np.repeat(np.asarray(q0, dtype=float)[None], n, axis=0)
    q[:, :arm] += JointNoise(sigma).sample(n, arm, np.random.default_rng(seed))
    return q


def _start(robot: str, object_name: str, barrier) -> None:
    """Worker start: its engine built and warmed (grid, compiled kernels), then the barrier."""
    engine = make_engine("fast", robot, object_name)
    grasp = shipped_grasps(object_name, robot)[0]
    engine.run(draws_of(grasp.q0, engine.description.arm_dof, 0.0133, 64, 99))
    _WORKER["engine"] = engine
    barrier.wait()


def _chunk(task: tuple) -> int:
    """Force-closure draws of one chunk (grasp index, sigma, draws, seed)."""
    engine = _WORKER["engine"]
    grasp = shipped_grasps(engine.obj.name, engine.description.name)[task[0]]
    q = draws_of(grasp.q0, engine.description.arm_dof, task[1], task[2], task[3])
    return int((engine.run(q).outcome == FORCE_CLOSURE).sum())


def static_hold_cost(robot: str, object_name: str, sigma: float, draws: int, seed: int,
                     pairs: int = 3) -> dict:
    """Seconds per draw of the fast engine without and with the static hold check, and with
    the patch contact model, on the same draws of each shipped grasp, one process, ``pairs``
    alternating runs (the minimum of each kept), after a first run of each."""
    import dataclasses

    plain = make_engine("fast", robot, object_name)
    checked = make_engine("fast", robot, object_name, static_hold=True)
    patched = make_engine("fast", dataclasses.replace(plain.description,
                                                      contact_model="patch"), object_name)
    grasps = shipped_grasps(object_name, robot)
    arm = plain.description.arm_dof
    qs = [draws_of(g.q0, arm, sigma, draws, [seed, i]) for i, g in enumerate(grasps)]
    timed = (("fast", plain), ("fast_static_hold", checked), ("fast_patch", patched))
    best = {name: np.inf for name, _ in timed}
    for _, engine in timed:
        for q in qs:
            engine.run(q)
    for _ in range(pairs):
        for name, engine in timed:
            start = time.perf_counter()
            for q in qs:
                engine.run(q)
            best[name] = min(best[name], (time.perf_counter() - start) / (draws * len(qs)))
    return {**{f"{k}_s_per_draw": v for k, v in best.items()},
            "static_hold_over_fast": best["fast_static_hold"] / best["fast"],
            "patch_over_fast": best["fast_patch"] / best["fast"]}


def per_draw(robot: str, object_name: str, sigma: float, draws: int, seed: int) -> dict:
    """Seconds per draw of both engines on one process over the same ``draws`` draws of each
    shipped grasp (the fast engine's: the best of three runs after a first one, which loads
    its compiled kernels and tables; a run of tens of milliseconds on a shared machine
    varies by a third from one to the next), and their force-closure counts."""
    fast, reference = make_engine("fast", robot, object_name), make_engine("pybullet", robot,
                                                                          object_name)
    try:
        grasps = shipped_grasps(object_name, robot)
        arm = fast.description.arm_dof
        qs = [draws_of(g.q0, arm, sigma, draws, [seed, i]) for i, g in enumerate(grasps)]
        out = {}
        for name, engine in (("fast", fast), ("pybullet", reference)):
            if name == "fast":  # loads the compiled kernels and tables (rare paths too)
                for q in qs:
                    engine.run(q)
            seconds = np.inf
            for _ in range(3 if name == "fast" else 1):
                start = time.perf_counter()
                results = [engine.run(q) for q in qs]
                seconds = min(seconds, time.perf_counter() - start)
            out[name] = {"engine": name, "draws": draws * len(qs),
                         "s_per_draw": seconds / (draws * len(qs)),
                         "force_closure": [int((r.outcome == FORCE_CLOSURE).sum())
                                           for r in results]}
        return out
    finally:
        reference.close()


def pool_run(robot: str, object_name: str, sigma: float, draws: int, processes: int,
             seed: int) -> dict:
    """Wall time of ``draws`` fast-engine draws of the first shipped grasp split over
    ``processes`` warm workers (each holds its engine before the clock starts), and of the
    pool's start (engine built, warmed)."""
    context = multiprocessing.get_context("fork")
    barrier = context.Barrier(processes + 1)
    start = time.perf_counter()
    with context.Pool(processes, initializer=_start,
                      initargs=(robot, object_name, barrier)) as pool:
        barrier.wait()
        ready = time.perf_counter() - start
        share = [draws // processes + (i < draws % processes) for i in range(processes)]
        tasks = [(0, sigma, n, [seed, i]) for i, n in enumerate(share)]
        begin = time.perf_counter()
        fc = sum(pool.map(_chunk, tasks, chunksize=1))
        wall = time.perf_counter() - begin
        again = time.perf_counter()
        pool.map(_chunk, tasks, chunksize=1)
        again = time.perf_counter() - again
    return {"draws": draws, "processes": processes, "wall_s": wall, "run_again_wall_s": again,
            "pool_start_s": ready, "draws_per_s": draws / wall, "p_fc": fc / draws}
