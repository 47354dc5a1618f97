"""Environment steps per second (KineGrasp-v0, one process) at n_draws = 64 and 256.

Run: ``python benchmarks/bench_env.py [--steps 40]``. Target: >= 20 steps/s at 64 draws.
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
    for n_draws in (64, 256):
        env = gym.make("KineGrasp-v0", n_draws=n_draws)
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
        print(f"n_draws = {n_draws:3d}: {args.steps / wall:6.1f} steps/s "
              f"({wall / args.steps * 1e3:6.1f} ms/step; target >= 20 steps/s at 64)")


if __name__ == "__main__":
    main()
