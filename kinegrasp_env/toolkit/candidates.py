"""Candidate grasps given as palm poses (from another planner, a person, a data set).

A palm-pose file is JSON::

    {"object": "drill",
     "candidates": [
       {"id": "a", "position": [x, y, z], "quaternion": [x, y, z, w], "spread": 0.0},
       {"id": "b", "pose": [[...4 numbers...] x 4], "hand": [7 numbers], "elbow": 0.1}]}

Each palm pose is the SDH palm frame in the OBJECT frame (metres; quaternion scalar last,
unit to 1e-6), or a 4x4 homogeneous matrix (rotation orthonormal to 1e-6, last row 0 0 0 1).
The pre-shape is ``hand`` (7 values, radians: spread, then proximal and distal of the three
fingers) or ``spread`` (radians) with the planner's mid-range proximal/distal values
(:data:`DEFAULT_PROXIMAL`, :data:`DEFAULT_DISTAL`). Each candidate is solved like a planner
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

from kinegrasp_env.world.grasps import Grasp, read_json_file

log = logging.getLogger(__name__)

#: Finger joint values used with ``spread`` alone: mid-range of the planner's sampling.
DEFAULT_PROXIMAL, DEFAULT_DISTAL = -0.55, 0.05
#: Tolerance of a unit quaternion's norm and of a rotation matrix's orthonormality.
UNIT_TOL = 1e-6
#: Seed of each candidate's IK restarts (per candidate: the result does not depend on order).
IK_RNG_SEED = 0
#: Why a candidate was rejected (the first word of its reason).
REASONS = ("unreachable", "arm_collision", "start_collision", "missed", "no_force_closure")


@dataclass(frozen=True)
class PalmCandidate:
    """One validated candidate.

    Attributes:
        id: its id (unique in the file).
        pose: (4, 4) palm frame in the object frame (metres).
        hand: (7,) hand pre-shape, radians.
        elbow: elbow angle to move to (radians), or None for the planner's IK choice.
    """

    id: str
    pose: np.ndarray
    hand: np.ndarray
    elbow: float | None = None


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


def quaternion_matrix(quat: np.ndarray) -> np.ndarray:
    """(3, 3) rotation of a unit quaternion (4,) [x, y, z, w]."""
    x, y, z, w = quat
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _numbers(entry: dict, key: str, shape: tuple[int, ...], where: str) -> np.ndarray:
    try:
        value = np.asarray(entry[key], dtype=float)
    except KeyError:
        raise ValueError(f"{where}: missing field {key!r}") from None
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {key} must be numbers") from None
    if value.shape != shape:
        raise ValueError(f"{where}: {key} must have shape {list(shape)}, got "
                         f"{list(value.shape)}")
    if not np.all(np.isfinite(value)):
        raise ValueError(f"{where}: {key} has non-finite entries")
    return value


def parse_pose(entry: dict, where: str) -> np.ndarray:
    """(4, 4) palm pose of one entry: ``pose`` (4x4) or ``position`` + ``quaternion``."""
    if "pose" in entry:
        pose = _numbers(entry, "pose", (4, 4), where)
        rot = pose[:3, :3]
        if not np.allclose(pose[3], [0, 0, 0, 1], atol=UNIT_TOL):
            raise ValueError(f"{where}: pose's last row must be [0, 0, 0, 1]")
        if (np.abs(rot.T @ rot - np.eye(3)).max() > UNIT_TOL
                or np.linalg.det(rot) < 0):
            raise ValueError(f"{where}: pose's rotation is not orthonormal (right-handed)")
        return pose
    position = _numbers(entry, "position", (3,), where)
    quat = _numbers(entry, "quaternion", (4,), where)
    if abs(np.linalg.norm(quat) - 1.0) > UNIT_TOL:
        raise ValueError(f"{where}: quaternion must be unit (norm {np.linalg.norm(quat):.6g})")
    pose = np.eye(4)
    pose[:3, :3] = quaternion_matrix(quat / np.linalg.norm(quat))
    pose[:3, 3] = position
    return pose


def parse_hand(entry: dict, where: str) -> np.ndarray:
    """(7,) pre-shape: ``hand``, or ``spread`` with the default finger values."""
    from kinegrasp_env.robot.model import kuka_sdh

    if "hand" in entry:
        hand = _numbers(entry, "hand", (7,), where)
        if "spread" in entry and not np.isclose(float(entry["spread"]), hand[0]):
            raise ValueError(f"{where}: spread {entry['spread']} differs from hand[0] {hand[0]}")
    else:
        spread = _numbers(entry, "spread", (), where)
        hand = np.array([float(spread), *[DEFAULT_PROXIMAL, DEFAULT_DISTAL] * 3])
    model = kuka_sdh()
    lo, hi = model.lower[7:], model.upper[7:]
    bad = np.flatnonzero((hand < lo - 1e-9) | (hand > hi + 1e-9))
    if bad.size:
        j = int(bad[0])
        raise ValueError(f"{where}: hand[{j}] = {hand[j]:.4f} is outside its limits "
                         f"[{lo[j]:.4f}, {hi[j]:.4f}]")
    return hand


def parse_candidate(entry, index: int, source: str) -> PalmCandidate:
    """Validate entry ``index`` of a candidate file; ValueError names it."""
    where = f"{source} candidate {index}"
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected an object, got {type(entry).__name__}")
    where = f"{source} candidate {entry.get('id', index)!s}"
    elbow = None
    if entry.get("elbow") is not None:
        elbow = float(_numbers(entry, "elbow", (), where))
    return PalmCandidate(str(entry.get("id", index)), parse_pose(entry, where),
                         parse_hand(entry, where), elbow)


def load_candidates(path: str | Path) -> tuple[str, list[PalmCandidate]]:
    """(object name, candidates) of a palm-pose file; ValueError names the file, the
    candidate and the problem (also for repeated ids and an unknown object)."""
    from kinegrasp_env.world.objects import is_object, unknown_object

    path = Path(path)
    data = read_json_file(path)
    if not isinstance(data, dict) or not isinstance(data.get("candidates"), list):
        raise ValueError(f"{path}: expected an object with a 'candidates' list")
    name = data.get("object")
    if not isinstance(name, str) or not is_object(name):
        raise ValueError(f"{path}: {unknown_object(name)}")
    found = [parse_candidate(e, i, str(path)) for i, e in enumerate(data["candidates"])]
    if not found:
        raise ValueError(f"{path}: the file holds no candidates")
    ids = [c.id for c in found]
    for i, cid in enumerate(ids):
        if cid in ids[:i]:
            raise ValueError(f"{path}: candidates {ids.index(cid)} and {i} have the same id "
                             f"{cid!r}; candidate ids must be unique")
    return name, found


def configuration(planner, candidate: PalmCandidate) -> tuple[np.ndarray | None, str]:
    """(q (14,), "") reaching the candidate's palm pose, or (None, why) when unreachable.

    IK as the planner's (:data:`IK_SEED`, 4 random restarts seeded by :data:`IK_RNG_SEED`),
    then the self-motion to ``candidate.elbow`` when given."""
    from kinegrasp_env.robot.model import ARM_JOINTS
    from kinegrasp_env.toolkit.planner import IK_SEED

    model = planner.model
    seed = np.zeros(model.dof)
    seed[model.index(ARM_JOINTS)] = IK_SEED
    seed[7:] = candidate.hand
    target = planner.obj.pose @ candidate.pose
    result = planner.ik.solve(target, seed, rng=np.random.default_rng(IK_RNG_SEED), restarts=4)
    if not result.success[0]:
        pos, rot = float(result.position_error[0]), float(result.orientation_error[0])
        return None, (f"no IK solution within the joint limits (closest: {pos:.3g} m, "
                      f"{rot:.3g} rad off)")
    q = result.q[0]
    if candidate.elbow is not None:
        moved, ok = planner.ik.set_elbow_angle(q, candidate.elbow)
        if not ok[0]:
            return None, f"elbow angle {candidate.elbow:g} rad leaves the joint limits"
        q = moved[0]
    return q, ""


def solve(planner, candidate: PalmCandidate, object_name: str) -> Grasp | Rejected:
    """The candidate's grasp (IK, arm clearance, closing with the planner's reference
    engine), or why it is rejected. ``planner``: a :class:`GraspPlanner` of the object."""
    from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, OUTCOMES
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
        details = {"start_collision": "the open hand intersects the object",
                   "missed": "the closing hand touches nothing",
                   "no_force_closure": "the closed hand's contacts are not in force closure"}
        name = OUTCOMES[outcome]
        return Rejected(candidate.id, name, details.get(name, name))
    k = int(draw.n_contacts[0])
    palm = planner.engine.kin.pose(q0, PALM_LINK)[0]
    psi = float(planner.ik.elbow_angle(q0[None])[0])
    return Grasp(object_name, q0, np.ascontiguousarray(palm), draw.points[0, :k].copy(),
                 draw.normals[0, :k].copy(), draw.finger[0, :k].astype(int),
                 draw.link[0, :k].astype(int), float(draw.quality[0]), id=candidate.id,
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
