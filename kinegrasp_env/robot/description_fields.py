"""The checks of a robot description's fields (:mod:`kinegrasp_env.robot.description`):
each returns the field's value or raises one :class:`RobotDescriptionError` line naming the
file, the key and the bad value."""

from __future__ import annotations

import math
from pathlib import Path

__all__ = ["RobotDescriptionError", "check_arm_angle_links", "check_efforts",
           "check_hand_mount", "check_mapping", "check_names", "check_number",
           "check_packages", "check_text", "fail", "joint_values"]


class RobotDescriptionError(ValueError):
    """A robot description refused: one line naming the file, the key and the value."""


def fail(where: str, key: str, problem: str) -> RobotDescriptionError:
    """The error of file ``where``'s ``key``, on one line."""
    return RobotDescriptionError(" ".join(f"{where}: {key}: {problem}".split()))


def check_names(value, where: str, key: str) -> tuple[str, ...]:
    """A non-empty list of distinct names."""
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, str) and v for v in value)):
        raise fail(where, key, f"expected a non-empty list of names, got {value!r}")
    if len(set(value)) != len(value):
        raise fail(where, key, f"names repeated in {value!r}")
    return tuple(value)


def check_mapping(value, where: str, key: str) -> dict:
    """A mapping whose keys are names."""
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise fail(where, key, f"expected a mapping of names to values, got {value!r}")
    return value


def check_number(value, where: str, key: str) -> float:
    """A finite number (not a bool; an integer too large for a float is not finite)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise fail(where, key, f"{value!r:.40} is not a finite number")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise fail(where, key, f"{value!r:.40} is not a finite number")
    return number


def joint_values(data, where, key, joints, movable, default) -> dict[str, float]:
    """Every joint of ``joints``'s value under ``key`` (a mapping, optional): the given one
    (within the joint's limits), else ``default(lower, upper)``."""
    given = check_mapping(data.get(key, {}) or {}, where, key)
    extra = [j for j in given if j not in joints]
    if extra:
        kind = "hand_joints" if key == "open" else "arm_joints"
        raise fail(where, key, f"{extra[0]!r} is not one of {kind}")
    values = {}
    for j in joints:
        lo, hi = movable[j].lower, movable[j].upper
        if j not in given:
            values[j] = default(lo, hi)
            continue
        v = check_number(given[j], where, f"{key}: {j}")
        if not lo - 1e-12 <= v <= hi + 1e-12:
            raise fail(where, key, f"{j}: {v:g} is outside the joint's limits "
                       f"[{lo:g}, {hi:g}]")
        values[j] = v
    return values


def check_hand_mount(data, where, path_links, flange: str) -> str:
    """The ``hand_mount`` link ("" when not given): one of the links from the last arm
    joint's child ``flange`` to the palm, which fixed joints join to both."""
    if "hand_mount" not in data:
        return ""
    link = data["hand_mount"]
    allowed = path_links[path_links.index(flange):]
    if not isinstance(link, str) or link not in allowed:
        raise fail(where, "hand_mount", f"{link!r} is not a link from the last arm joint's "
                   f"child to palm_link (one of {', '.join(allowed)})")
    return link


def check_arm_angle_links(data, where, arm, movable, path_links
                          ) -> tuple[str, str, str] | None:
    """The shoulder, elbow and wrist links of the arm angle: three links of the arm chain
    ``path_links``, by default (7 arm joints) the links moved by arm joints 2, 4 and 6;
    None for another arm that names none."""
    if "arm_angle_links" not in data:
        if len(arm) != 7:
            return None
        return tuple(movable[arm[i]].child for i in (1, 3, 5))
    names = check_names(data["arm_angle_links"], where, "arm_angle_links")
    if len(names) != 3:
        raise fail(where, "arm_angle_links", f"expected 3 links (shoulder, elbow, wrist), "
                   f"got {list(names)}")
    for link in names:
        if link not in path_links:
            raise fail(where, "arm_angle_links", f"{link!r} is not a link of the arm chain")
    return names


def check_efforts(data: dict, where: str, movable: dict) -> dict[str, float]:
    """The ``efforts`` overrides: movable joint (of ``movable``, name -> joint) -> its motor
    effort (N m or N, > 0)."""
    efforts = {}
    for j, v in check_mapping(data.get("efforts", {}) or {}, where, "efforts").items():
        if j not in movable:
            raise fail(where, "efforts", f"unknown movable joint {j!r}")
        value = check_number(v, where, f"efforts: {j}")
        if value <= 0:
            raise fail(where, "efforts", f"{j}: {value:g} is not > 0")
        efforts[j] = value
    return efforts


def check_packages(data: dict, where: str, folder: Path) -> dict[str, Path]:
    """The ``packages`` folders: package name -> its folder, resolved from ``folder`` (the
    description's own)."""
    packages = {}
    for pkg, given in check_mapping(data.get("packages", {}) or {}, where,
                                    "packages").items():
        if not isinstance(given, str):
            raise fail(where, "packages", f"{pkg}: expected a folder path, got {given!r}")
        resolved = (folder / given).resolve()
        if not resolved.is_dir():
            raise fail(where, "packages", f"{pkg}: {given!r} is not a folder ({resolved})")
        packages[pkg] = resolved
    return packages


def check_text(data: dict, where: str, key: str, default: str) -> str:
    """A non-empty text under ``key`` (``default`` when not given)."""
    text = data.get(key, default)
    if not isinstance(text, str) or not text.strip():
        raise fail(where, key, f"expected a non-empty text, got {text!r}")
    return text
