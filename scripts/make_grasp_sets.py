"""Generate the shipped grasp sets ``assets/grasps/kuka_sdh/<object>.json`` (12 grasps per object).

Run: ``python scripts/make_grasp_sets.py [--count 12] [--seed 0]``. Uses the sampler that
planned them (:mod:`sdh_grasp_sampler`, beside this script) with its default settings
(fingertip grasps: at most three contacts, one per finger link), seeded per object.
"""

from __future__ import annotations

import argparse

from sdh_grasp_sampler import GraspPlanner

from kinegrasp_env.world.grasps import save_grasps, shipped_grasp_file
from kinegrasp_env.world.objects import OBJECT_NAMES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=12)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("objects", nargs="*", default=list(OBJECT_NAMES))
    args = parser.parse_args()
    for index, name in enumerate(args.objects):
        planner = GraspPlanner(name)
        seed = args.seed + 1000 * OBJECT_NAMES.index(name)
        grasps = planner.plan(args.count, seed=seed, progress=True)
        planner.close()
        if len(grasps) < args.count:
            raise SystemExit(f"{name}: only {len(grasps)} grasps found")
        path = save_grasps(grasps, shipped_grasp_file(name),
                           generator="scripts/make_grasp_sets.py", seed=seed)
        print(path, index)


if __name__ == "__main__":
    main()
