"""Which grasps ``reproduce`` evaluates: ``--object`` (default: every object the robot has
shipped grasps of) and ``--grasps``, a count of the shipped grasps or a grasp file
(``kinegrasp plan``'s output), which is how an imported object (it has no shipped set) is
drawn.
"""

from __future__ import annotations

from pathlib import Path

from kinegrasp_env.cli.common import CLIError, reported

#: ``reproduce fig9|fig10``: grasps (fig9) or arm configurations of one grasp (fig10) per
#: object.
FIGURE_GRASPS = 10
#: ``reproduce fig7``: arm configurations of one grasp per object (equal to
#: ``toolkit.experiments.fig7``'s default, tested).
FIG7_VARIANTS = 8
#: ``reproduce table1``'s object without --object, and its number of grasps without --grasps.
TABLE1_OBJECT, TABLE1_GRASPS = "spray_flask", "5"


def is_count(text: str) -> bool:
    """Whether a ``reproduce --grasps`` value is a number (else it names a grasp file)."""
    return text.strip().lstrip("+-").isdigit()


def imported_without_grasps(name: str, robot: str) -> CLIError:
    """The one-line error of ``reproduce`` on an imported object without a grasp file (it
    has no shipped set of ``robot``): how to make one and give it."""
    from kinegrasp_env.world.grasps import plan_command

    return CLIError(f"{name} is an imported object and has no shipped grasp set; give its "
                    f"grasps with --grasps FILE (e.g. from `{plan_command(robot, name, True)}`)")


def grasp_file(path: str) -> list:
    """The grasps of ``--grasps FILE`` (``kinegrasp plan``'s format): at least one, all of
    one object; a bad file is a one-line :class:`CLIError`."""
    from kinegrasp_env.world.grasps import load_grasps

    if Path(path).is_dir():
        raise CLIError(f"--grasps {path} is a folder, not a grasp file")
    with reported(ValueError):  # load_grasps: missing file, bad JSON, bad fields
        grasps = load_grasps(path)
    if not grasps:
        raise CLIError(f"--grasps {path}: the file holds no grasps")
    other = next((g for g in grasps if g.object != grasps[0].object), None)
    if other is not None:
        raise CLIError(f"--grasps {path}: grasps of {grasps[0].object} and {other.object}; "
                       "give a file of one object's grasps")
    return grasps


def written(out: str, names: list[str]) -> str:
    """``written: <out>/a, b`` for the files that exist (a figure that failed is left out;
    its warning was printed)."""
    present = [name for name in names if (Path(out) / name).exists()]
    return f"written: {out}/" + ", ".join(present)
