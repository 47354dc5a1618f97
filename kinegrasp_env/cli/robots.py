"""Robot commands: ``robots`` (list the built-in and the user's robots), ``robots add`` (check
a robot description YAML and copy it, its URDF and meshes into the catalog), ``robots show``
(draw one) and ``robots remove``.
"""

from __future__ import annotations

import json
import sys

from kinegrasp_env.cli.common import plural, reported
from kinegrasp_env.cli.output_paths import PNG_SUFFIXES, output_file


def cmd_list(args) -> int:
    from kinegrasp_env.robot.catalog import catalog_rows
    from kinegrasp_env.robot.description import RobotDescriptionError

    with reported(RobotDescriptionError):  # a user entry that no longer checks out
        rows = catalog_rows()
    if args.json:
        print(json.dumps(rows))
        return 0
    width = max(8, *(len(r["name"]) for r in rows))
    palm = max(9, *(len(r["palm_link"]) for r in rows))
    print(f"{'name':<{width}} {'source':<8} {'arm DOF':>7}  {'palm link':<{palm}}  "
          f"{'contact':<7}  hand joints")
    for r in rows:
        print(f"{r['name']:<{width}} {r['source']:<8} {r['arm_dof']:>7}  "
              f"{r['palm_link']:<{palm}}  {r['contact_model']:<7}  "
              f"{len(r['hand_joints'])}: {', '.join(r['hand_joints'])}")
    return 0


def cmd_add(args) -> int:
    from kinegrasp_env.robot.catalog import add_robot, moved_collisions
    from kinegrasp_env.robot.description import RobotDescriptionError

    with reported(RobotDescriptionError):  # a bad description, a name taken
        robot, folder = add_robot(args.path, force=args.force)
    print(f"{robot.name}: {robot.arm_dof} arm joints, palm {robot.palm_link}, "
          f"{plural(len(robot.hand_joints), 'hand joint')}, "
          f"{plural(len(robot.fingers), 'finger')} ({', '.join(robot.fingertip_links)}), "
          f"{plural(len(robot.meshes), 'mesh reference')}")
    print(f"  stored in {folder}")
    for pad, link in moved_collisions(folder).items():
        print(f"  {pad}'s collision shapes (fixed to {link}, which a closing joint moves) "
              f"are {link}'s in the stored URDF: the finger touches with them")
    from kinegrasp_env.robot.description import never_in_force_closure

    reason = never_in_force_closure(robot)
    if reason is not None:
        print(f"  note: {reason}; plan will find no grasp", file=sys.stderr)
    return 0


def cmd_show(args) -> int:
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.robot.picture import draw_robot

    out = output_file(args.out, "--out", figure=False, suffixes=PNG_SUFFIXES)
    with reported(RobotDescriptionError):  # unknown name
        robot = load_robot(args.name)
    from kinegrasp_env.robot.hand_frame import hand_frame

    frame = hand_frame(robot)
    path = draw_robot(robot, out, frame=frame)
    print(f"{robot.name}: drawn at its open pre-shape in {path} (right: the hand, its approach "
          "axis blue, closing directions red)")
    print("\n".join(frame.lines()))
    if robot.preshapes:
        print("pre-shapes the planners draw (each line one draw; other hand joints at open):")
        print("\n".join(f"  {draw.text()}" for draw in robot.preshapes))
    else:
        print("pre-shape the planners close from: the open one (no preshapes)")
    return 0


def cmd_remove(args) -> int:
    from kinegrasp_env.robot.catalog import remove_robot
    from kinegrasp_env.robot.description import RobotDescriptionError

    with reported(RobotDescriptionError):  # a built-in or unknown name
        folder = remove_robot(args.name)
    print(f"{args.name} removed ({folder})")
    return 0


def add_commands(sub) -> None:
    """Register ``robots`` and its actions ``add``, ``show``, ``remove``."""
    p = sub.add_parser("robots", help="list the built-in and added robots; add one from a "
                       "description YAML (add), draw (show) or remove one")
    p.add_argument("--json", action="store_true", help="print the catalog as JSON")
    p.set_defaults(func=cmd_list)
    actions = p.add_subparsers(dest="action", metavar="{add,show,remove}")

    a = actions.add_parser("add", help="check a robot description (YAML next to a URDF) and "
                           "copy it, the URDF and its meshes into the catalog")
    a.add_argument("path", help="the description YAML")
    a.add_argument("--force", action="store_true",
                   help="replace an added robot of the same name")
    a.set_defaults(func=cmd_add)

    s = actions.add_parser("show", help="draw a robot at its open pre-shape (PNG)")
    s.add_argument("name", help="a built-in or added robot")
    s.add_argument("--out", required=True, help="the PNG file to write")
    s.set_defaults(func=cmd_show)

    r = actions.add_parser("remove", help="delete an added robot")
    r.add_argument("name", help="the added robot's name")
    r.set_defaults(func=cmd_remove)
