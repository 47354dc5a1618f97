"""Grasps: nominal arm+hand configuration, palm pose, nominal contacts and quality; JSON I/O.

A grasp file is JSON: ``{"object": name, "grasps": [grasp, ...]}`` with each grasp a dict of
``id``, ``object``, ``robot`` (a catalog robot; default ``kuka_sdh``), ``q0`` (the robot's
actuated joints: its arm joints, then its hand joints; radians or metres), ``palm_pose``
(4x4, world frame), ``contacts`` (list of ``{"finger", "link", "point", "normal"}`` in the
object frame) and ``q_nominal``. :func:`save_grasps` also writes each grasp as a palm-pose
candidate (:func:`palm_pose_fields`: ``position``, ``quaternion`` of the palm in the object
frame, ``hand``, ``spread`` and, when known, ``elbow``), so the same file reads as full
configurations (:func:`load_grasps`, which ignores those fields) or as palm poses to solve by
IK (``kinegrasp_env.toolkit.candidates.load_candidates``). README: "Candidates as palm poses".
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from kinegrasp_env.assets import assets_dir
from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT, check_robot_name, load_robot
from kinegrasp_env.spec_yaml import parse_json, read_user_text
from kinegrasp_env.world.names import OBJECT_NAMES, is_object, shipped_grasp_file, unknown_object
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.robot_configuration import (
    check_configuration,
    joints_words,
    palm_at,
    robot_model,
)

#: The fields of a grasp file's entry beyond its palm-pose candidate fields
#: (:meth:`Grasp.to_dict`, :func:`palm_pose_fields`).
GRASP_ENTRY_KEYS = ("id", "object", "q0", "palm_pose", "q_nominal", "contacts", "meta",
                    "robot")


@dataclass(frozen=True, eq=False)
class Grasp:
    """One grasp.

    Attributes:
        object: catalog object name.
        q0: (dof,) nominal configuration of ``robot``: its arm joints, then its hand's
            (the pre-shape), radians (metres for a prismatic joint).
        palm_pose: (4, 4) palm frame reached by q0, world frame.
        points, normals: (k, 3) nominal contacts (object frame; inward normals).
        fingers, links: (k,) finger and link (its index along the finger, 0 at the palm) of
            each contact.
        q_nominal: Ferrari-Canny quality of the nominal contacts.
        id: identifier within its set.
        meta: free-form extra information (e.g. the elbow angle, the planner's settings).
        robot: the catalog robot whose configuration ``q0`` is (default ``kuka_sdh``; for
            another robot ``q0`` is its actuated vector: arm joints, then hand joints).
    """

    object: str
    q0: np.ndarray
    palm_pose: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    fingers: np.ndarray
    links: np.ndarray
    q_nominal: float
    id: str = "0"
    meta: dict = field(default_factory=dict)
    robot: str = DEFAULT_ROBOT

    @property
    def arm_dof(self) -> int:
        """Arm joints at the head of ``q0`` (the robot's description's)."""
        return load_robot(self.robot).arm_dof

    @property
    def arm(self) -> np.ndarray:
        return self.q0[:self.arm_dof]

    @property
    def hand(self) -> np.ndarray:
        return self.q0[self.arm_dof:]

    def to_dict(self, object_pose: np.ndarray | None = None) -> dict:
        """The grasp's JSON entry; given the object's pose (4, 4) in the world frame, with
        the palm-pose candidate fields (:func:`palm_pose_fields`) after ``object``."""
        return {
            "id": self.id, "object": self.object,
            **({} if object_pose is None else palm_pose_fields(self, object_pose)),
            "q0": self.q0.tolist(),
            "palm_pose": self.palm_pose.tolist(), "q_nominal": self.q_nominal,
            "contacts": [{"finger": int(f), "link": int(k), "point": p.tolist(),
                          "normal": n.tolist()}
                         for f, k, p, n in zip(self.fingers, self.links, self.points,
                                               self.normals, strict=True)],
            "meta": self.meta,
            **({} if self.robot == DEFAULT_ROBOT else {"robot": self.robot}),
        }

    @classmethod
    def from_dict(cls, data: dict, where: str = "grasp", *, object_name: str | None = None,
                  default_id: str = "0", robot_name: str | None = None) -> Grasp:
        """Build and validate a grasp from its entry of a grasp file (the fields of README's
        grasp-file table). ``object`` defaults to the file's top-level one (``object_name``),
        ``robot`` to the file's (``robot_name``), else ``kuka_sdh``,
        ``palm_pose`` to the palm at ``q0`` (forward kinematics, world frame), ``contacts`` to
        none, ``q_nominal`` to 0 and ``id`` to ``default_id``.

        Raises:
            ValueError: one line naming the entry (``where``) and the field.
        """
        if not isinstance(data, dict):
            raise ValueError(f"{where}: expected an object with a grasp's fields, got "
                             f"{type(data).__name__}")
        label = where if "id" not in data else f"{where} (id {data['id']!r})"
        obj = data.get("object", object_name)
        if obj is None:
            raise ValueError(f"{label}: field 'object' missing (give it in the entry or once "
                             "at the top of the file)")
        if not isinstance(obj, str) or not is_object(obj):
            raise ValueError(f"{label}: field 'object': {unknown_object(obj)}")
        robot = data.get("robot", robot_name or DEFAULT_ROBOT)
        robot_model(robot, f"{label}: field 'robot'")
        q0 = _array_field(data, "q0", label, joints_words(robot))
        check_configuration(q0, f"{label}: field 'q0'", robot=robot)
        if data.get("palm_pose") is None:
            pose = palm_at(q0, robot)
        else:
            pose = _array_field(data, "palm_pose", label, "a 4x4 matrix (world frame)")
            if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
                raise ValueError(f"{label}: field 'palm_pose': must be a finite 4x4 matrix, "
                                 f"got shape {pose.shape}")
        moved = _object_moved(data, pose, obj)
        if moved is not None:
            raise ValueError(f"{label}: planned with {obj} at another pose than the catalog's "
                             f"now ({moved[0] * 1e3:.1f} mm, {math.degrees(moved[1]):.1f} "
                             f"degrees away; moved by `kinegrasp objects place`?): its q0 no "
                             "longer reaches the object; solve its palm poses again by "
                             "renaming the file's 'grasps' list to 'candidates'")
        contacts = data.get("contacts", [])
        if not isinstance(contacts, list):
            raise ValueError(f"{label}: field 'contacts': must be a list of "
                             "{finger, link, point, normal} objects")
        rows = [_contact(c, f"{label}: field 'contacts' entry {j}")
                for j, c in enumerate(contacts)]
        try:
            q_nominal = float(data.get("q_nominal", 0.0))
        except (TypeError, ValueError):
            q_nominal = math.nan
        if not math.isfinite(q_nominal):
            raise ValueError(f"{label}: field 'q_nominal': must be a finite number, got "
                             f"{data.get('q_nominal')!r}")
        meta = data.get("meta", {})
        if not isinstance(meta, dict):
            raise ValueError(f"{label}: field 'meta': must be an object")
        points = np.array([r[2] for r in rows], dtype=float).reshape(-1, 3)
        normals = np.array([r[3] for r in rows], dtype=float).reshape(-1, 3)
        fingers = np.array([r[0] for r in rows], dtype=int)
        links = np.array([r[1] for r in rows], dtype=int)
        return cls(obj, q0, pose, points, normals, fingers, links, q_nominal,
                   str(data.get("id", default_id)), dict(meta), robot)


def check_grasp(value) -> None:
    """ValueError (one line naming the type) unless ``value`` is a :class:`Grasp`."""
    if not isinstance(value, Grasp):
        raise ValueError(f"grasp must be a Grasp (kinegrasp_env.world.grasps), got "
                         f"{type(value).__name__}")


def check_robot(grasp: Grasp, robot: str, option: str = "") -> None:
    """ValueError (one line) when the grasp was made for another robot than ``robot``,
    advising its own robot (and the command ``option`` that names it, e.g. ``--robot``)."""
    if grasp.robot != robot:
        advice = f" ({option} {grasp.robot})" if option else ""
        raise ValueError(f"grasp {grasp.id!r} is a grasp of robot {grasp.robot!r}, not of "
                         f"{robot!r}; use it with robot {grasp.robot!r}{advice}")

#: How far (metres, radians) the object may lie from where a grasp entry's palm poses put it
#: before the entry is stale: 10 um and 1e-5 rad, above a pose saved in float32 or rounded
#: to 8 decimals (gaps up to ~1e-7) and far below any placement a user makes.
MOVED_TOL = 1e-5


def _object_moved(data: dict, palm_world: np.ndarray, name: str) -> tuple[float, float] | None:
    """(distance m, angle rad) between object ``name``'s catalog pose and the pose an entry's
    palm poses imply (its world-frame ``palm_pose`` (4, 4) ``palm_world`` and its
    object-frame ``position`` + ``quaternion``), or None where they agree to
    :data:`MOVED_TOL` or the entry has no object-frame pose."""
    from kinegrasp_env.robot.palm_pose import quaternion_matrix

    try:
        position = np.asarray(data["position"], dtype=float).reshape(3)
        quaternion = np.asarray(data["quaternion"], dtype=float).reshape(4)
    except (KeyError, TypeError, ValueError):
        return None
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quaternion))
            and np.linalg.norm(quaternion) > 0):
        return None
    in_object = np.eye(4)
    in_object[:3, :3] = quaternion_matrix(quaternion / np.linalg.norm(quaternion))
    in_object[:3, 3] = position
    gap = pose_gap(palm_world @ np.linalg.inv(in_object), load_object(name).pose)
    return None if max(gap) <= MOVED_TOL else gap


def pose_gap(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(distance m, angle rad) between two poses (4, 4): an object moved by more than
    :data:`MOVED_TOL` in either is no longer where grasps planned for the other reach. The
    angle is 2 asin(|R_a - R_b|_F / (2 sqrt 2)), exact for rotations and, unlike the
    arccos of the trace, as accurate as the matrices' entries for small angles."""
    distance = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
    chord = float(np.linalg.norm(a[:3, :3] - b[:3, :3])) / (2.0 * np.sqrt(2.0))
    return distance, float(2.0 * np.arcsin(min(chord, 1.0)))


def _array_field(data: dict, name: str, label: str, what: str) -> np.ndarray:
    """Field ``name`` of an entry as a float array (ValueError naming entry and field)."""
    if name not in data:
        raise ValueError(f"{label}: field {name!r} missing ({what})")
    try:
        return np.asarray(data[name], dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{label}: field {name!r}: expected {what}, got "
                         f"{data[name]!r:.60}") from None


def _contact(entry, label: str) -> tuple[int, int, np.ndarray, np.ndarray]:
    """(finger, link, point (3,), normal (3,)) of one ``contacts`` entry."""
    if not isinstance(entry, dict):
        raise ValueError(f"{label}: expected an object with point, normal, finger, link")
    out = []
    for name in ("point", "normal"):
        value = _array_field(entry, name, label, "3 numbers (object frame)")
        if value.shape != (3,) or not np.all(np.isfinite(value)):
            raise ValueError(f"{label}: field {name!r}: expected 3 finite numbers, got "
                             f"{entry[name]!r:.60}")
        out.append(value)
    try:
        finger, link = int(entry.get("finger", -1)), int(entry.get("link", -1))
    except (TypeError, ValueError):
        raise ValueError(f"{label}: fields 'finger', 'link' must be integers") from None
    return finger, link, out[0], out[1]


def palm_pose_fields(grasp: Grasp, object_pose: np.ndarray) -> dict:
    """The grasp as a palm-pose candidate (``kinegrasp_env.toolkit.candidates``):
    ``position`` (3,) metres and ``quaternion`` (4,) [x, y, z, w] of the palm frame in the
    object frame, ``hand`` (h,) the pre-shape (radians or metres, in the robot's hand joint
    order), ``spread`` (radians: the value of the hand's one pre-shape-only joint, where it
    has one: :func:`~kinegrasp_env.robot.palm_pose.spread_joint`) and ``elbow`` (the elbow
    angle psi, radians; only when ``meta`` records ``elbow_angle``).

    Args:
        grasp: the grasp (its ``palm_pose`` is in the world frame).
        object_pose: (4, 4) the object frame in the world frame.
    """
    from kinegrasp_env.robot.palm_pose import spread_joint
    from kinegrasp_env.world.sim import matrix_to_pose

    position, quaternion = matrix_to_pose(np.linalg.solve(object_pose, grasp.palm_pose))
    fields = {"position": [float(v) for v in position], "quaternion": quaternion,
              "hand": grasp.hand.tolist()}
    description = load_robot(grasp.robot)
    joint = spread_joint(description)
    if joint is not None:
        fields["spread"] = float(grasp.hand[description.hand_joints.index(joint)])
    if grasp.meta.get("elbow_angle") is not None:
        fields["elbow"] = float(grasp.meta["elbow_angle"])
    return fields


def read_json_file(path: str | Path) -> object:
    """The parsed JSON of a user's file; a missing file or bad JSON is a ValueError naming
    the file (grasp files, candidate files)."""
    path = Path(path)
    return parse_json(read_user_text(path), path)


def load_grasps(path: str | Path) -> list[Grasp]:
    """Read a grasp file: ``{"object": NAME, "grasps": [entry, ...]}``, each entry with the
    fields of README's grasp-file table (see :meth:`Grasp.from_dict`; an entry's ``object``
    defaults to the top-level one, its ``id`` to its index). ValueError names the file, the
    entry and the field."""
    path = Path(path)
    data = read_json_file(path)
    if holds_candidates(data):
        raise ValueError(f"{path} is a palm-pose file (a 'candidates' list), not a grasp file "
                         "(a 'grasps' list); its candidates become grasps once solved: "
                         "`kinegrasp rank`, `evaluate`, `report`, `elbow`, `sensitivity` and "
                         "`validate` take it as it is")
    if not isinstance(data, dict) or not isinstance(data.get("grasps"), list):
        raise ValueError(f"{path}: expected an object with a 'grasps' list")
    top = data.get("object")
    if top is not None and (not isinstance(top, str) or not is_object(top)):
        raise ValueError(f"{path}: field 'object': {unknown_object(top)}")
    robot = data.get("robot")
    if robot is not None:
        robot_model(robot, f"{path}: field 'robot'")
    grasps = [Grasp.from_dict(g, f"{path} grasp {i}", object_name=top, default_id=str(i),
                              robot_name=robot)
              for i, g in enumerate(data["grasps"])]
    check_unique_ids([g.id for g in grasps], str(path), "grasps",
                     objects=[g.object for g in grasps])
    return grasps


def holds_candidates(data) -> bool:
    """Whether the JSON value ``data`` is a palm-pose file's (an object with a
    ``candidates`` list), not a grasp file's."""
    return isinstance(data, dict) and "candidates" in data


def check_unique_ids(ids: list[str], where: str, what: str,
                     objects: list[str] | None = None) -> None:
    """ValueError naming the first two entries of ``ids`` (of the ``what`` of ``where``, a
    file) that share an id, among the entries of one object where ``objects`` gives each
    entry's (a file of several objects' grasps may number each object's from 0): a grasp or
    candidate is chosen, and its results are keyed, by its id."""
    first: dict[tuple[str | None, str], int] = {}
    for i, entry_id in enumerate(ids):
        key = (None if objects is None else objects[i], entry_id)
        if key in first:
            of = "" if objects is None else f" of {objects[i]}"
            raise ValueError(f"{where}: {what} {first[key]} and {i} have the same id "
                             f"{entry_id!r}{of}; ids must be unique")
        first[key] = i


def save_grasps(grasps: list[Grasp], path: str | Path, **extra) -> Path:
    """Write grasps to ``path`` atomically (temporary file, then rename), each with its
    palm-pose candidate fields in its object's frame (:func:`palm_pose_fields`)."""
    path = Path(path)
    poses = {name: load_object(name).pose for name in {g.object for g in grasps}}
    robots = {g.robot for g in grasps}
    if len(robots) == 1 and robots != {DEFAULT_ROBOT}:
        extra = {"robot": robots.pop(), **extra}
    payload = {"object": grasps[0].object if grasps else None, **extra,
               "grasps": [g.to_dict(poses[g.object]) for g in grasps]}
    write_atomic(path, json.dumps(payload, indent=1))
    return path


class NoGraspSetError(ValueError):
    """An object without a shipped grasp set for the robot asked: ``reason`` why, then
    ``advice`` (on the command line: ``kinegrasp plan``, :func:`plan_command`); ``imported``:
    because it is an imported object."""

    def __init__(self, reason: str, advice: str, imported: bool = False):
        super().__init__(f"{reason}; {advice}")
        self.reason, self.imported = reason, imported


def plan_command(robot: str, object_name: str, out: bool = False) -> str:
    """The command that plans grasps of ``object_name`` for ``robot``; with ``out``, into
    the file ``<object>_grasps.json``."""
    command = f"kinegrasp plan --robot {robot} --object {object_name}"
    return f"{command} --out {object_name}_grasps.json" if out else command


def no_grasp_set(object_name: str, robot: str = DEFAULT_ROBOT) -> NoGraspSetError:
    """The error for an imported object, which has no shipped grasp set (of ``robot``)."""
    return NoGraspSetError(
        f"{object_name!r} is an imported object and has no shipped grasp set",
        f"make one with `{plan_command(robot, object_name, out=True)}` and give that file "
        "with --grasps FILE (to `kinegrasp rank`, as its input: `kinegrasp rank FILE`)",
        imported=True)


def shipped_objects(robot: str = DEFAULT_ROBOT) -> tuple[str, ...]:
    """The objects with a shipped grasp set for ``robot``: those of
    ``assets/grasps/<robot>/`` (sorted in the catalog's order, built-in objects first)."""
    folder = assets_dir() / "grasps" / robot
    found = {p.stem for p in folder.glob("*.json")} if folder.is_dir() else set()
    return (tuple(n for n in OBJECT_NAMES if n in found)
            + tuple(sorted(found.difference(OBJECT_NAMES))))


def shipped_grasps(object_name: str, robot: str = DEFAULT_ROBOT) -> list[Grasp]:
    """The shipped grasp set of an object for catalog robot ``robot``
    (``assets/grasps/<robot>/<object>.json``: the planners' output, where one is shipped:
    :func:`shipped_objects`).

    A placed copy of an object with a shipped set (``kinegrasp objects place drill --as
    NAME``) that stands where that object stands has its set (its grasps named after the
    copy): its arm configurations reach the same contacts, and its table may make some of them
    start in collision.

    Raises:
        NoGraspSetError: for an imported object, or a placed copy moved from where its
            grasps were planned, or an object with no shipped set for ``robot``; ValueError
            for an unknown name.
    """
    check_robot_name(robot)  # an unknown robot named as such, before its grasps are sought
    if not isinstance(object_name, str) or not is_object(object_name):
        raise unknown_object(object_name)
    shipped = shipped_objects(robot)
    if object_name in shipped:
        return load_grasps(shipped_grasp_file(object_name, robot))
    base = object_name if object_name in OBJECT_NAMES else load_object(object_name).base
    if base not in OBJECT_NAMES:
        raise no_grasp_set(object_name, robot)
    if base not in shipped:
        raise NoGraspSetError(
            f"robot {robot!r} has no shipped grasps of {object_name!r} (shipped: "
            f"{', '.join(shipped) or 'none'})",
            f"plan them (`{plan_command(robot, object_name)}`)")
    if max(pose_gap(load_object(object_name).pose, load_object(base).pose)) > MOVED_TOL:
        raise NoGraspSetError(
            f"{object_name!r} stands elsewhere than {base!r}, so the shipped grasps' arm "
            "configurations miss it",
            f"plan for it (`{plan_command(robot, object_name)}`) or give palm poses "
            "(`kinegrasp rank CANDIDATES.json`)")
    return [replace(g, object=object_name) for g in shipped_grasps(base, robot)]


def grasp_by_index(object_name: str, index: int) -> Grasp:
    grasps = shipped_grasps(object_name)
    if not 0 <= index < len(grasps):
        raise ValueError(f"grasp index {index} out of range: {object_name} has "
                         f"{len(grasps)} grasps (0..{len(grasps) - 1})")
    return grasps[index]

