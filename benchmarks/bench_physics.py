"""Physics engine throughput: draws/s of the closing alone and of the holding test.

For each built-in object, one shipped grasp of ``--robot``, at two joint-noise sigmas, the
same draws as ``kinegrasp evaluate`` would take: the physics engine's ``run`` (closing under
dynamics, contacts, Q) and the holding test's ``run_hold`` (the closing on the pinned object,
then grip, release, six gravity directions and the lift), one process, engines built
beforehand (world construction reported separately); draws/s of wall time and the process's
CPU time per draw (the cost on an unshared core). Also P(FC) of the physics engine next to
the kinematic (fast) engine's on the same draws, P(hold), and whether the same
configurations give the same numbers twice.

    python benchmarks/bench_physics.py [--robot kuka_sdh] [--draws 20] [--grasp 0]
        [--sigmas 0.0133 0.0333]

The figures (seconds, draws/s, P(FC), P(hold)) also go to
``benchmarks/results/bench_physics.json`` (``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from results_file import add_options, settings, write_result

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.evaluate import robot_configurations
from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine
from kinegrasp_env.physics.protocol import HoldProtocol
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import OBJECT_NAMES


def timed(fn):
    """(fn(), wall seconds, CPU seconds of this process): on a shared machine the CPU time
    is the load-independent cost."""
    start, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - start, time.process_time() - cpu


def bench_object(name: str, args) -> tuple[dict, list[dict]]:
    """Print one object's lines; return its world row and its per-sigma rows."""
    grasp = shipped_grasps(name, robot=args.robot)[args.grasp]
    engine, build, _ = timed(lambda: make_engine("physics", args.robot, name))
    holder = RobotHoldEngine(args.robot, name, protocol=HoldProtocol())
    fast = make_engine("fast", args.robot, name)
    mass = engine.hold.world.mass
    print(f"{name}: world built in {build:.2f} s (mass {mass:.3f} kg)")
    rows = []
    for sigma in args.sigmas:
        q = robot_configurations(grasp, engine, sigma=sigma, n=args.draws, seed=args.seed)
        closed, t_run, cpu_run = timed(lambda q=q: engine.run(q))
        (pinned, hold), t_lift, cpu_lift = timed(lambda q=q: holder.run_hold(q))
        again = engine.run(q)
        _, hold_again = holder.run_hold(q)
        kinematic = fast.run(q)
        same = (np.array_equal(closed.quality, again.quality)
                and np.array_equal(hold.grip_shift, hold_again.grip_shift, equal_nan=True)
                and np.array_equal(hold.outcome, hold_again.outcome))
        n = len(q)
        p_fc, p_kin = (np.mean(d.outcome == FORCE_CLOSURE) for d in (closed, kinematic))
        print(f"  sigma {sigma:.4f}: closing {n / t_run:5.2f} draws/s (CPU "
              f"{cpu_run / n * 1e3:4.0f} ms/draw), holding test {n / t_lift:5.2f} draws/s "
              f"(CPU {cpu_lift / n * 1e3:5.0f} ms/draw) | P(FC) physics {p_fc:.2f} (pinned "
              f"{np.mean(pinned.outcome == FORCE_CLOSURE):.2f}), kinematic {p_kin:.2f}, "
              f"P(hold) {hold.held.mean():.2f} | same numbers twice: {same}")
        rows.append({"object": name, "sigma": sigma, "draws": n,
                     "closing_draws_per_s": n / t_run, "closing_cpu_s_per_draw": cpu_run / n,
                     "holding_draws_per_s": n / t_lift, "holding_cpu_s_per_draw": cpu_lift / n,
                     "p_fc_physics": p_fc,
                     "p_fc_pinned": np.mean(pinned.outcome == FORCE_CLOSURE),
                     "p_fc_kinematic": p_kin, "p_hold": hold.held.mean(),
                     "same_numbers_twice": bool(same)})
    world = {"object": name, "world_build_s": build, "mass_kg": mass}
    for each in (engine, holder, fast):
        each.close()
    return world, rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="kuka_sdh")
    parser.add_argument("--draws", type=int, default=20)
    parser.add_argument("--grasp", type=int, default=0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sigmas", type=float, nargs="+", default=[0.0133, 0.0333])
    parser.add_argument("--objects", nargs="+", default=list(OBJECT_NAMES))
    add_options(parser, __file__)
    args = parser.parse_args()
    worlds, rows = [], []
    for name in args.objects:
        world, object_rows = bench_object(name, args)
        worlds.append(world)
        rows += object_rows
    if not args.no_json:
        write_result(__file__, {"worlds": worlds, "sigmas": rows, "settings": settings(args)},
                     args.json_out)


if __name__ == "__main__":
    main()
