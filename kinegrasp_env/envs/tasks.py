"""A task's grasp given the way a user describes one: an object (built-in or imported) and a
nominal arm+hand configuration ``q0`` or a palm pose (the envs' reset options).

The nominal contacts and Q are computed on the spot: the hand closes once, without noise, at
q0 with the env's engine (as the planner records a grasp). A task needs the hand to close
ON the object: the closing must touch it with >= 2 contacts and every finger closing on it
(outcome ``force_closure`` or ``no_force_closure``; the latter is a valid task with nominal
Q = 0, whose reward may still rise with the elbow or the noise). ``start_collision`` (the
open hand already in the object) and ``missed`` (fewer than 2 contacts, or a finger closing
on nothing) leave no nominal contacts and are ValueErrors naming the outcome. The arm links
are not checked against the object (the draws do not check them either).

Any robot of the env (:func:`given_robot_grasp`: the closing of the engine ``engine``
names): the robot's actuated vector, or a palm pose with its pre-shape as the description
names it, reached by every robot's one IK (:func:`palm_pose_configuration`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.envs.grasp_task import RobotTask
from kinegrasp_env.montecarlo.draws import MISSED, START_COLLISION
from kinegrasp_env.montecarlo.nominal import grasp_from_draw, outcome_detail
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.palm_ik import reach_robot_palm_pose
from kinegrasp_env.robot.palm_pose import PalmCandidate, parse_palm_pose
from kinegrasp_env.world.grasps import GRASP_ENTRY_KEYS, Grasp
from kinegrasp_env.world.objects import is_object, load_object, unknown_object
from kinegrasp_env.world.robot_configuration import check_configuration, robot_model

#: The reset options that name a task's grasp; at most one of them is given.
GRASP_OPTIONS = ("grasp", "q0", "palm_pose")


def grasp_option(options: dict) -> str | None:
    """Which of :data:`GRASP_OPTIONS` the reset options give (None: none); ValueError when
    more than one is given."""
    given = [key for key in GRASP_OPTIONS if options.get(key) is not None]
    if len(given) > 1:
        raise ValueError(f"give one of the reset options {', '.join(GRASP_OPTIONS)}, not "
                         f"{' and '.join(given)}")
    return given[0] if given else None


def task_object(options: dict, key: str) -> str:
    """The ``object`` option that a ``q0`` or ``palm_pose`` option needs: any built-in or
    imported object (not only the env's ``objects``); ValueError if missing or unknown."""
    name = options.get("object")
    if name is None:
        raise ValueError(f"the reset option {key} needs the option object (the name of a "
                         "built-in or imported object)")
    if not isinstance(name, str) or not is_object(name):
        raise unknown_object(name)
    return name


def reset_q0(value, robot: str) -> np.ndarray:
    """(dof,) a ``q0`` reset option of ``robot``, validated: its actuated vector (its arm joints
    then its hand's, radians, docs/conventions.md); finite, within the
    joint limits; ValueError names the bad entry."""
    dof = robot_model(robot).dof
    try:
        q0 = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"reset option q0 must be {dof} numbers, got {value!r}") from None
    if q0.ndim != 1:
        raise ValueError(f"reset option q0 must be a flat list of {dof} numbers, got shape "
                         f"{list(q0.shape)}")
    return check_configuration(q0, "reset option q0", robot).copy()


def palm_pose_candidate(entry, robot: RobotDescription | None = None) -> PalmCandidate:
    """A ``palm_pose`` reset option (one palm-pose entry in the object frame:
    :mod:`kinegrasp_env.robot.palm_pose`, or a grasp file's entry, which carries those
    fields) of ``robot`` (None: the default robot); ValueError for a malformed entry or one
    that names another robot."""
    if not isinstance(entry, dict):
        raise ValueError(f"reset option palm_pose must be a dict: 'position' + 'quaternion' or "
                         f"'pose' (4x4), with the hand's pre-shape (optional 'elbow', 'id'); "
                         f"got {type(entry).__name__}")
    named = entry.get("robot")
    if robot is not None and named is not None and named != robot.name:
        raise ValueError(f"reset option palm_pose: a palm pose of robot {named!r}, the env's "
                         f"robot is {robot.name!r}")
    return parse_palm_pose(entry, "reset option palm_pose", default_id="palm_pose",
                           robot=robot, other_keys=GRASP_ENTRY_KEYS)


def palm_pose_configuration(description: RobotDescription, kin, motion, object_name: str,
                            entry) -> tuple[np.ndarray, dict]:
    """(q0 (dof,), meta) reaching a ``palm_pose`` reset option of ``description``'s robot with
    the object at its pose, by every robot's palm-pose IK
    (:func:`~kinegrasp_env.robot.palm_ik.reach_robot_palm_pose`; ``kin`` the robot's
    :class:`~kinegrasp_env.robot.kinematics.Kinematics`, ``motion`` its self-motion, used for
    an ``elbow``); ValueError for a malformed entry or an unreachable pose."""
    candidate = palm_pose_candidate(entry, description)
    q0, why = reach_robot_palm_pose(kin, description,
                                    load_object(object_name).pose @ candidate.pose,
                                    candidate.hand, candidate.elbow, motion=motion)
    return reached(q0, why, object_name), {"id": candidate.id,
                                           "palm_pose_object": candidate.pose.tolist()}


def reached(q0: np.ndarray | None, why: str, object_name: str) -> np.ndarray:
    """q0, or the ValueError (one line) of a palm pose the IK did not reach, saying ``why``."""
    if q0 is None:
        raise ValueError(f"reset option palm_pose is unreachable on {object_name}: {why}")
    return q0


def check_closes(draw, object_name: str, source: str) -> None:
    """ValueError (one line naming ``source``, the option, and the outcome) unless the
    nominal closing ``draw`` (one row) touches the object: ``start_collision`` or ``missed``
    leave no nominal contacts."""
    outcome = int(draw.outcome[0])
    if outcome in (START_COLLISION, MISSED):
        raise ValueError(f"reset option {source}: the hand does not close on {object_name} "
                         f"({outcome_detail(outcome)}; {int(draw.n_contacts[0])} contacts); "
                         "a task needs >= 2 contacts with every finger on the object")


def given_robot_grasp(options: dict, key: str, task: RobotTask) -> Grasp:
    """The grasp of a ``q0`` or ``palm_pose`` reset option (``key``) of the env's robot
    (``task``) on the ``object`` option: closed once at q0 by the engine ``engine`` names."""
    name = task_object(options, key)
    description = task.description
    if key == "q0":
        q0, meta = reset_q0(options["q0"], description.name), {"id": "q0"}
    else:
        q0, meta = palm_pose_configuration(description, task.kin, task.motion, name,
                                           options["palm_pose"])
    draw = task.closing_engine(name).run(q0[None])
    check_closes(draw, name, key)
    grasp_id = meta.pop("id")
    meta = {"source": key, "elbow_angle": float(task.motion.elbow_angle(q0[None])[0]), **meta}
    return grasp_from_draw(draw, name, q0, task.kin.pose(q0[None], description.palm_link)[0],
                           grasp_id=grasp_id, meta=meta, robot=description.name)
