"""The static hold check of the shipped grasps at sigma 0: for each robot and object, each
grasp's Q, the object's mass, the largest multiple of its weight the contacts carry within
the hand's effort limits (six gravity directions and the lift), and the directions held at
the object's own weight. Written into docs/guides/physics.md between
``<!-- static-hold:start -->`` and ``<!-- static-hold:end -->``.

With ``--planned N``, a second table: for each robot and each object of ``--planned-objects``,
N grasps planned afresh (seed ``--plan-seed``; the Panda's antipodal planner with side
approaches allowed, ``min_downward`` -0.3; 4,000 pairs or approaches tried; the default
robot's by the approach planner, its pre-shapes drawn) and the largest multiple of the
weight any of them carries: whether a hand can hold an object at all, not only on its
shipped grasps. Written between
``<!-- static-hold-planned:start -->`` and ``<!-- static-hold-planned:end -->``.

    python scripts/static_hold_table.py [--objects cube drill] [--planned 40]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from marked_section import write_between

from kinegrasp_env.montecarlo.evaluate import make_engine
from kinegrasp_env.world.grasps import shipped_grasps, shipped_objects

PAGE = Path(__file__).resolve().parents[1] / "docs" / "guides" / "physics.md"
START, END = "<!-- static-hold:start -->", "<!-- static-hold:end -->"
PLANNED = "<!-- static-hold-planned:start -->", "<!-- static-hold-planned:end -->"
DIRECTIONS = ("+x", "-x", "+y", "-y", "+z", "-z")
ROBOTS = ("kuka_sdh", "panda")


def capacities(robot: str, obj: str, grasps: list) -> tuple[np.ndarray, np.ndarray,
                                                             np.ndarray, float]:
    """(Q (n,), carried multiple of the weight (n,), loads held at the weight (n, 6), mass
    in kg) of grasps at their nominal closing (the default robot through its description,
    by the reference engine; another robot by its fast engine)."""
    engine_name = "pybullet" if robot == "kuka_sdh" else "fast"
    with make_engine(engine_name, robot, obj, static_hold=True) as engine:
        q = np.array([g.q0 for g in grasps], dtype=float)
        batch = engine.close_batch(q)
        draws = engine.scored(q, batch)
        check = engine.hold_check
        carried = check.capacity(q, batch.joints, draws.points, draws.normals, draws.finger,
                                 draws.link)
        return draws.quality, carried, draws.held, check.mass


def held_text(held: np.ndarray) -> str:
    return "".join(d if ok else "." for d, ok in zip(DIRECTIONS, held, strict=True))


def rows(robot: str, obj: str) -> list[str]:
    grasps = shipped_grasps(obj) if robot == "kuka_sdh" else shipped_grasps(obj, robot=robot)
    quality, carried, held, mass = capacities(robot, obj, grasps)
    return [f"| {robot} | {obj} {g.id} | {quality[i]:.4f} | {mass:.3f} | {carried[i]:.2f} | "
            f"`{held_text(held[i])}` |" for i, g in enumerate(grasps)]


def planned(robot: str, obj: str, count: int, seed: int) -> list:
    """Up to ``count`` force-closure grasps of ``robot`` on ``obj`` planned afresh."""
    from kinegrasp_env.toolkit.grasp_planner import plan_grasps
    from kinegrasp_env.toolkit.plan_checks import PlannerSettings

    settings = PlannerSettings(attempts=4000, surface_samples=800, min_downward=-0.3)
    return plan_grasps(robot, obj, count=count, seed=seed, settings=settings)


def planned_row(robot: str, obj: str, count: int, seed: int) -> str:
    grasps = planned(robot, obj, count, seed)
    if not grasps:
        return f"| {robot} | {obj} | | 0 | | | |"
    _, carried, held, mass = capacities(robot, obj, grasps)
    best = int(np.argmax(carried))
    return (f"| {robot} | {obj} | {mass:.3f} | {len(grasps)} | {np.median(carried):.2f} | "
            f"{carried[best]:.2f} | `{held_text(held[best])}` |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "drill"])
    parser.add_argument("--planned", type=int, default=0,
                        help="grasps to plan per robot and object (0: no second table)")
    parser.add_argument("--planned-objects", nargs="+", default=["drill", "spray_flask"])
    parser.add_argument("--plan-seed", type=int, default=1)
    args = parser.parse_args()
    lines = ["| robot | grasp | Q | mass kg | carries x weight | loads held (.: not held) |",
             "|---|---|---|---|---|---|"]
    for robot in ROBOTS:
        for obj in args.objects:
            if robot == "kuka_sdh" or obj in shipped_objects(robot):
                lines += rows(robot, obj)
    text = "\n".join(lines)
    print(text)
    write_between(PAGE, START, END, text)
    if args.planned:
        lines = ["| robot | object | mass kg | grasps planned | carries x weight: median | "
                 "best | its loads held |", "|---|---|---|---|---|---|---|"]
        for robot in ROBOTS:
            for obj in args.planned_objects:
                lines.append(planned_row(robot, obj, args.planned, args.plan_seed))
                print(lines[-1], flush=True)
        write_between(PAGE, *PLANNED, "\n".join(lines))


if __name__ == "__main__":
    main()
