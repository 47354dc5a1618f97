"""Monte Carlo evaluation throughput: one spray-flask grasp at sigma = 0.0133.

Run: ``python benchmarks/bench_evaluate.py [--draws 10000] [--grasp 0]``. Prints wall time
and draws/s on 1 and 2 processes (same seed: identical statistics), and where the time goes
on one process (kinematics, auto-close, quality). Target: 10,000 draws in under 20 s on the
2-core machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kinegrasp_env.montecarlo.engines import OUTCOMES, PybulletEngine
from kinegrasp_env.montecarlo.evaluate import chunk_noise, evaluate_grasp
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import grasp_by_index


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--draws", type=int, default=10_000)
    parser.add_argument("--grasp", type=int, default=0)
    parser.add_argument("--object", default="spray_flask")
    args = parser.parse_args()
    grasp = grasp_by_index(args.object, args.grasp)
    noise = JointNoise(0.0133)
    results = {}
    for processes in (1, 2):
        start = time.perf_counter()
        stats = evaluate_grasp(grasp, noise, args.draws, seed=0, processes=processes)
        wall = time.perf_counter() - start
        results[processes] = stats
        print(f"{processes} process(es): {wall:7.2f} s  {args.draws / wall:8.0f} draws/s  "
              f"P(FC) = {stats.p_fc:.4f}  q_mean = {stats.q_mean:.5f}")
    same = results[1].to_json() == results[2].to_json()
    print(f"identical statistics on 1 and 2 processes: {same}")
    # stage split on one process (a sample of the same draws)
    engine = PybulletEngine(args.object)
    n = min(args.draws, 2000)
    eps = chunk_noise(noise, 0, 0, n)
    q = np.repeat(grasp.q0[None], n, axis=0)
    q[:, :7] += eps
    draws = engine.run(q)
    t = engine.timing
    total = t.kinematics + t.autoclose + t.quality
    print(f"stage split over {n} draws (1 process): kinematics {t.kinematics / n * 1e6:7.1f} "
          f"us/draw ({t.kinematics / total:.1%}), auto-close {t.autoclose / n * 1e6:7.1f} us/draw "
          f"({t.autoclose / total:.1%}), quality {t.quality / n * 1e6:7.1f} us/draw "
          f"({t.quality / total:.1%})")
    counts = np.bincount(draws.outcome, minlength=4)
    contacts = np.bincount(draws.n_contacts, minlength=7)
    print("outcomes: " + ", ".join(f"{o} {c}" for o, c in zip(OUTCOMES, counts, strict=True)))
    print("contacts per draw: " + ", ".join(f"{k}: {c}" for k, c in enumerate(contacts) if c))


if __name__ == "__main__":
    main()
