"""What a support table changes: the built-in objects' shipped grasps and noisy draws on a
table, the table test's cost, and plans made with the table.

For each built-in object, a placed copy on the default table (0.6 x 0.8 m, top at the
object's base, down to the robot's base plane) in a private catalog: how many of its 12
shipped grasps start in the table at zero noise, the fraction of draws in the table and
P(FC) with and without it at two sigmas (fast engine, common random numbers), and the fast
engine's draws/s with and without the table (side by side, one process). Then ``--plan N``
grasps planned on the cube and the drill with the table: each checked at zero noise (force
closure, open and closed hand clear of the table).

    python benchmarks/table_effect.py [--draws 200] [--plan 5]

The figures (fractions, P(FC), draws/s, seconds) also go to
``benchmarks/results/table_effect.json`` (``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np
from results_file import add_options, settings, write_result


def draws_per_second(engine, q: np.ndarray, repeats: int = 3) -> float:
    engine.run(q[:8])  # warm (kernels, probe)
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        engine.run(q)
        best = min(best, time.perf_counter() - t)
    return len(q) / best


def object_rows(name: str, draws: int) -> dict:
    from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, START_COLLISION
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
    from kinegrasp_env.world.grasps import shipped_grasps

    placed = f"{name}_on_table"
    q0 = np.array([g.q0 for g in shipped_grasps(name)])
    bare = make_engine("fast", DEFAULT_ROBOT, name)
    tabled = make_engine("fast", DEFAULT_ROBOT, placed)
    nominal = tabled.in_table(q0)
    cells, record = [], {"object": name, "shipped_in_table": int(nominal.sum()),
                         "shipped": len(q0),
                         "shipped_in_table_indices": np.flatnonzero(nominal).tolist()}
    for sigma in (0.0133, 0.0333):
        q = np.repeat(q0, draws, axis=0)
        q[:, :7] += np.random.default_rng(7).normal(0.0, sigma, (len(q), 7))
        a, b = bare.run(q), tabled.run(q)
        in_table = tabled.in_table(q)
        cells.append(f"{in_table.mean():.3f} / {(a.outcome == FORCE_CLOSURE).mean():.3f} -> "
                     f"{(b.outcome == FORCE_CLOSURE).mean():.3f}")
        assert np.all(b.outcome[in_table] == START_COLLISION)
        record |= {f"in_table_{sigma}": in_table.mean(),
                   f"p_fc_without_{sigma}": (a.outcome == FORCE_CLOSURE).mean(),
                   f"p_fc_with_{sigma}": (b.outcome == FORCE_CLOSURE).mean()}
    q = np.repeat(q0, 100, axis=0)
    q[:, :7] += np.random.default_rng(8).normal(0.0, 0.0133, (len(q), 7))
    rates = draws_per_second(bare, q), draws_per_second(tabled, q)
    speed = f"{rates[0]:.0f} / {rates[1]:.0f}"
    print(f"| {name} | {int(nominal.sum())}/12 ({', '.join(map(str, np.flatnonzero(nominal)))}) "
          f"| {cells[0]} | {cells[1]} | {speed} |", flush=True)
    return {**record, "fast_draws_per_s_without": rates[0], "fast_draws_per_s_with": rates[1]}


def plan_rows(name: str, count: int) -> dict:
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
    from kinegrasp_env.toolkit.grasp_planner import plan_grasps

    t = time.perf_counter()
    grasps = plan_grasps("kuka_sdh", f"{name}_on_table", count=count, seed=0)
    seconds = time.perf_counter() - t
    engine = make_engine("pybullet", DEFAULT_ROBOT, f"{name}_on_table")
    q0 = np.array([g.q0 for g in grasps])
    draws = engine.run(q0)
    closed = np.concatenate([q0[:, :7], draws.hand], axis=1)
    open_in = engine.in_table(engine.check(q0))
    closed_in = engine.in_table(engine.check(closed))
    print(f"| {name} on the table | {len(grasps)} in {seconds:.0f} s | "
          f"{int((draws.outcome == 3).sum())}/{len(grasps)} force closure | open hand in the "
          f"table: {int(open_in.sum())}, closed hand: {int(closed_in.sum())} |", flush=True)
    engine.close()
    return {"object": name, "planned": len(grasps), "plan_s": seconds,
            "force_closure": int((draws.outcome == 3).sum()),
            "open_hand_in_table": int(open_in.sum()), "closed_hand_in_table": int(closed_in.sum())}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=200, help="draws per grasp and sigma")
    parser.add_argument("--plan", type=int, default=5, help="grasps to plan per object")
    add_options(parser, __file__)
    args = parser.parse_args()
    os.environ["KINEGRASP_HOME"] = tempfile.mkdtemp(prefix="kinegrasp_table_")
    from kinegrasp_env.world.objects import OBJECT_NAMES
    from kinegrasp_env.world.placement import place_object
    from kinegrasp_env.world.support import SupportTable

    for name in OBJECT_NAMES:
        place_object(name, as_name=f"{name}_on_table", table=SupportTable())
    print(f"{args.draws} draws per grasp and sigma, fast engine, one process")
    print("| object | shipped grasps in the table at zero noise | sigma 0.0133: in the table / "
          "P(FC) without -> with | sigma 0.0333: same | fast draws/s without / with |")
    print("|---|---|---|---|---|")
    record = {"objects": [object_rows(name, args.draws) for name in OBJECT_NAMES]}
    if args.plan:
        print("\n| planned | grasps | at zero noise | in the table |\n|---|---|---|---|")
        record["planned"] = [plan_rows(name, args.plan) for name in ("cube", "drill")]
    if not args.no_json:
        write_result(__file__, {**record, "settings": settings(args)}, args.json_out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
