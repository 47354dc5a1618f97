"""Candidate grasps given as palm poses (from another planner, a person, a data set).

A palm-pose file is JSON::

    {"object": "drill",
     "candidates": [
       {"id": "a", "position": [x, y, z], "quaternion": [x, y, z, w], "spread": 0.0},
       {"id": "b", "pose": [[...4 numbers...] x 4], "hand": [7 numbers], "elbow": 0.1}]}

Each palm pose is the SDH palm frame in the OBJECT frame (metres; quaternion scalar last,
unit to 1e-6), or a 4x4 homogeneous matrix (rotation orthonormal to 1e-6, last row 0 0 0 1).
The pre-shape is ``hand`` (7 values, radians: spread, then proximal and distal of the three
fingers) or ``spread`` (radians) with the planner's mid-range proximal/distal values (one
entry's schema, its parsing and its IK: :mod:`kinegrasp_env.robot.palm_pose`, which the envs'
``palm_pose`` reset option shares). Each candidate is solved like a planner
candidate (:meth:`GraspPlanner.try_candidate`): IK from the planner's seed for the palm pose
in the world frame (the object at its catalog pose), or moved along the self-motion to
``elbow`` (radians) when given; the arm links must keep the planner's clearance; the hand
closes with the reference engine and must reach force closure. A candidate that fails is
returned with its reason (:data:`REASONS`) instead of a grasp.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegrasp_env.robot.palm_pose import PalmCandidate, parse_palm_pose, reach_palm_pose
from kinegrasp_env.world.grasps import Grasp, read_json_file

log = logging.getLogger(__name__)

#: Why a candidate was rejected (the first word of its reason).
REASONS = ("unreachable", "arm_collision", "start_collision", "missed", "no_force_closure")


@dataclass(frozen=True)
class Rejected:
    """A candidate that gives no grasp: ``reason`` is one of :data:`REASONS`."""

    id: str
    reason: str
    detail: str


def is_candidate_file(path: str | Path) -> bool:
    """True when ``path`` is a JSON object with a ``candidates`` list (not a grasp file)."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and "candidates" in data


def parse_candidate(entry, index: int, source: str) -> PalmCandidate:
    """Validate entry ``index`` of a candidate file; ValueError names it."""
    where = f"{source} candidate {index}"
    if isinstance(entry, dict):
        where = f"{source} candidate {entry.get('id', index)!s}"
    return parse_palm_pose(entry, where, str(index))


def load_candidates(path: str | Path) -> tuple[str, list[PalmCandidate]]:
    """(object name, candidates) of a palm-pose file, or of a grasp file read as palm poses
    (its ``grasps`` list: see :func:`grasp_entry_as_candidate`); ValueError names the file,
    the candidate and the problem (also for repeated ids and an unknown object)."""
    from kinegrasp_env.world.objects import is_object, load_object, unknown_object

    path = Path(path)
    data = read_json_file(path)
    key = next((k for k in ("candidates", "grasps") if isinstance(data, dict)
                and isinstance(data.get(k), list)), None)
    if key is None:
        raise ValueError(f"{path}: expected an object with a 'candidates' (or 'grasps') list")
    name = data.get("object")
    if not isinstance(name, str) or not is_object(name):
        raise ValueError(f"{path}: {unknown_object(name)}")
    entries = data[key]
    if key == "grasps":
        pose = load_object(name).pose
        entries = [grasp_entry_as_candidate(e, pose) for e in entries]
    found = [parse_candidate(e, i, str(path)) for i, e in enumerate(entries)]
    if not found:
        raise ValueError(f"{path}: the file holds no candidates")
    ids = [c.id for c in found]
    for i, cid in enumerate(ids):
        if cid in ids[:i]:
            raise ValueError(f"{path}: candidates {ids.index(cid)} and {i} have the same id "
                             f"{cid!r}; candidate ids must be unique")
    return name, found


def grasp_entry_as_candidate(entry, object_pose: np.ndarray):
    """A grasp file's entry as a palm-pose entry: as it is when it has the candidate fields
    (``world.grasps.palm_pose_fields``: every file ``save_grasps`` writes); an older entry
    gets ``pose`` = its world-frame ``palm_pose`` in the object frame (``object_pose``, (4, 4):
    the object's catalog pose) and its ``hand`` from ``q0[7:]``. ``q0`` is not used."""
    if not isinstance(entry, dict) or "pose" in entry or "position" in entry:
        return entry
    out = dict(entry)
    try:
        out["pose"] = np.linalg.solve(object_pose, np.asarray(entry["palm_pose"],
                                                              dtype=float)).tolist()
    except (KeyError, TypeError, ValueError, np.linalg.LinAlgError):
        return entry  # parsing then names the missing palm pose
    if "hand" not in out and "spread" not in out and np.size(entry.get("q0", [])) == 14:
        out["hand"] = list(entry["q0"][7:])
    return out


def configuration(planner, candidate: PalmCandidate) -> tuple[np.ndarray | None, str]:
    """(q (14,), "") reaching the candidate's palm pose, or (None, why) when unreachable:
    :func:`~kinegrasp_env.robot.palm_pose.reach_palm_pose` with the object at its pose."""
    return reach_palm_pose(planner.ik, planner.obj.pose @ candidate.pose, candidate.hand,
                           candidate.elbow)


def solve(planner, candidate: PalmCandidate, object_name: str) -> Grasp | Rejected:
    """The candidate's grasp (IK, arm clearance, closing with the planner's reference
    engine), or why it is rejected. ``planner``: a :class:`GraspPlanner` of the object."""
    from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, OUTCOMES
    from kinegrasp_env.montecarlo.nominal import OUTCOME_DETAILS, grasp_from_draw
    from kinegrasp_env.robot.model import PALM_LINK

    q0, why = configuration(planner, candidate)
    if q0 is None:
        return Rejected(candidate.id, "unreachable", why)
    if not planner.arm_clear(q0):
        return Rejected(candidate.id, "arm_collision", "an arm link is within "
                        "the planner's clearance of the object")
    draw = planner.engine.run(q0[None])
    outcome = int(draw.outcome[0])
    if outcome != FORCE_CLOSURE:
        name = OUTCOMES[outcome]
        return Rejected(candidate.id, name, OUTCOME_DETAILS.get(name, name))
    palm = planner.engine.kin.pose(q0, PALM_LINK)[0]
    psi = float(planner.ik.elbow_angle(q0[None])[0])
    return grasp_from_draw(draw, object_name, q0, palm, grasp_id=candidate.id,
                           meta={"elbow_angle": psi, "source": "palm_pose"})


def solve_all(object_name: str, candidates: list[PalmCandidate]
              ) -> tuple[list[Grasp], list[Rejected]]:
    """(grasps of the accepted candidates, rejected candidates), both in file order."""
    from kinegrasp_env.toolkit.planner import GraspPlanner

    planner = GraspPlanner(object_name)
    grasps, rejected = [], []
    try:
        for candidate in candidates:
            result = solve(planner, candidate, object_name)
            (grasps if isinstance(result, Grasp) else rejected).append(result)
    finally:
        planner.close()
    log.info("%s: %d of %d palm-pose candidates accepted", object_name, len(grasps),
             len(candidates))
    return grasps, rejected
