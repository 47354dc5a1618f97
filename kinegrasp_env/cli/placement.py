"""``kinegrasp objects place``: where an object stands, and its support table.

``objects place NAME [--as NEW] [--position X Y Z] [--yaw DEG | --orientation X Y Z W]
[--table | --no-table]
[--table-size X Y] [--table-thickness T] [--force]``: an imported object's placement is
changed in its entry; a built-in object gets a placed copy (``--as NEW``), used by name like
any other object.
"""

from __future__ import annotations

import math

from kinegrasp_env.cli.common import CLIError, finite_float, positive_float, reported
from kinegrasp_env.wording import fixed


def table_setting(args):
    """The table asked for: a ``SupportTable``, None (``--no-table``) or ``KEEP``."""
    from kinegrasp_env.world.placement import KEEP
    from kinegrasp_env.world.support import TABLE_SIZE, SupportTable

    if args.no_table:
        if args.table or args.table_size or args.table_thickness:
            raise CLIError("--no-table cannot go with --table, --table-size or "
                           "--table-thickness")
        return None
    if not (args.table or args.table_size or args.table_thickness):
        return KEEP
    size = TABLE_SIZE if args.table_size is None else tuple(
        positive_float(v, "--table-size") for v in args.table_size)
    thickness = None if args.table_thickness is None else positive_float(
        args.table_thickness, "--table-thickness")
    return SupportTable(size, thickness)


def cmd_place(args) -> int:
    from kinegrasp_env.world.placement import place_object
    from kinegrasp_env.world.store import CatalogError

    position = None if args.position is None else [
        finite_float(v, "--position") for v in args.position]
    yaw = None if args.yaw is None else math.radians(finite_float(args.yaw, "--yaw"))
    orientation = None if args.orientation is None else [
        finite_float(v, "--orientation") for v in args.orientation]
    if yaw is not None and orientation is not None:
        raise CLIError("--yaw and --orientation both set the rotation: give one")
    table = table_setting(args)
    with reported(CatalogError, ValueError):  # unknown or built-in name, taken --as name
        name = place_object(args.name, as_name=args.as_name, position=position, yaw=yaw,
                            table=table, force=args.force, orientation=orientation)
    from kinegrasp_env.world.catalog_listing import placement_fields
    from kinegrasp_env.world.objects import load_object

    fields = placement_fields(load_object(name), rounded=False)  # a small turn is no default
    print(f"{name}: {placement_note(fields).lstrip('; ') or 'default placement, no table'}")
    return 0


def placement_note(row: dict) -> str:
    """``; at (x, y, z) m, yaw d deg`` when not the default placement, ``; on a table X x Y
    m`` when there is a table (empty otherwise), for a catalog row."""
    from kinegrasp_env.world.names import OBJECT_POSITION

    def metres(v) -> str:
        return "(" + ", ".join(fixed(x, 3) for x in v) + ")"

    note = ""
    if row["yaw"] is None:  # tilted
        note += (f"; at {metres(row['position'])} m, orientation ("
                 f"{', '.join(fixed(v, 4) for v in row['orientation'])})")
    elif any(abs(a - b) > 1e-9 for a, b in zip(row["position"], OBJECT_POSITION,
                                                 strict=True)) or abs(row["yaw"]) > 1e-9:
        yaw = round(math.degrees(row["yaw"]), 4) + 0.0  # no "-0", no "-5.7e-16"
        note += f"; at {metres(row['position'])} m, yaw {yaw:.4g} deg"
    if row["table"] is not None:
        sx, sy = row["table"]["size"]
        note += f"; on a {sx:.2f} x {sy:.2f} m table"
    return note


def add_place_command(actions) -> None:
    """Register ``objects place`` among the ``objects`` actions."""
    p = actions.add_parser(
        "place", help="set where an object stands (position, yaw or orientation) and its "
        "support table; for "
        "a built-in object, as a placed copy (--as NEW)")
    p.add_argument("name", help="a built-in, imported or placed object")
    p.add_argument("--as", dest="as_name", metavar="NEW",
                   help="write a placed copy under this name (required for built-in objects)")
    p.add_argument("--position", nargs=3, metavar=("X", "Y", "Z"),
                   help="the object frame's origin (centre of its base) in the robot's base "
                   "frame, metres (default: as now; built-in objects stand at 0.6 0 0.1)")
    p.add_argument("--yaw", metavar="DEG", help="rotation about the vertical, degrees (the "
                   "object then upright: a tilt set by --orientation is replaced)")
    p.add_argument("--orientation", nargs=4, metavar=("X", "Y", "Z", "W"),
                   help="the object frame's full orientation in the robot's base frame, a "
                   "unit quaternion (scalar last), as a data set gives it (instead of --yaw; "
                   "an object that is not upright stands without a support table)")
    p.add_argument("--table", action="store_true",
                   help="put a support table under the object (top at its base, reaching down "
                   "to the robot's base plane): a draw whose hand or arm starts in it is "
                   "start_collision and the planner avoids it")
    p.add_argument("--no-table", action="store_true", help="remove the support table")
    p.add_argument("--table-size", nargs=2, metavar=("X", "Y"),
                   help="the table top's size, metres (default 0.6 0.8; implies --table)")
    p.add_argument("--table-thickness", metavar="T",
                   help="the table's thickness, metres (default: down to the robot's base "
                   "plane; implies --table)")
    p.add_argument("--force", action="store_true", help="replace an existing --as object")
    p.set_defaults(func=cmd_place)
