"""The grasps a sweep spec sweeps: ``grasp_files`` read and checked (each file's SHA-256 kept,
its grasps of the swept object and the spec's robot), the robot's shipped sets for the rest,
and the robot a spec that names none takes from its grasp files. Every check raises a
:class:`SpecError` naming the spec entry (``where``).
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path
from typing import Any

from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.world.grasps import Grasp, check_robot
from kinegrasp_env.world.objects import object_version


class SpecError(ValueError):
    """A sweep specification that cannot run (raised before any work starts)."""


def grasp_files(value: Any, objects: tuple[str, ...], where: str,
                base: str | Path | None, robot: str) -> tuple[tuple[str, str, str], ...]:
    """``grasp_files``: (object, absolute path, SHA-256) per entry, each file read and
    checked (grasps of that object and of ``robot``, at least one)."""
    if not isinstance(value, dict):
        raise SpecError(f"{where}: 'grasp_files' must map objects to grasp files, e.g. "
                        "{duck: duck_grasps.json}")
    out = []
    for name, text in value.items():
        if name not in objects:
            raise SpecError(f"{where}: grasp_files names {name!r}, which is not in 'objects'")
        if not isinstance(text, str) or not text:
            raise SpecError(f"{where}: grasp_files: {name}: expected a file name, got {text!r}")
        path = spec_path(base, text)
        try:
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
            grasps = file_grasps(str(path), digest)
        except FileNotFoundError:
            raise SpecError(f"{where}: grasp_files: {name}: no such file {path}") from None
        except (OSError, ValueError) as exc:
            raise SpecError(f"{where}: grasp_files: {name}: {exc}") from None
        if not grasps:
            raise SpecError(f"{where}: grasp_files: {name}: {path} holds no grasps")
        other = next((g for g in grasps if g.object != name), None)
        if other is not None:
            raise SpecError(f"{where}: grasp_files: {name}: grasp {other.id} of {path} is a "
                            f"grasp of {other.object}")
        for grasp in grasps:
            try:
                check_robot(grasp, robot)
            except ValueError as exc:
                raise SpecError(f"{where}: grasp_files: {name}: {exc}") from None
        out.append((name, str(path), digest))
    return tuple(out)


def spec_path(base: str | Path | None, text: str) -> Path:
    """A file a spec names, relative to the spec's folder ``base`` (else the current one)."""
    return (Path(base or ".") / text).absolute()


def files_robot(value: Any, base: str | Path | None, objects: tuple[str, ...]) -> str:
    """The robot of a spec that names none: the one robot whose grasps the ``grasp_files``
    of the swept ``objects`` hold, else the default one (files of several robots, or
    unreadable ones, are reported by the checks that read them)."""
    robots = set()
    files = value if isinstance(value, dict) else {}
    for text in (text for name, text in files.items() if name in objects):
        path = spec_path(base, str(text))
        try:  # read as the checks read it (cached: they do not read it again)
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
            robots.update(g.robot for g in file_grasps(str(path), digest))
        except (OSError, ValueError):
            continue
    return robots.pop() if len(robots) == 1 else DEFAULT_ROBOT


@lru_cache(maxsize=16)
def file_grasps(path: str, digest: str) -> tuple[Grasp, ...]:
    """The grasps of a grasp file whose bytes have SHA-256 ``digest`` (a file changed since
    the spec was read is a :class:`SpecError`)."""
    from kinegrasp_env.world.grasps import load_grasps

    if hashlib.sha256(Path(path).read_bytes()).hexdigest() != digest:
        raise SpecError(f"{path} changed since the sweep spec was read")
    return tuple(load_grasps(path))


def grasp_set(name: str, files: tuple[tuple[str, str, str], ...],
              robot: str = DEFAULT_ROBOT) -> tuple[Grasp, ...]:
    for object_name, path, digest in files:
        if object_name == name:
            return file_grasps(path, digest)
    return shipped_set(name, robot)


def shipped_set(name: str, robot: str) -> tuple[Grasp, ...]:
    """The robot's shipped set of ``name`` (``assets/grasps/<robot>/``; a placed copy's,
    the copy as it stands now), read once per version of the object."""
    try:
        version = object_version(name)
    except ValueError:  # not in the catalog: the grasp lookup says so
        version = ""
    return versioned_shipped_set(name, robot, version)


@lru_cache(maxsize=32)
def versioned_shipped_set(name: str, robot: str, version: str) -> tuple[Grasp, ...]:
    """:func:`shipped_set` of one version of the object (``version``: the cache's key)."""
    from kinegrasp_env.world.grasps import shipped_grasps

    return tuple(shipped_grasps(name, robot))


def check_grasp_sets(objects: tuple[str, ...], files: tuple[tuple[str, str, str], ...],
                     where: str, robot: str = DEFAULT_ROBOT) -> None:
    """An object the robot has no shipped set of (an imported one among them) needs a grasp
    file: one line saying how."""
    from kinegrasp_env.world.grasps import NoGraspSetError, plan_command

    given = {name for name, _, _ in files}
    for name in (n for n in objects if n not in given):
        try:
            shipped_set(name, robot)
        except NoGraspSetError as exc:
            if not exc.imported:
                raise SpecError(f"{where}: {exc}, and give the file in 'grasp_files'") from None
            raise SpecError(
                f"{where}: {exc.reason}; give its grasp file in 'grasp_files' (e.g. "
                f"grasp_files: {{{name}: {name}_grasps.json}}, written by "
                f"`{plan_command(robot, name, out=True)}`)") from None


def check_grasp_indices(objects: tuple[str, ...], indices: tuple[int, ...],
                        files: tuple[tuple[str, str, str], ...], where: str,
                        robot: str = DEFAULT_ROBOT) -> None:
    for name in objects:
        count = len(grasp_set(name, files, robot))
        bad = [i for i in indices if i >= count]
        if bad:
            kind = "grasp file" if any(f[0] == name for f in files) else "shipped set"
            raise SpecError(f"{where}: grasp {bad[0]} does not exist for {name} "
                            f"(its {kind} has grasps 0..{count - 1})")
