"""The fast engine's auto-close with fewer golden-section steps for the grid gaps.

Run: ``python benchmarks/bench_refine.py [--draws 400] [--steps 14 8]``. On the same noisy
draws of the first 6 shipped grasps of each object (sigma 0.0133), the compiled closing loop
is run with each number of refinement steps (:data:`kinegrasp_env.closing.capsule_gap.REFINE`
is the default; the others through
:meth:`~kinegrasp_env.closing.fast.FastHand.with_refine_steps`), side by side in one run: closing
time per draw, the share of draws whose contacts found, missed fingers and start collisions
equal those of the first setting, and the largest difference of a contact point (metres).
The settings run interleaved ``--repeats`` times; the fastest time of each is kept (the
machine's noise between runs is larger than the effect).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kinegrasp_env.closing.capsule_gap import REFINE
from kinegrasp_env.closing.fast import FastHand
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import OBJECT_NAMES, load_object
from kinegrasp_env.world.sdf import object_grid


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--draws", type=int, default=400, help="draws per grasp")
    parser.add_argument("--steps", type=int, nargs="+", default=[14, REFINE])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    for name in OBJECT_NAMES:
        hand = FastHand(load_object(name), object_grid(name))
        q = []
        for grasp in shipped_grasps(name)[:6]:
            draws = np.tile(grasp.q0, (args.draws, 1))
            draws[:, :7] += JointNoise(0.0133, "gaussian").sample(args.draws, 7, rng)
            q.append(draws)
        q = np.concatenate(q)
        hands = {steps: hand.with_refine_steps(steps) for steps in args.steps}
        times: dict[int, float] = {}
        results = {}
        for _ in range(args.repeats):  # interleaved; the fastest of the repeats is kept
            for steps in args.steps:
                hands[steps].close(q[:5])  # compiled kernels loaded
                start = time.perf_counter()
                results[steps] = hands[steps].close(q)
                seconds = time.perf_counter() - start
                times[steps] = min(times.get(steps, np.inf), seconds / len(q))
        first = results[args.steps[0]]
        for steps in args.steps:
            out = results[steps]
            same = ((out.found == first.found).all(axis=(1, 2))
                    & (out.missed == first.missed).all(axis=1)
                    & (out.start_collision == first.start_collision))
            points = np.abs(out.points - first.points)
            diff = np.nanmax(points) if np.isfinite(points).any() else 0.0
            print(f"{name:12s} {steps:2d} steps: {times[steps] * 1e6:6.1f} us per draw "
                  f"({times[steps] / times[args.steps[0]]:.2f}x), same contacts found "
                  f"{same.mean():.4f} of {len(q)}, points within {diff:.1e} m")


if __name__ == "__main__":
    main()
