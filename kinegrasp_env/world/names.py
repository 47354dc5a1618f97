"""The catalog's names without its geometry: built-in and imported object names, where an
object stands by default, and the size of each built-in object's shipped grasp set.

Cheap on purpose (no NumPy, trimesh or numba): the command line builds its ``--object``
choices and ``--help`` texts from it before any work. :mod:`kinegrasp_env.world.objects` and
:mod:`kinegrasp_env.world.grasps` use the same definitions.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

from kinegrasp_env.assets import asset_path
from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.world.store import imported_folder, imported_names

#: The catalog, in the paper's order (cube, spray flask, power drill, a household object).
OBJECT_NAMES: tuple[str, ...] = ("cube", "spray_flask", "drill", "mug")
#: Where the object frame sits in the world (robot base) frame: 0.6 m in front of the
#: robot, on a table 0.1 m above the robot's base plane.
OBJECT_POSITION: tuple[float, float, float] = (0.6, 0.0, 0.1)


def object_names() -> tuple[str, ...]:
    """Every object name: the built-in ones, then the imported ones (sorted)."""
    return OBJECT_NAMES + tuple(n for n in imported_names() if n not in OBJECT_NAMES)


def is_object(name: str) -> bool:
    """Whether ``name`` is a built-in or imported object."""
    return name in OBJECT_NAMES or imported_folder(name) is not None


def unknown_object(name: str) -> ValueError:
    """The error for a name that is no object (lists the known ones)."""
    return ValueError(f"unknown object {name!r}; known objects: {', '.join(object_names())} "
                      "(import one with `kinegrasp objects add FILE`)")


def shipped_grasp_file(name: str, robot: str = DEFAULT_ROBOT) -> Path:
    """The shipped grasp file of built-in object ``name`` for catalog robot ``robot``:
    ``assets/grasps/<robot>/<name>.json`` (whether it exists is not checked here)."""
    return asset_path("grasps", robot, f"{name}.json")


@cache
def shipped_grasp_count(name: str) -> int:
    """How many grasps built-in object ``name``'s shipped set holds (the file's ``grasps``
    list, not checked here: :func:`kinegrasp_env.world.grasps.shipped_grasps` reads it)."""
    with open(shipped_grasp_file(name), encoding="utf-8") as fh:
        return len(json.load(fh)["grasps"])
