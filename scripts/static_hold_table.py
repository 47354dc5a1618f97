"""The static hold check of the shipped grasps at sigma 0: for each robot and object, each
grasp's Q, the object's mass, the largest multiple of its weight the contacts carry within
the hand's effort limits (six gravity directions and the lift), and the directions held at
the object's own weight. Written into docs/guides/physics.md between
``<!-- static-hold:start -->`` and ``<!-- static-hold:end -->``.

    python scripts/static_hold_table.py [--objects cube drill]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from marked_section import write_between

from kinegrasp_env.montecarlo.robot_evaluate import make_engine
from kinegrasp_env.world.grasps import shipped_grasps, shipped_objects

PAGE = Path(__file__).resolve().parents[1] / "docs" / "guides" / "physics.md"
START, END = "<!-- static-hold:start -->", "<!-- static-hold:end -->"
DIRECTIONS = ("+x", "-x", "+y", "-y", "+z", "-z")


def rows(robot: str, obj: str) -> list[str]:
    grasps = shipped_grasps(obj) if robot == "kuka_sdh" else shipped_grasps(obj, robot=robot)
    engine_name = "pybullet" if robot == "kuka_sdh" else "fast"
    with make_engine(engine_name, robot, obj, static_hold=True) as engine:
        q = np.array([g.q0 for g in grasps], dtype=float)
        batch = engine.close_batch(q)
        draws = engine.scored(q, batch)
        check = engine.hold_check
        capacity = check.capacity(q, batch.joints, draws.points, draws.normals, draws.finger,
                                  draws.link)
        out = []
        for i, g in enumerate(grasps):
            held = "".join(d if ok else "." for d, ok in zip(DIRECTIONS, draws.held[i],
                                                             strict=True))
            out.append(f"| {robot} | {obj} {g.id} | {draws.quality[i]:.4f} | {check.mass:.3f} | "
                       f"{capacity[i]:.2f} | `{held}` |")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "drill"])
    args = parser.parse_args()
    lines = ["| robot | grasp | Q | mass kg | carries x weight | loads held (.: not held) |",
             "|---|---|---|---|---|---|"]
    for robot in ("kuka_sdh", "panda"):
        for obj in args.objects:
            if robot == "kuka_sdh" or obj in shipped_objects(robot):
                lines += rows(robot, obj)
    text = "\n".join(lines)
    print(text)
    write_between(PAGE, START, END, text)


if __name__ == "__main__":
    main()
