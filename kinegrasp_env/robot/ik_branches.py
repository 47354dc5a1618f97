"""The IK branches of a palm pose: the distinct arm configurations that put the palm there.

A 6-joint arm is not redundant for the 6-D palm pose: the configurations reaching one pose
are finitely many (up to 16 for a general 6R arm, 8 for the common wrist-partitioned ones:
shoulder left/right x elbow up/down x wrist flipped or not), fewer within the joint limits.
They are the arm-configuration variants of a grasp (its palm pose, hence its nominal
contacts, fixed), as the self-motion is for a 7-joint arm.

:func:`ik_branches` finds them numerically for any description arm, nothing in it naming a
joint or a link: the planner's batched damped-least-squares IK
(:func:`~kinegrasp_env.robot.palm_ik.solve_palm_ik`) from ``starts`` uniform random
starts within the joint limits (a seeded Generator; a joint without limits starts in
[-pi, pi]); the converged solutions within the limits are merged when they agree to
:data:`MERGE_TOL` radians on every joint (the largest difference; a revolute joint whose
range exceeds 2 pi, or a continuous one, compared modulo 2 pi: q and q + 2 pi are one
branch). Numeric IK from random starts finds each branch reachable within the limits with a
probability that rises with the number of starts (each start falls into the basin of one
branch, or of none); it never proves that no other branch exists. Measured on the xArm 6's
two cube grasps of ``kinegrasp plan --robot xarm6 --object cube --count 2 --seed 0`` (the
first is the grasp of ``tests/test_ik_branches.py``): 3 branches each at 50, 200 and 1000
starts (starts seed 0), on the first also at 5000 and 20,000 starts but 1 at 10 and 20
(seed 1); a quarter to a third of the starts converge within the limits; each start is
one numeric IK solve, so the cost grows with the number of starts.

A branch's label is the sign pattern, among the branches found, of what differs in sign
between them: for a 6-joint arm the determinant of the palm's 6x6 Jacobian (it changes sign
across the elbow, wrist and shoulder singularities that separate branches), then each arm
joint (the description's joint names; angles wrapped as above), e.g.
``det(J)- joint1+ joint4-``; where two branches share a pattern, ``#1``, ``#2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.counts import check_count
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.palm_ik import solve_palm_ik
from kinegrasp_env.sampling.noise import SeedLike, as_generator

#: Two solutions are one branch when no joint differs by more than this (radians or metres).
#: Converged solutions of one branch agree to ~1e-6 (the IK's tolerance is 1e-7 m and rad).
MERGE_TOL = 1e-3
#: Default number of random IK starts.
DEFAULT_STARTS = 200
#: Seed of the random IK starts wherever a palm pose's branches are searched (the elbow
#: search, the envs' branch coordinates, the figures' variants): a palm pose's branches are
#: the same in every run, whatever its noise seed.
BRANCH_SEED = 0
#: DLS iterations per start.
IK_ITERATIONS = 200
#: A joint's sign counts in a label where |angle| exceeds this (radians).
SIGN_TOL = 1e-3


@dataclass(frozen=True)
class IKBranch:
    """One IK branch of a palm pose.

    Attributes:
        q: (arm_dof,) arm joints (radians or metres), within the limits; of the solutions
            merged into it, the one nearest the middle of the joint ranges.
        label: the sign pattern that tells it from the other branches found (module docstring).
        hits: how many of the starts converged to it.
    """

    q: np.ndarray
    label: str
    hits: int


def wrapped_joints(description: RobotDescription) -> np.ndarray:
    """(arm_dof,) bool: the arm joints compared modulo 2 pi (continuous, or a revolute range
    wider than 2 pi)."""
    model = description.model
    out = []
    for name in description.arm_joints:
        joint = model.joint(name)
        out.append(joint.kind == "continuous"
                   or (joint.kind == "revolute" and joint.upper - joint.lower > 2 * np.pi))
    return np.array(out, dtype=bool)


def joint_difference(description: RobotDescription, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest joint difference (...,) between arm configurations a and b (..., arm_dof),
    broadcast; wrapped joints (:func:`wrapped_joints`) modulo 2 pi."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    d = np.where(wrapped_joints(description), np.angle(np.exp(1j * d)), d)
    return np.abs(d).max(axis=-1)


def _check(description: RobotDescription, palm_pose, starts) -> np.ndarray:
    pose = np.asarray(palm_pose, dtype=float)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise ValueError(f"palm_pose must be a finite (4, 4) pose, got shape {pose.shape}")
    rot = pose[:3, :3]
    if (np.abs(rot.T @ rot - np.eye(3)).max() > 1e-6 or np.linalg.det(rot) < 0
            or not np.allclose(pose[3], [0, 0, 0, 1])):
        raise ValueError("palm_pose is not a rigid transform (orthonormal right-handed "
                         "rotation, last row 0 0 0 1)")
    check_count(starts, "starts")
    if description.arm_dof < 1:
        raise ValueError(f"robot {description.name!r} has no arm joints")
    return pose


def _labels(description: RobotDescription, kin: Kinematics, qs: np.ndarray) -> list[str]:
    """Sign-pattern labels of branches qs (m, arm_dof), unique (a repeated one gets #k)."""
    wrapped = np.where(wrapped_joints(description), np.angle(np.exp(1j * qs)), qs)
    signs = np.where(wrapped > SIGN_TOL, 1, np.where(wrapped < -SIGN_TOL, -1, 0))
    names = list(description.arm_joints)
    if qs.shape[1] == 6 and len(qs):  # a square Jacobian: its determinant's sign too
        det = np.linalg.det(kin.jacobian(_full(description, qs), description.palm_link)
                            [:, :, :6])
        signs = np.concatenate([np.sign(det).astype(int)[:, None], signs], axis=1)
        names = ["det(J)", *names]
    flips = [j for j in range(signs.shape[1]) if np.unique(signs[:, j]).size > 1]
    base = [" ".join(f"{names[j]}{'+-0'[[1, -1, 0].index(s[j])]}" for j in flips)
            or "branch" for s in signs]
    labels = []
    for i, text in enumerate(base):
        labels.append(text if base.count(text) == 1 else f"{text} #{base[:i + 1].count(text)}")
    return labels


def _full(description: RobotDescription, arms: np.ndarray) -> np.ndarray:
    """(n, dof) configurations: arm joints ``arms`` (n, arm_dof), the hand at its open
    pre-shape."""
    full = np.repeat(description.open_configuration()[None], len(arms), axis=0)
    full[:, :description.arm_dof] = arms
    return full


def ik_branches(description: RobotDescription, palm_pose: np.ndarray, *,
                starts: int = DEFAULT_STARTS, seed: SeedLike = BRANCH_SEED,
                merge_tol: float = MERGE_TOL, kin: Kinematics | None = None
                ) -> list[IKBranch]:
    """The distinct IK branches of ``palm_pose`` (module docstring), sorted by their joints.

    Args:
        description: the robot (any number of arm joints; a 7-joint arm's solutions form a
            curve, sampled here at random: use its self-motion instead).
        palm_pose: (4, 4) world pose of the description's palm link (metres).
        starts: random IK starts.
        seed: seed or Generator of the starts.
        merge_tol: joint-space tolerance of one branch (radians or metres).
        kin: the robot's kinematics (default: built from ``description.model``).

    Returns:
        The branches (possibly none: the pose is out of reach within the limits).

    Raises:
        ValueError: a palm pose that is not a finite rigid transform, a bad ``starts``.
    """
    pose = _check(description, palm_pose, starts)
    rng = as_generator(seed)
    kin = kin or Kinematics(description.model)
    dof = description.arm_dof
    lo, hi = description.model.lower[:dof], description.model.upper[:dof]
    draw_lo = np.where(np.isfinite(lo), lo, -np.pi)
    draw_hi = np.where(np.isfinite(hi), hi, np.pi)
    first = rng.uniform(draw_lo, draw_hi, size=(int(starts), dof))
    arms, ok = solve_palm_ik(kin, description, np.repeat(pose[None], int(starts), axis=0), rng,
                             restarts=0, iterations=IK_ITERATIONS, starts=first)
    ok &= description.model.within_limits(_full(description, arms))
    mid = 0.5 * (draw_lo + draw_hi)
    half = np.maximum(0.5 * (draw_hi - draw_lo), 1e-12)
    groups: list[list[np.ndarray]] = []
    for q in arms[ok]:
        for group in groups:
            if joint_difference(description, q, group[0]) <= merge_tol:
                group.append(q)
                break
        else:
            groups.append([q])
    reps = [min(g, key=lambda q: float(np.abs((q - mid) / half).max())) for g in groups]
    wrapped = wrapped_joints(description)
    order = sorted(range(len(groups)), key=lambda i: tuple(np.round(np.where(
        wrapped, np.angle(np.exp(1j * reps[i])), reps[i]), 3)))
    qs = np.array([reps[i] for i in order]).reshape(len(order), dof)
    labels = _labels(description, kin, qs)
    return [IKBranch(qs[k].copy(), labels[k], len(groups[i])) for k, i in enumerate(order)]
