"""Environment steps per second (KineGrasp-v0, one process), every robot alike.

Run: ``python benchmarks/bench_env.py [--steps 40] [--robot kuka_sdh --robot panda]``.
Both engines, side by side in one run, every object's engine built in the env (the fast
engine's grids built and kernels compiled) before the clock starts. Steps/s of wall time,
and of the process's CPU time (what a machine shared with other work still shows).

Per robot: n_draws = 64 (the env's default) and 256 over the env's drawn tasks; target >= 100
steps/s at 64 draws with the fast engine. Then the fast engine at 64 draws one object at a
time (the mixed figure moves with the env's draw of tasks: its objects cost 2x apart).

The figures (steps/s, seconds) also go to ``benchmarks/results/bench_env.json``
(``--json-out PATH``, ``--no-json``): ``steps`` and ``fast_64_draws_per_object``, a ``robot``
column each.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
from results_file import add_options, settings, write_result

import kinegrasp_env  # noqa: F401  (registers the envs)

#: The robots timed when no ``--robot`` is given.
ROBOTS = ("kuka_sdh", "panda")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--robot", action="append", default=None, metavar="NAME",
                        help="a catalog robot to time (repeatable; default: "
                             f"{' and '.join(ROBOTS)})")
    add_options(parser, __file__)
    args = parser.parse_args()
    if args.steps < 1:
        parser.error(f"--steps must be >= 1, got {args.steps}")
    from kinegrasp_env.robot.catalog import robot_names

    args.robot = list(dict.fromkeys(args.robot or ROBOTS))
    for robot in args.robot:
        if robot not in robot_names():
            parser.error(f"unknown robot {robot!r}; known robots: {', '.join(robot_names())}")
    result = {"steps": [], "fast_64_draws_per_object": []}
    for robot in args.robot:
        steps_rows, object_rows = robot_steps(robot, args.steps)
        result["steps"] += steps_rows
        result["fast_64_draws_per_object"] += object_rows
    if not args.no_json:
        write_result(__file__, {**result, "settings": settings(args)}, args.json_out)


def timed_steps(env, steps: int, options: dict | None = None) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of ``steps`` random steps of ``env`` (the done signal
    off; a truncated episode is reset with ``options``)."""
    start, cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        action = env.action_space.sample()
        action[1] = -1.0
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset(options=options)
    return time.perf_counter() - start, time.process_time() - cpu


def steps_row(prefix: str, engine: str, n_draws: int, steps: int, wall: float, cpu: float,
              target_draws: int) -> dict:
    """Print one timed run (after ``prefix``) and return its row: steps/s of wall and CPU
    time, seconds a step."""
    print(f"{prefix}{engine:8s} n_draws = {n_draws:3d}: {steps / wall:6.1f} steps/s "
          f"({wall / steps * 1e3:6.1f} ms/step; {steps / cpu:6.1f} steps/s of CPU time; "
          f"target >= 100 steps/s at {target_draws}, fast)")
    return {"engine": engine, "n_draws": n_draws, "steps": steps, "steps_per_s": steps / wall,
            "s_per_step": wall / steps, "steps_per_cpu_s": steps / cpu}


def robot_steps(robot: str, steps: int) -> tuple[list[dict], list[dict]]:
    """Steps/s of KineGrasp-v0 with ``robot``: both engines at 64 and 256 draws over the
    env's drawn tasks, then the fast engine at 64 draws per object."""
    from kinegrasp_env.world.grasps import shipped_objects

    objects = shipped_objects(robot)
    steps_rows, object_rows = [], []

    def warmed(engine: str, n_draws: int):
        """The env with every object's engine built (grids, compiled kernels, worlds)."""
        env = gym.make("KineGrasp-v0", robot=robot, n_draws=n_draws, engine=engine)
        env.action_space.seed(0)
        for name in objects:
            env.reset(seed=0, options={"object": name})
            env.step(env.action_space.sample())
        env.reset(seed=0)
        return env

    for engine, n_draws in (("pybullet", 64), ("fast", 64), ("pybullet", 256), ("fast", 256)):
        env = warmed(engine, n_draws)
        wall, cpu = timed_steps(env, steps)
        env.close()
        steps_rows.append({"robot": robot, **steps_row(f"{robot:8s} ", engine, n_draws, steps,
                                                       wall, cpu, target_draws=64)})
    env = warmed("fast", 64)
    for name in objects:
        options = {"object": name}
        env.reset(seed=0, options=options)
        wall, _ = timed_steps(env, steps, options)
        print(f"{robot:8s} fast     n_draws =  64, {name:12s}: {steps / wall:6.1f} steps/s "
              f"({wall / steps * 1e3:6.1f} ms/step)")
        object_rows.append({"robot": robot, "object": name, "n_draws": 64,
                            "steps_per_s": steps / wall, "s_per_step": wall / steps})
    env.close()
    return steps_rows, object_rows


if __name__ == "__main__":
    main()
