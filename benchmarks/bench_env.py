"""Environment steps per second (KineGrasp-v0, one process) at n_draws = 64 and 256.

Run: ``python benchmarks/bench_env.py [--steps 40]``. Both engines, side by side in one
run (the fast engine's grids built and kernels compiled beforehand). Target: >= 20 steps/s
at 64 draws.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import kinegrasp_env  # noqa: F401  (registers the envs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=40)
    args = parser.parse_args()
    from kinegrasp_env.engine import FastEngine
    from kinegrasp_env.grasps import shipped_grasps
    from kinegrasp_env.objects import OBJECT_NAMES

    for name in OBJECT_NAMES:  # warm-up: grids built or loaded, numba compiled
        FastEngine(name).run(shipped_grasps(name)[0].q0[None])
    for engine, n_draws in (("pybullet", 64), ("fast", 64), ("pybullet", 256), ("fast", 256)):
        env = gym.make("KineGrasp-v0", n_draws=n_draws, engine=engine)
        env.reset(seed=0)
        env.action_space.seed(0)
        env.step(env.action_space.sample())  # warm-up (engine construction)
        start = time.perf_counter()
        for _ in range(args.steps):
            action = env.action_space.sample()
            action[1] = -1.0
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        wall = time.perf_counter() - start
        env.close()
        print(f"{engine:8s} n_draws = {n_draws:3d}: {args.steps / wall:6.1f} steps/s "
              f"({wall / args.steps * 1e3:6.1f} ms/step; target >= 20 steps/s at 64)")


if __name__ == "__main__":
    main()
