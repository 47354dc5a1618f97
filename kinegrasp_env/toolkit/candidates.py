"""Candidate grasps given as palm poses (from another planner, a person, a data set), for any
catalog robot.

A palm-pose file is JSON::

    {"object": "drill",
     "candidates": [
       {"id": "a", "position": [x, y, z], "quaternion": [x, y, z, w], "spread": 0.0},
       {"id": "b", "pose": [[...4 numbers...] x 4], "hand": [7 numbers], "elbow": 0.1}]}

    {"object": "my_box", "robot": "panda", "frame": "source",
     "candidates": [{"id": "top", "position": [x, y, z], "quaternion": [x, y, z, w],
                     "hand": {"panda_finger_joint1": 0.04}}]}

``robot`` (the file's top level; default ``kuka_sdh``) names the catalog robot; a caller's
robot (``rank --robot``) must agree with it (:func:`file_robot`). Each palm pose is that
robot's palm link frame (metres; quaternion scalar last, unit to 1e-6; or a 4x4 homogeneous
matrix) in the frame ``frame`` names (:data:`FRAMES`): ``object`` (the default) or ``source``,
the imported mesh's own frame, mapped to the object frame through the catalog entry's
``source_to_object`` (:func:`source_pose_to_object`). The pre-shape is ``hand`` by the
robot's hand joint names or as a list in its description's order (one entry's schema, its
parsing: :mod:`kinegrasp_env.robot.palm_pose`, which the envs'
``palm_pose`` reset option shares).

Every robot's candidates are solved one way
(:class:`~kinegrasp_env.toolkit.candidate_solver.CandidateSolver`): IK from the description's
``home`` for the palm pose in the world frame (the object at its catalog pose), or moved
along the self-motion to ``elbow`` (radians) when given; every link but the fingers must keep
the planner's clearance; the hand closes with the robot's reference engine. A candidate that reaches
and clears but whose nominal closing is not in force closure (the hand touches without it,
or a finger closes on nothing) is still a grasp (Q = 0, ``meta["nominal_force_closure"]``
False, ``meta["nominal_outcome"]`` the closing's outcome): dropping it would bias every
comparison with outside labels, and noise may still put some draws in force closure. One
that cannot be reached, or whose links collide, is returned with its reason
(:data:`REASONS`) instead of a grasp.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.robot.palm_pose import PalmCandidate, parse_palm_pose
from kinegrasp_env.world.grasps import (
    GRASP_ENTRY_KEYS,
    Grasp,
    check_unique_ids,
    holds_candidates,
    read_json_file,
)

log = logging.getLogger(__name__)

#: Why a candidate was rejected (the first word of its reason).
REASONS = ("unreachable", "arm_collision", "start_collision")
#: The frames a file's poses may be given in (``frame`` at its top level; the first is the
#: default).
FRAMES = ("object", "source")
#: The top-level fields of a palm-pose file; any other is refused (a misspelt ``frame`` would
#: otherwise read every pose in the object frame without a word).
CANDIDATE_FILE_KEYS = ("object", "robot", "frame", "candidates")
#: Top-level fields a planned grasp file carries (``kinegrasp plan``'s seed), kept by a file
#: whose ``grasps`` list was renamed ``candidates`` to solve its palm poses again: read, not
#: used.
PLANNED_FILE_KEYS = ("planner_seed",)


@dataclass(frozen=True)
class Rejected:
    """A candidate that gives no grasp: ``reason`` is one of :data:`REASONS`."""

    id: str
    reason: str
    detail: str


@dataclass(frozen=True)
class CandidateFile:
    """A palm-pose file read and checked.

    Attributes:
        object: the catalog object every candidate grasps.
        robot: the catalog robot whose palm and hand the candidates give.
        frame: the frame the file gave its poses in (:data:`FRAMES`); ``candidates`` hold
            them in the object frame either way.
        candidates: in file order; each pose (4, 4) in the object frame.
        robot_named: False where neither the file nor the caller named the robot (the
            default robot's candidates, which a command says).
    """

    object: str
    robot: str
    frame: str
    candidates: list[PalmCandidate]
    robot_named: bool = True


def is_candidate_file(path: str | Path) -> bool:
    """True when ``path`` is a JSON object with a ``candidates`` list (not a grasp file)."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return False
    return holds_candidates(data)


def parse_candidate(entry, index: int, source: str, robot=None) -> PalmCandidate:
    """Validate entry ``index`` of a candidate file; ValueError names it. ``robot``: the
    :class:`~kinegrasp_env.robot.description.RobotDescription` whose hand the entry gives
    (default: the default robot)."""
    where = f"{source} candidate {index}"
    if isinstance(entry, dict):
        where = f"{source} candidate {entry.get('id', index)!s}"
    return parse_palm_pose(entry, where, str(index), robot, other_keys=GRASP_ENTRY_KEYS)


def file_robot(data: dict, entries: list, path: Path, robot: str | None) -> str:
    """The catalog robot of a palm-pose file: its top-level ``robot`` (entries that name one
    must agree with it; a grasp file may name it in its entries only), else ``robot``, else
    the default robot. ValueError (one line) when the file and ``robot`` (``rank --robot``)
    name two robots, or for an unknown robot."""
    from kinegrasp_env.robot.catalog import check_robot_name

    named = data.get("robot")
    for i, entry in enumerate(entries):
        own = entry.get("robot") if isinstance(entry, dict) else None
        if own is None:
            continue
        if named is None:
            named = own
        elif own != named:
            label = entry.get("id", i)
            raise ValueError(f"{path}: candidate {label} names robot {own!r}, the file "
                             f"{named!r}; one file holds one robot's candidates")
    if named is not None and robot is not None and named != robot:
        raise ValueError(f"{path}: the file's robot {named!r} conflicts with --robot {robot}; "
                         f"give one of them (or the same robot in both)")
    name = named if named is not None else robot or DEFAULT_ROBOT
    try:
        return check_robot_name(name)
    except ValueError as exc:
        raise ValueError(f"{path}: field 'robot': {exc}") from None


def source_pose_to_object(pose: np.ndarray, to_object: np.ndarray) -> np.ndarray:
    """(4, 4) a palm pose given in an imported mesh's source frame (``pose`` (4, 4): position
    in the source file's units, a rotation) in the object frame: ``to_object`` (4, 4) is the
    entry's ``source_to_object`` (scale s times a rotation, then a translation, metres); the
    position maps as the mesh's vertices do, the rotation turns by the rotation alone."""
    linear = to_object[:3, :3]
    scale = float(np.cbrt(np.linalg.det(linear)))
    out = np.eye(4)
    out[:3, :3] = (linear / scale) @ pose[:3, :3]
    out[:3, 3] = linear @ pose[:3, 3] + to_object[:3, 3]
    return out


def file_frame(data: dict, key: str, name: str, path: Path) -> np.ndarray | None:
    """The ``source_to_object`` (4, 4) to map the file's poses through (``frame`` is
    ``source``), or None (``object``, the default). ValueError (one line) for another frame,
    a grasp file given in the source frame, or an object without ``source_to_object``."""
    from kinegrasp_env.world.objects import source_to_object

    frame = data.get("frame", FRAMES[0])
    if frame not in FRAMES:
        raise ValueError(f"{path}: frame {frame!r} is not one of 'object' (the default: poses "
                         f"in the object frame) or 'source' (poses in the imported mesh's own "
                         f"frame)")
    if frame == "object":
        return None
    if key == "grasps":
        raise ValueError(f"{path}: frame 'source' is for a 'candidates' list; a grasp file's "
                         f"palm poses are in the object frame")
    to_object = source_to_object(name)
    if to_object is None:
        raise ValueError(f"{path}: frame 'source' needs an object imported from a mesh (its "
                         f"catalog entry records source_to_object); {name!r} has none: give "
                         f"its poses in the object frame (\"frame\": \"object\")")
    return to_object


def read_candidates(path: str | Path, robot: str | None = None) -> CandidateFile:
    """A palm-pose file, or a grasp file read as palm poses (its ``grasps`` list: see
    :func:`grasp_entry_as_candidate`), checked; ``robot``: the robot asked for (``rank
    --robot``; None: the file's). ValueError names the file, the candidate and the problem
    (also for repeated ids, an unknown object or robot, a robot conflict and a bad frame)."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.world.objects import is_object, load_object, unknown_object

    path = Path(path)
    data = read_json_file(path)
    key = next((k for k in ("candidates", "grasps") if isinstance(data, dict)
                and isinstance(data.get(k), list)), None)
    if key is None:
        raise ValueError(f"{path}: expected an object with a 'candidates' (or 'grasps') list")
    unknown = [str(k) for k in data if k not in CANDIDATE_FILE_KEYS + PLANNED_FILE_KEYS]
    if key == "candidates" and unknown:
        raise ValueError(f"{path}: unknown field {unknown[0]!r}; a palm-pose file has "
                         f"{', '.join(CANDIDATE_FILE_KEYS)}")
    name = data.get("object")
    if name is None:
        raise ValueError(f"{path}: missing field 'object' (the catalog object the file's "
                         f"{key} grasp)")
    if not isinstance(name, str) or not is_object(name):
        raise ValueError(f"{path}: {unknown_object(name)}")
    entries = data[key]
    robot_name = file_robot(data, entries, path, robot)
    to_object = file_frame(data, key, name, path)
    if key == "grasps":
        pose = load_object(name).pose
        entries = [grasp_entry_as_candidate(e, pose, robot_name) for e in entries]
    description = load_robot(robot_name)
    found = [parse_candidate(e, i, str(path), description) for i, e in enumerate(entries)]
    if not found:
        raise ValueError(f"{path}: the file holds no candidates")
    check_unique_ids([c.id for c in found], str(path), "candidates")
    if to_object is not None:
        found = [replace(c, pose=source_pose_to_object(c.pose, to_object)) for c in found]
    named = robot is not None or data.get("robot") is not None or any(
        isinstance(e, dict) and e.get("robot") is not None for e in data[key])
    return CandidateFile(name, robot_name, FRAMES[to_object is not None], found, named)


def load_candidates(path: str | Path, robot: str | None = None
                    ) -> tuple[str, list[PalmCandidate]]:
    """(object name, candidates in the object frame) of a palm-pose file
    (:func:`read_candidates`, which also says the robot)."""
    read = read_candidates(path, robot)
    return read.object, read.candidates


def grasp_entry_as_candidate(entry, object_pose: np.ndarray, robot: str = DEFAULT_ROBOT):
    """A grasp file's entry as a palm-pose entry: as it is when it has the candidate fields
    (``world.grasps.palm_pose_fields``: every file ``save_grasps`` writes); an older entry
    gets ``pose`` = its world-frame ``palm_pose`` in the object frame (``object_pose``, (4, 4):
    the object's catalog pose) and its ``hand`` from ``q0`` past the arm joints. ``q0`` is not
    used. A ``spread`` such a file may repeat for a hand without a pre-shape-only joint
    (:func:`~kinegrasp_env.robot.palm_pose.spread_joint`) is dropped: ``hand`` holds the
    pre-shape."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.palm_pose import spread_joint

    if not isinstance(entry, dict):
        return entry
    out = dict(entry)
    description = load_robot(robot)
    if spread_joint(description) is None:
        out.pop("spread", None)
    if "pose" in out or "position" in out:
        return out
    try:
        out["pose"] = np.linalg.solve(object_pose, np.asarray(entry["palm_pose"],
                                                              dtype=float)).tolist()
    except (KeyError, TypeError, ValueError, np.linalg.LinAlgError):
        return out  # parsing then names the missing palm pose
    q0 = entry.get("q0")
    if "hand" not in out and isinstance(q0, list) and len(q0) == description.model.dof:
        out["hand"] = list(q0[description.arm_dof:])
    return out


def solve_all(object_name: str, candidates: list[PalmCandidate], robot: str = DEFAULT_ROBOT,
              friction: float = 0.5) -> tuple[list[Grasp], list[Rejected]]:
    """(grasps of the accepted candidates, rejected candidates), both in file order;
    ``robot``: the catalog robot the candidates are of (their poses in the object frame);
    ``friction``: the mu their nominal closings are scored with."""
    from kinegrasp_env.toolkit.candidate_solver import CandidateSolver

    grasps, rejected = [], []
    solver = CandidateSolver(robot, object_name, friction=friction)
    try:
        for candidate in candidates:
            result = solver.solve(candidate, object_name)
            if not isinstance(result, Grasp):
                result = Rejected(candidate.id, *result)
            (grasps if isinstance(result, Grasp) else rejected).append(result)
    finally:
        solver.close()
    log.info("%s: %d of %d palm-pose candidates of robot %s accepted", object_name,
             len(grasps), len(candidates), robot)
    return grasps, rejected
