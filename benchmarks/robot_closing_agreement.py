"""The physics closing against the kinematic jaw-closing model of a description robot: for
each shipped grasp of the robot (sigma 0, the nominal configuration), the contacts of the
holding test's closing (the jaws' motors on the pinned object, before the grip; pybullet)
against those of the kinematic reference closing (``RobotWorld.auto_close``), per contact:
the point distance (mm) and the normal angle (degrees), object frame
(:mod:`kinegrasp_env.physics.robot_agreement`).

    python benchmarks/robot_closing_agreement.py [--robot panda] [--objects cube]

The figures also go to ``benchmarks/results/robot_closing_agreement.json`` (``--json-out
PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from results_file import add_options, settings, write_result


def grasp_rows(robot: str, object_name: str) -> list[dict]:
    from kinegrasp_env.closing.generic_reference import RobotWorld
    from kinegrasp_env.physics.protocol import HoldProtocol
    from kinegrasp_env.physics.robot_agreement import closing_agreement
    from kinegrasp_env.physics.robot_hold import RobotHold
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import load_object

    description, obj = load_robot(robot), load_object(object_name)
    simulator = RobotHold(description, obj, 0.5, HoldProtocol())
    kinematic = RobotWorld(description, obj)
    rows = []
    try:
        for index, grasp in enumerate(shipped_grasps(object_name, robot)):
            agreement = closing_agreement(simulator, kinematic, grasp.q0)
            row = {"object": object_name, "grasp": index,
                   "contacts": len(agreement.pairs),
                   "unpaired": len(agreement.physics_only) + len(agreement.kinematic_only),
                   "max_distance_mm": round(agreement.max_distance * 1e3, 3),
                   "max_angle_deg": round(float(np.degrees(agreement.max_angle)), 3),
                   "distances_mm": [round(p.distance * 1e3, 3) for p in agreement.pairs],
                   "angles_deg": [round(float(np.degrees(p.angle)), 3)
                                  for p in agreement.pairs]}
            print(f"| {object_name} {index} | {row['contacts']} | {row['unpaired']} | "
                  f"{', '.join(f'{d:.2f}' for d in row['distances_mm'])} | "
                  f"{', '.join(f'{a:.2f}' for a in row['angles_deg'])} |")
            rows.append(row)
    finally:
        simulator.close()
        kinematic.close()
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda", help="a catalog robot (not kuka_sdh)")
    parser.add_argument("--objects", nargs="+", default=["cube"],
                        help="objects with shipped grasps of the robot")
    add_options(parser, __file__)
    args = parser.parse_args()
    print(f"robot {args.robot}, sigma 0: physics closing against the kinematic closing")
    print("| grasp | paired contacts | unpaired | point distance mm | normal angle deg |")
    print("|---|---|---|---|---|")
    rows = [row for name in args.objects for row in grasp_rows(args.robot, name)]
    record = {"grasps": rows,
              "max_distance_mm": max(r["max_distance_mm"] for r in rows),
              "max_angle_deg": max(r["max_angle_deg"] for r in rows)}
    print(f"largest point distance {record['max_distance_mm']:.3f} mm, largest normal angle "
          f"{record['max_angle_deg']:.3f} deg")
    if not args.no_json:
        write_result(__file__, {**record, "settings": settings(args)}, args.json_out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
