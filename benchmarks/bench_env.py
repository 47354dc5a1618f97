"""Environment steps per second (KineGrasp-v0, one process) at n_draws = 64 and 256.

Run: ``python benchmarks/bench_env.py [--steps 40]``. Both engines, side by side in one
run (the fast engine's grids built and kernels compiled beforehand). Target: >= 100 steps/s
at 64 draws with the fast engine. Steps/s of wall time, and of the process's CPU time (what a
machine shared with other work still shows). Then the fast engine at 64 draws one object at
a time, and the fast engine's auto-close of one step's
draws, the compiled closing loop against the vectorized one it replaced (same results,
tested).

The figures (steps/s, seconds) also go to ``benchmarks/results/bench_env.json``
(``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
from results_file import add_options, settings, write_result

import kinegrasp_env  # noqa: F401  (registers the envs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=40)
    add_options(parser, __file__)
    args = parser.parse_args()
    steps_rows, closing_rows = [], []
    from kinegrasp_env.montecarlo.engines import FastEngine
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import OBJECT_NAMES

    for name in OBJECT_NAMES:  # warm-up: grids built or loaded, numba compiled
        FastEngine(name).run(shipped_grasps(name)[0].q0[None])
    for engine, n_draws in (("pybullet", 64), ("fast", 64), ("pybullet", 256), ("fast", 256)):
        env = gym.make("KineGrasp-v0", n_draws=n_draws, engine=engine)
        env.reset(seed=0)
        env.action_space.seed(0)
        env.step(env.action_space.sample())  # warm-up (engine construction)
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(args.steps):
            action = env.action_space.sample()
            action[1] = -1.0
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        env.close()
        print(f"{engine:8s} n_draws = {n_draws:3d}: {args.steps / wall:6.1f} steps/s "
              f"({wall / args.steps * 1e3:6.1f} ms/step; {args.steps / cpu:6.1f} steps/s of CPU "
              f"time; target >= 100 steps/s at 64, fast)")
        steps_rows.append({"engine": engine, "n_draws": n_draws, "steps": args.steps,
                           "steps_per_s": args.steps / wall, "s_per_step": wall / args.steps,
                           "steps_per_cpu_s": args.steps / cpu})

    object_rows = per_object(OBJECT_NAMES, args.steps)

    import numpy as np

    from kinegrasp_env.closing.fast import FastHand
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.world.objects import load_object
    from kinegrasp_env.world.sdf import object_grid

    rng = np.random.default_rng(0)
    for n_draws in (64, 256):
        timings = {"compiled": 0.0, "vectorized": 0.0}
        for name in OBJECT_NAMES:
            hands = {c: FastHand(load_object(name), object_grid(name), closing=c)
                     for c in timings}
            for grasp in shipped_grasps(name)[:4]:
                q = np.tile(grasp.q0, (n_draws, 1))
                q[:, :7] += JointNoise(0.0133, "gaussian").sample(n_draws, 7, rng)
                for closing, hand in hands.items():
                    start = time.perf_counter()
                    for _ in range(5):
                        hand.close(q)
                    timings[closing] += (time.perf_counter() - start) / 5
        calls = 4 * len(OBJECT_NAMES)
        compiled, vectorized = (timings[c] / calls * 1e3 for c in ("compiled", "vectorized"))
        print(f"auto-close of {n_draws:3d} draws: compiled loop {compiled:5.1f} ms, "
              f"vectorized {vectorized:5.1f} ms ({vectorized / compiled:.1f}x)")
        closing_rows.append({"n_draws": n_draws, "compiled_s": compiled / 1e3,
                             "vectorized_s": vectorized / 1e3,
                             "vectorized_over_compiled": vectorized / compiled})
    if not args.no_json:
        write_result(__file__, {"steps": steps_rows, "fast_64_draws_per_object": object_rows,
                                "autoclose": closing_rows, "settings": settings(args)},
                     args.json_out)


def per_object(names, steps: int) -> list[dict]:
    """Fast-engine steps/s at 64 draws with every episode on one object (the mixed figure
    above moves with the env's draw of tasks: its objects cost 2x apart)."""
    env = gym.make("KineGrasp-v0", n_draws=64, engine="fast")
    env.action_space.seed(0)
    rows = []
    for name in names:
        env.reset(seed=0, options={"object": name})
        env.step(env.action_space.sample())  # warm-up
        start = time.perf_counter()
        for _ in range(steps):
            action = env.action_space.sample()
            action[1] = -1.0
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset(options={"object": name})
        wall = time.perf_counter() - start
        print(f"fast     n_draws =  64, {name:12s}: {steps / wall:6.1f} steps/s "
              f"({wall / steps * 1e3:6.1f} ms/step)")
        rows.append({"object": name, "steps_per_s": steps / wall, "s_per_step": wall / steps})
    env.close()
    return rows


if __name__ == "__main__":
    main()
