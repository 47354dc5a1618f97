"""Changing where an object stands (``kinegrasp objects place``).

An imported object's placement (pose and support table) is part of its catalog entry and is
rewritten in place (``entry.json`` through a temporary file and a rename: readers see the old
entry or the new one). A built-in object cannot be changed; ``--as NEW`` makes a *placed
object*: a catalog entry holding only ``base`` (the object whose geometry it has), ``pose``
and ``table``, loaded by :func:`kinegrasp_env.world.objects.load_object` as the base object
under the new name. Placed copies of imported objects work the same way.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.world import objects
from kinegrasp_env.world.importer import publish
from kinegrasp_env.world.store import (
    ENTRY_FILE,
    FORMAT_VERSION,
    CatalogError,
    catalog_dir,
    imported_folder,
    read_entry,
    valid_name,
)
from kinegrasp_env.world.support import SupportTable, is_upright, placement_pose, pose_yaw

#: ``table`` argument of :func:`place_object` meaning "leave the table as it is".
KEEP = "keep"


@dataclass(frozen=True)
class Placement:
    """Where an object stands: ``pose`` (4, 4) object frame in the world (robot base) frame
    and its support ``table`` (None: none)."""

    pose: np.ndarray
    table: SupportTable | None

    def to_entry(self) -> dict:
        """The entry fields ``pose`` (4x4 nested list) and ``table``."""
        return {"pose": self.pose.tolist(),
                "table": None if self.table is None else self.table.to_dict()}


#: A quaternion's norm may differ from 1 by this much (a data set's rounding).
UNIT_TOL = 1e-6


def orientation_matrix(quaternion) -> np.ndarray:
    """(3, 3) rotation of a unit quaternion (4,) [x, y, z, w] (scalar last).

    Raises:
        ValueError: not 4 finite numbers, or a norm further than :data:`UNIT_TOL` from 1.
    """
    from kinegrasp_env.robot.palm_pose import quaternion_matrix

    quat = np.asarray(quaternion, dtype=float)
    if quat.shape != (4,) or not np.all(np.isfinite(quat)):
        raise ValueError(f"an orientation is a quaternion of 4 finite numbers x y z w, got "
                         f"{np.atleast_1d(quat).tolist()}")
    norm = float(np.linalg.norm(quat))
    if abs(norm - 1.0) > UNIT_TOL:
        raise ValueError(f"the orientation quaternion {quat.tolist()} is not a unit one "
                         f"(norm {norm:.9g})")
    return quaternion_matrix(quat / norm)


def new_placement(current: objects.GraspObject, position=None, yaw: float | None = None,
                  table: SupportTable | str | None = KEEP, orientation=None) -> Placement:
    """``current``'s placement with the given fields changed (None / :data:`KEEP`: as now):
    the position, the rotation (``yaw`` radians about the vertical, or a full
    ``orientation`` quaternion [x, y, z, w]) and the table.

    Raises:
        ValueError: both ``yaw`` and ``orientation``; a bad position, yaw or quaternion; a
            support table under an object that is not upright (the table's top is the plane
            of the object's base)."""
    if yaw is not None and orientation is not None:
        raise ValueError("give the rotation as a yaw or as an orientation, not both")
    now = current.pose
    pose = placement_pose(now[:3, 3] if position is None else position,
                          pose_yaw(now) if yaw is None else yaw)
    if orientation is not None:
        pose[:3, :3] = orientation_matrix(orientation)
    elif yaw is None:
        pose[:3, :3] = now[:3, :3]  # as now, tilted or not
    table = current.table if table == KEEP else table
    if table is not None and not is_upright(pose):
        raise ValueError("a support table stands under an upright object (its top is the "
                         "plane of the object's base): remove it with --no-table, or turn the "
                         "object about the vertical only")
    return Placement(pose, table)


def place_object(name: str, *, as_name: str | None = None, position=None,
                 yaw: float | None = None, table: SupportTable | str | None = KEEP,
                 force: bool = False, orientation=None) -> str:
    """Set the placement of object ``name`` (or of a new placed copy ``as_name``); returns
    the name of the object written.

    Args:
        name: a built-in, imported or placed object.
        as_name: write a placed copy under this name instead (required for built-in
            objects).
        position: (3,) metres in the robot's base frame; yaw: radians about the vertical;
            orientation: (4,) a unit quaternion [x, y, z, w] of the object frame in the world
            frame (instead of ``yaw``; an object that is not upright stands without a table);
            table: a :class:`SupportTable`, None (no table) or :data:`KEEP`.
        force: replace an existing entry ``as_name``.

    Raises:
        CatalogError: an unknown name, a built-in object without ``as_name``, an invalid or
            taken ``as_name`` (without ``force``), a bad position or yaw.
    """
    current = objects.load_object(name)  # an unknown name: its one-line error
    try:
        placement = new_placement(current, position, yaw, table, orientation)
    except ValueError as exc:
        raise CatalogError(str(exc)) from None
    if as_name is None:
        if name in objects.OBJECT_NAMES:
            raise CatalogError(f"{name!r} is a built-in object and stays as the paper placed "
                               f"it; make a placed copy with --as NEW_NAME")
        rewrite_entry(name, placement)
        return name
    write_placed(as_name, current.base or name, placement, force)
    return as_name


def rewrite_entry(name: str, placement: Placement) -> None:
    """Replace the ``pose`` and ``table`` of entry ``name`` (atomically)."""
    folder = imported_folder(name)
    entry = read_entry(folder)
    entry.update(placement.to_entry())
    write_atomic(folder / ENTRY_FILE, json.dumps(entry, indent=1))


def write_placed(as_name: str, base: str, placement: Placement, force: bool) -> None:
    """Write the placed object ``as_name`` (of ``base``) as a new entry folder, renamed into
    place whole."""
    if not valid_name(as_name):
        raise CatalogError(f"invalid object name {as_name!r}: a letter or digit, then letters, "
                           f"digits, '_', '-' or '.' (64 at most)")
    if as_name in objects.OBJECT_NAMES or as_name == base:
        raise CatalogError(f"{as_name!r} is taken by a built-in object or is the base itself; "
                           f"choose another name")
    existing = imported_folder(as_name)
    if existing is not None and not force:
        raise CatalogError(f"an object named {as_name!r} exists; use --force to replace it")
    root = catalog_dir()
    root.mkdir(parents=True, exist_ok=True)
    work = tempfile.mkdtemp(prefix=f".tmp-{as_name}-{os.getpid()}-", dir=root)
    entry = {"format": FORMAT_VERSION, "name": as_name, "base": base,
             **placement.to_entry()}
    (Path(work) / ENTRY_FILE).write_text(json.dumps(entry, indent=1))
    publish(Path(work), root / as_name)
