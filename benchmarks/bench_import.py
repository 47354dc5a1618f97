"""Importing meshes nobody here wrote, and what imported objects cost the engines.

Run: ``python benchmarks/bench_import.py [--home DIR] [--grasps 5] [--draws 200]
[--reference-draws 40] [--only duck bunny]`` (tens of minutes on 2 cores: CoACD and the
planner dominate; ``--home`` keeps the catalog, so a second run reuses the imports).

1. Import five meshes of ``pybullet_data`` (duck.obj, bunny.obj scaled from its 2 m to 0.2 m,
   objects/mug.obj, teddy2_VHACD_CHs.obj and random_urdfs/000/000.urdf) with the default
   settings: wall time, parts, size, r_max and the deviation of the parts from the mesh.
2. Plan ``--grasps`` force-closure grasps of each (``kinegrasp plan``'s planner): time and
   count.
3. Grasp 0 of each, ``--draws`` noisy draws (sigma = 0.0133 rad) with the fast engine and
   ``--reference-draws`` with the pybullet engine, on one process, engines warm: draws/s,
   P(FC) of each engine, next to the built-in objects' shipped grasp 0, with the number of
   convex parts (both engines' cost per draw grows with the parts near the fingers).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np
import pybullet_data

#: (file in pybullet_data, --scale, name)
MESHES = (
    ("duck.obj", 0.05, "duck"),
    ("bunny.obj", 0.1, "bunny"),
    ("objects/mug.obj", 1.0, "pb_mug"),
    ("teddy2_VHACD_CHs.obj", 0.1, "teddy"),
    ("random_urdfs/000/000.urdf", 1.0, "blob000"),
)
SIGMA = 0.0133


def import_all(names: list[str]) -> list[str]:
    from kinegrasp_env.world.importer import ImportSettings, import_object

    done = []
    print(f"{'object':<8} {'import [s]':>10} {'parts':>5} {'size x, y, z [m]':<22} "
          f"{'r_max [m]':>9}  deviation [mm] lost max/mean, added max/mean")
    for file, scale, name in MESHES:
        if name not in names:
            continue
        path = os.path.join(pybullet_data.getDataPath(), file)
        result = import_object(path, name, ImportSettings(scale=scale))
        e, d = result.entry, result.entry["deviation"]
        seconds = e["import_seconds"]
        size = ", ".join(f"{v:.3f}" for v in e["size"])
        print(f"{name:<8} {seconds:>10.1f} {e['parts']:>5} {size:<22} {e['r_max']:>9.4f}  "
              f"{1e3 * d['missing_max']:.2f}/{1e3 * d['missing_mean']:.2f}, "
              f"{1e3 * d['added_max']:.2f}/{1e3 * d['added_mean']:.2f}"
              f"{'  (reused entry)' if result.reused else ''}", flush=True)
        done.append(name)
    return done


def plan_all(names: list[str], count: int) -> dict:
    from kinegrasp_env.toolkit.planner import GraspPlanner

    grasps = {}
    for name in names:
        planner = GraspPlanner(name)
        start = time.perf_counter()
        try:
            found = planner.plan(count, seed=0)
        finally:
            planner.close()
        grasps[name] = found
        print(f"{name:<8} plan: {len(found)} force-closure grasps in "
              f"{time.perf_counter() - start:.1f} s; nominal Q "
              + ", ".join(f"{g.q_nominal:.4f}" for g in found), flush=True)
    return grasps


def rate(engine_name: str, name: str, q0: np.ndarray, draws: int) -> tuple[float, float]:
    """(draws/s, P(FC)) of ``draws`` noisy draws of q0 through one warm engine."""
    from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, make_engine
    from kinegrasp_env.montecarlo.evaluate import chunk_noise
    from kinegrasp_env.sampling.noise import JointNoise

    engine = make_engine(engine_name, name)
    try:
        engine.run(np.repeat(q0[None], 4, axis=0))  # warm-up: grid, kernels, bodies
        q = np.repeat(q0[None], draws, axis=0)
        q[:, :7] += chunk_noise(JointNoise(SIGMA), 0, 0, draws)
        start = time.perf_counter()
        out = engine.run(q)
        wall = time.perf_counter() - start
    finally:
        engine.close()
    return draws / wall, float(np.mean(out.outcome == FORCE_CLOSURE))


def engines(grasps: dict, draws: int, reference: int) -> None:
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import OBJECT_NAMES, load_object

    rows = [(name, shipped_grasps(name)[0]) for name in OBJECT_NAMES]
    rows += [(name, found[0]) for name, found in grasps.items() if found]
    print(f"\n{'object':<12} {'parts':>5} {'fast draws/s':>12} {'P(FC)':>6} "
          f"{'pybullet draws/s':>16} {'P(FC)':>6}   (grasp 0, sigma {SIGMA} rad, 1 process)")
    for name, grasp in rows:
        fast, p_fast = rate("fast", name, grasp.q0, draws)
        slow, p_slow = rate("pybullet", name, grasp.q0, reference)
        print(f"{name:<12} {len(load_object(name).parts):>5} {fast:>12.0f} {p_fast:>6.3f} "
              f"{slow:>16.0f} {p_slow:>6.3f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--home", help="catalog folder ($KINEGRASP_HOME; default: a new "
                        "temporary one)")
    parser.add_argument("--grasps", type=int, default=5, help="grasps to plan per object")
    parser.add_argument("--draws", type=int, default=2000, help="fast-engine draws")
    parser.add_argument("--reference-draws", type=int, default=200,
                        help="pybullet-engine draws")
    parser.add_argument("--only", nargs="*", default=[m[2] for m in MESHES],
                        help="meshes to use, by name")
    args = parser.parse_args()
    os.environ["KINEGRASP_HOME"] = args.home or tempfile.mkdtemp(prefix="kinegrasp-home-")
    print(f"catalog: {os.environ['KINEGRASP_HOME']}")
    names = import_all(args.only)
    grasps = plan_all(names, args.grasps) if args.grasps > 0 else {}
    engines(grasps, args.draws, args.reference_draws)


if __name__ == "__main__":
    main()
