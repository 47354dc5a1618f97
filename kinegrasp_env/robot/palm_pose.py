"""A grasp given as a palm pose: its schema (one entry of a palm-pose file, or the envs'
``palm_pose`` reset option) and the arm configuration that reaches it.

One entry is a dict::

    {"id": "a", "position": [x, y, z], "quaternion": [x, y, z, w], "spread": 0.0}
    {"id": "b", "pose": [[...4 numbers...] x 4], "hand": [7 numbers], "elbow": 0.1}
    {"id": "c", "position": [x, y, z], "quaternion": [x, y, z, w],
     "hand": {"panda_finger_joint1": 0.04}}

The palm pose is the robot's palm link frame (the description's ``palm_link``: ``palm`` of
the default robot's SDH) in the OBJECT frame (metres; quaternion scalar last, unit to
:data:`UNIT_TOL`), or a 4x4 homogeneous matrix (rotation orthonormal to :data:`UNIT_TOL`,
last row 0 0 0 1). The pre-shape, radians or metres per hand joint:

- ``hand`` as ``{joint name: value}`` of the description's ``hand_joints`` (a joint left out
  takes its ``open`` value) or as a list in the ``hand_joints`` order; without ``hand``, the
  description's ``open`` pre-shape;
- ``spread`` (radians) sets the hand's one pre-shape-only joint (:func:`spread_joint`: the
  SDH's ``f1_spread``), the other joints as above; a hand without one refuses it.

``elbow`` (radians, optional) is the elbow angle to move to along the self-motion (a 7-joint
arm with an arm angle). Any other field is refused (:data:`PALM_POSE_KEYS`; a grasp file's
entries, read as palm poses, may carry theirs), and so are ``pose`` and ``position`` +
``quaternion`` together.

The arm configuration that reaches an entry is found by every robot's one IK
(:func:`~kinegrasp_env.robot.palm_ik.reach_robot_palm_pose`: from the description's ``home``,
then random restarts seeded by :data:`IK_RNG_SEED`, so that the result does not depend on
other entries; then the self-motion to ``elbow`` when given).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.wording import plural

if TYPE_CHECKING:
    from kinegrasp_env.robot.description import RobotDescription

#: Seed of each palm pose's IK restarts (per pose: the result does not depend on order).
IK_RNG_SEED = 0
#: The fields of a palm-pose entry (``robot``: the robot a file's entry is of).
PALM_POSE_KEYS = ("id", "position", "quaternion", "pose", "hand", "spread", "elbow", "robot")
#: Tolerance of a unit quaternion's norm and of a rotation matrix's orthonormality.
UNIT_TOL = 1e-6


@dataclass(frozen=True)
class PalmCandidate:
    """One validated palm pose.

    Attributes:
        id: its id (unique in a file).
        pose: (4, 4) palm frame in the object frame (metres).
        hand: (h,) hand pre-shape in the robot's ``hand_joints`` order (radians or metres;
            h = 7 for the default robot).
        elbow: elbow angle to move to (radians), or None for the IK's choice.
    """

    id: str
    pose: np.ndarray
    hand: np.ndarray
    elbow: float | None = None


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
        both = [key for key in ("position", "quaternion") if key in entry]
        if both:
            raise ValueError(f"{where}: give 'pose' (4x4) or 'position' + 'quaternion', not "
                             f"both ({' and '.join(['pose', *both])} given)")
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


def _within_limits(hand: np.ndarray, lo: np.ndarray, hi: np.ndarray, where: str,
                   names: tuple[str, ...] = ()) -> np.ndarray:
    """``hand`` (h,) when every value is within [lo, hi] (h,) (1e-9 slack), else ValueError
    (naming the joint, when ``names`` gives them)."""
    bad = np.flatnonzero((hand < lo - 1e-9) | (hand > hi + 1e-9))
    if bad.size:
        j = int(bad[0])
        name = f" ({names[j]})" if names else ""
        raise ValueError(f"{where}: hand[{j}]{name} = {hand[j]:.4f} is outside its limits "
                         f"[{lo[j]:.4f}, {hi[j]:.4f}]")
    return hand


def hand_hint(description: RobotDescription) -> str:
    """How robot ``description`` takes its pre-shape (one line, for error messages)."""
    example = ", ".join(f'"{j}": {description.open[j]:g}' for j in description.hand_joints)
    return (f"'hand' by joint name ({{{example}}}; a joint left out keeps its open value) or "
            f"as a list of {len(description.hand_joints)} in that order; without 'hand', "
            f"its open pre-shape")


def named_hand(value: dict, where: str, description: RobotDescription) -> np.ndarray:
    """(h,) pre-shape from ``{hand joint name: value}``: the description's ``open`` value
    for a joint left out; ValueError for an unknown name or a value that is no finite
    number."""
    names = description.hand_joints
    unknown = [k for k in value if k not in names]
    if unknown:
        raise ValueError(f"{where}: hand: {unknown[0]!r} is not a hand joint of robot "
                         f"{description.name!r} (its hand joints: {', '.join(names)})")
    hand = np.array([description.open[j] for j in names], dtype=float)
    for k, v in value.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"{where}: hand: {k}: {v!r} is not a finite number")
        hand[names.index(k)] = float(v)
    return hand


def spread_joint(description: RobotDescription) -> str | None:
    """The hand's one pre-shape-only joint (a hand joint ``close`` leaves out: a spread), or
    None when the hand has none or several."""
    pre = [j for j in description.hand_joints if j not in description.close]
    return pre[0] if len(pre) == 1 else None


def parse_hand(entry: dict, where: str, description: RobotDescription) -> np.ndarray:
    """(h,) pre-shape of robot ``description``: ``hand`` by joint name or as a list in
    ``hand_joints`` order, else the description's ``open`` pre-shape; ``spread`` sets the
    hand's one pre-shape-only joint (:func:`spread_joint`): alone, beside a ``hand`` mapping
    that leaves that joint out, or equal to ``hand``'s value; within the joint limits."""
    names = description.hand_joints
    value = entry.get("hand")
    if value is None:
        hand = np.array([description.open[j] for j in names], dtype=float)
    elif isinstance(value, dict):
        hand = named_hand(value, where, description)
    else:
        if np.size(value) != len(names) and np.ndim(value) == 1:
            raise ValueError(f"{where}: hand has {np.size(value)} values; robot "
                             f"{description.name!r} has {plural(len(names), 'hand joint')}: "
                             f"give "
                             f"{hand_hint(description)}")
        hand = _numbers(entry, "hand", (len(names),), where)
    if "spread" in entry:
        joint = spread_joint(description)
        if joint is None:
            raise ValueError(f"{where}: 'spread' sets a hand's one pre-shape-only joint; robot "
                             f"{description.name!r} has none: give {hand_hint(description)}")
        spread, i = float(_numbers(entry, "spread", (), where)), names.index(joint)
        if value is None or (isinstance(value, dict) and joint not in value):
            hand[i] = spread
        elif not np.isclose(spread, hand[i]):
            raise ValueError(f"{where}: spread {spread:g} differs from hand's {joint} "
                             f"{hand[i]:g}")
    arm = description.arm_dof
    return _within_limits(hand, description.model.lower[arm:], description.model.upper[arm:],
                          where, names)


def parse_palm_pose(entry, where: str, default_id: str = "0",
                    robot: RobotDescription | None = None,
                    other_keys: tuple[str, ...] = ()) -> PalmCandidate:
    """Validate one palm-pose entry (a dict of the schema above); ValueError starts with
    ``where`` and names the field. ``default_id``: its id when it has none. ``robot``: the
    robot whose pre-shape ``hand`` is (default: the default robot, ``kuka_sdh``).
    ``other_keys``: fields accepted and not read beside :data:`PALM_POSE_KEYS` (a grasp
    file's, read as palm poses); any other key is refused (a misspelt ``elbow`` would
    otherwise be dropped without a word)."""
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected an object, got {type(entry).__name__}")
    unknown = [str(key) for key in entry if key not in PALM_POSE_KEYS + tuple(other_keys)]
    if unknown:
        raise ValueError(f"{where}: unknown field {unknown[0]!r}; a palm pose has "
                         f"{', '.join(PALM_POSE_KEYS)}")
    elbow = None
    if entry.get("elbow") is not None:
        elbow = float(_numbers(entry, "elbow", (), where))
        if abs(elbow) > np.pi:  # an angle in degrees, most likely
            raise ValueError(f"{where}: elbow must be an angle in [-pi, pi] radians, got "
                             f"{elbow:g} (in degrees that is {np.radians(elbow):.4g} rad)")
    pose = parse_pose(entry, where)
    if robot is None:
        from kinegrasp_env.robot.catalog import load_robot

        robot = load_robot(DEFAULT_ROBOT)
    hand = parse_hand(entry, where, robot)
    if elbow is not None and not robot.has_self_motion:
        raise ValueError(f"{where}: elbow: robot {robot.name!r} has no elbow angle (its "
                         f"arm has {robot.arm_dof} joints); leave elbow out")
    return PalmCandidate(str(entry.get("id", default_id)), pose, hand, elbow)
