"""Newton on the arm's self-motion as one compiled loop: the palm held, the elbow angle moved.

:func:`continue_elbow` (run by :meth:`kinegrasp_env.robot.ik.ArmIK.set_elbow_angle` and by
every robot's :class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`) solves, at each
continuation step, the square system "palm pose error = 0 (6 rows), elbow angle - goal = 0
(1 row)" in the 7 arm joints, three times: the step, and the same step in two halves as its
continuity check. For one configuration (what the environment asks for at every step) the batched
numpy kinematics spend almost all their time in per-call overhead (paid at every step, and
a curve of elbow angles takes ~30 of them); here each row runs its whole Newton loop
compiled (timings: ``benchmarks/bench_self_motion.py``): the
chain base -> palm as 4x4 products, the palm's geometric Jacobian, the elbow angle's
gradient by central differences, a 7x7 solve.

The pose error, the elbow angle and the Jacobian's joint columns are the row functions of
:mod:`kinegrasp_env.robot.pose_rules`, which :mod:`kinegrasp_env.robot.kinematics` applies
to batches; ``tests/test_ik.py`` checks the chain poses against the batched kinematics (an
independent implementation: column-wise rotations), and the Newton's results against this
kernel run interpreted.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.robot.kinematics import (
    Kinematics,
    elbow_angle,
    snap_rotation,
)
from kinegrasp_env.robot.pose_rules import add_joint_column, elbow_angle_of, pose_error_into

#: Newton stops where the residual (palm error, metres and radians, and the elbow angle
#: error, radians) has a norm below this.
RESIDUAL_TOL = 1e-11
#: Largest change of one joint per Newton iteration (radians).
MAX_JOINT_STEP = 0.2
#: Central-difference step of the elbow angle's gradient (radians).
GRADIENT_STEP = 1e-6
#: A continuation step's Newton converged where its residual's norm (metres, radians) is
#: below this, whichever Newton solved it (:func:`compiled_step`, the numpy one of
#: :class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`).
CONVERGED_TOL = 1e-9
#: A continuation step and the same step in two halves end within this (radians, any
#: joint): else the step left the path (:func:`continue_elbow`).
CONTINUITY_TOL = 1e-6
#: A continuation step is checked where its halves are at least this (radians of the elbow
#: angle); a step that fails is taken again in halves until they would fall below it.
MIN_CHECKED_STEP = 0.01


@dataclass(frozen=True, eq=False)
class ArmChain:
    """The serial chain from the robot's base to one link, as arrays for the kernel.

    Attributes:
        origins: (J, 4, 4) each joint's fixed origin transform (parent link -> joint frame;
            rotation entries within 1e-10 of 0 or +-1 set to that value, as
            :func:`kinegrasp_env.robot.kinematics.snap_rotation` does for the numpy FK).
        axes: (J, 3) unit joint axes in the joint frame.
        index: (J,) int64: the arm joint (0..6) that drives each joint, -1 for fixed joints.
        marks: (3,) int64: the joints whose child frames are the shoulder, elbow and wrist
            (the description's ``arm_angle_links``).
    """

    origins: np.ndarray
    axes: np.ndarray
    index: np.ndarray
    marks: np.ndarray


def arm_chain(kin: Kinematics, link: str, arm_index: np.ndarray,
              angle_links: tuple[str, str, str]) -> ArmChain:
    """The chain to ``link`` whose movable joints are the actuated joints ``arm_index``
    (driven directly: multiplier 1, offset 0), its elbow angle that of the shoulder, elbow
    and wrist links ``angle_links``. ValueError for any other chain."""
    drivers = kin.model.drivers()
    chain = kin.chain(link)
    arm = [int(i) for i in arm_index]
    index = []
    for joint in chain:
        if not joint.movable:
            index.append(-1)
            continue
        source, mult, off = drivers[joint.name]
        driven = source in arm and mult == 1.0 and off == 0.0
        if joint.kind not in ("revolute", "continuous") or not driven:
            raise ValueError(f"joint {joint.name!r} is not an arm joint driven directly")
        index.append(arm.index(source))
    children = [joint.child for joint in chain]
    missing = [name for name in angle_links if name not in children]
    if missing:
        raise ValueError(f"the chain to {link!r} does not pass {missing}")
    origins = np.array([j.origin for j in chain], dtype=float)
    for origin in origins:  # URDF right angles rounded as the numpy kinematics round them
        origin[:3, :3] = snap_rotation(origin[:3, :3])
    return ArmChain(np.ascontiguousarray(origins),
                    np.ascontiguousarray([j.axis for j in chain], dtype=float),
                    np.array(index, dtype=np.int64),
                    np.array([children.index(name) for name in angle_links],
                             dtype=np.int64))


@jit.kernel
def chain_forward(origins, axes, index, q, frames):
    """Poses (J, 4, 4) of every joint's child frame at arm joints q (7,) into frames."""
    rot = np.empty((3, 3))
    parent = np.eye(4)
    for j in range(origins.shape[0]):
        # pose = parent @ origin
        for r in range(4):
            for c in range(4):
                frames[j, r, c] = (parent[r, 0] * origins[j, 0, c]
                                   + parent[r, 1] * origins[j, 1, c]
                                   + parent[r, 2] * origins[j, 2, c]
                                   + parent[r, 3] * origins[j, 3, c])
        if index[j] >= 0:  # then @ the joint's rotation about its axis (Rodrigues)
            x, y, z = axes[j, 0], axes[j, 1], axes[j, 2]
            angle = q[index[j]]
            co, si = np.cos(angle), np.sin(angle)
            t = 1.0 - co
            rot[0, 0], rot[0, 1], rot[0, 2] = co + x * x * t, x * y * t - z * si, \
                x * z * t + y * si
            rot[1, 0], rot[1, 1], rot[1, 2] = y * x * t + z * si, co + y * y * t, \
                y * z * t - x * si
            rot[2, 0], rot[2, 1], rot[2, 2] = z * x * t - y * si, z * y * t + x * si, \
                co + z * z * t
            for r in range(3):
                a0, a1, a2 = frames[j, r, 0], frames[j, r, 1], frames[j, r, 2]
                for c in range(3):
                    frames[j, r, c] = a0 * rot[0, c] + a1 * rot[1, c] + a2 * rot[2, c]
        for r in range(4):
            for c in range(4):
                parent[r, c] = frames[j, r, c]


@jit.kernel
def elbow_angle_one(frames, marks):
    """Elbow angle (radians) from the shoulder, elbow and wrist origins in frames (J, 4, 4)
    (:func:`kinegrasp_env.robot.pose_rules.elbow_angle_of`)."""
    s, e, w = marks[0], marks[1], marks[2]
    return elbow_angle_of(frames[s, 0, 3], frames[s, 1, 3], frames[s, 2, 3],
                          frames[e, 0, 3], frames[e, 1, 3], frames[e, 2, 3],
                          frames[w, 0, 3], frames[w, 1, 3], frames[w, 2, 3])


@jit.kernel
def palm_error(frames, target, out):
    """Pose error (6,) of the chain's last frame against target (4, 4) into out
    (:func:`kinegrasp_env.robot.pose_rules.pose_error_into`)."""
    pose_error_into(frames[frames.shape[0] - 1], target, out)


@jit.kernel
def newton_row(origins, axes, index, marks, q, target, goal, iterations, err):
    """Newton on "palm error = 0, elbow angle = goal" from arm joints q (7,), in place;
    the palm error (6,) at the result into err."""
    n_joints = origins.shape[0]
    frames = np.empty((n_joints, 4, 4))
    probe = np.empty((n_joints, 4, 4))
    jac = np.empty((7, 7))
    residual = np.empty(7)
    shifted = np.empty(7)
    last = n_joints - 1
    for _ in range(iterations):
        chain_forward(origins, axes, index, q, frames)
        palm_error(frames, target, residual)
        diff = goal - elbow_angle_one(frames, marks)
        residual[6] = np.arctan2(np.sin(diff), np.cos(diff))
        if np.sqrt(np.sum(residual * residual)) < RESIDUAL_TOL:
            break
        jac[:, :] = 0.0
        for j in range(n_joints):  # geometric Jacobian of the palm origin and frame
            k = index[j]
            if k < 0:
                continue
            x, y, z = axes[j, 0], axes[j, 1], axes[j, 2]
            wx = frames[j, 0, 0] * x + frames[j, 0, 1] * y + frames[j, 0, 2] * z
            wy = frames[j, 1, 0] * x + frames[j, 1, 1] * y + frames[j, 1, 2] * z
            wz = frames[j, 2, 0] * x + frames[j, 2, 1] * y + frames[j, 2, 2] * z
            dx, dy, dz = (frames[last, 0, 3] - frames[j, 0, 3],
                          frames[last, 1, 3] - frames[j, 1, 3],
                          frames[last, 2, 3] - frames[j, 2, 3])
            add_joint_column(jac, k, 1.0, True, wx, wy, wz, dx, dy, dz)
        for k in range(7):  # the elbow angle's gradient, by central differences
            shifted[:] = q
            shifted[k] = q[k] + GRADIENT_STEP
            chain_forward(origins, axes, index, shifted, probe)
            plus = elbow_angle_one(probe, marks)
            shifted[k] = q[k] - GRADIENT_STEP
            chain_forward(origins, axes, index, shifted, probe)
            diff = plus - elbow_angle_one(probe, marks)
            jac[6, k] = np.arctan2(np.sin(diff), np.cos(diff)) / (2.0 * GRADIENT_STEP)
        step = solve_or_least_squares(jac, residual)
        for k in range(7):
            if np.isfinite(step[k]):
                q[k] += min(max(step[k], -MAX_JOINT_STEP), MAX_JOINT_STEP)
    chain_forward(origins, axes, index, q, frames)
    palm_error(frames, target, err)


@jit.kernel
def solve_or_least_squares(jac, residual):
    """jac^-1 residual, or the least-squares step (pseudo-inverse) where jac is singular."""
    try:
        return np.linalg.solve(jac, residual)
    except Exception:  # numba raises a LinAlgError it cannot name here
        return np.linalg.pinv(jac) @ residual


@jit.kernel
def newton_rows(origins, axes, index, marks, q, target, goal, iterations, err):
    """:func:`newton_row` for every row: q (m, 7) in place, target (m, 4, 4), goal (m,),
    err (m, 6)."""
    for i in range(q.shape[0]):
        newton_row(origins, axes, index, marks, q[i], target[i], goal[i], iterations, err[i])


def self_motion_newton(chain: ArmChain, q_arm: np.ndarray, target: np.ndarray,
                       goal: np.ndarray, iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Newton from arm joints q_arm (m, 7) (radians) towards palm poses target (m, 4, 4)
    (world frame, metres) and elbow angles goal (m,) (radians): (arm joints (m, 7), palm
    pose error (m, 6) there: metres, then radians)."""
    q = np.array(q_arm, dtype=float, order="C")
    err = np.empty((q.shape[0], 6))
    newton_rows(chain.origins, chain.axes, chain.index, chain.marks, q,
                np.ascontiguousarray(target, dtype=float),
                np.ascontiguousarray(goal, dtype=float), int(iterations), err)
    return q, err


#: One Newton solve of a continuation step: (rows (m, dof), targets (m, 4, 4), goals (m,)) ->
#: (configurations (m, dof), converged within the joint limits (m,)).
NewtonStep = Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def compiled_step(chain: ArmChain, kin: Kinematics, arm_index: np.ndarray,
                  newton_iterations: int = 30) -> NewtonStep:
    """The compiled Newton (:func:`self_motion_newton`) as a continuation step: converged
    where the residual is below :data:`CONVERGED_TOL`, the result within the joint limits."""
    def step(rows: np.ndarray, targets: np.ndarray, goals: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        trial = rows.copy()
        trial[:, arm_index], err = self_motion_newton(chain, trial[:, arm_index], targets,
                                                      goals, newton_iterations)
        return trial, ((np.linalg.norm(err, axis=1) < CONVERGED_TOL)
                       & kin.model.within_limits(trial))

    return step


def continue_elbow(newton: NewtonStep, kin: Kinematics, link: str,
                   angle_links: tuple[str, str, str], q: np.ndarray,
                   psi: np.ndarray | float, *, max_step: float = 0.3
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Move configurations along the self-motion to elbow angles ``psi``, the pose of
    ``link`` held, by continuation: each step one solve of ``newton`` (the compiled one,
    :func:`compiled_step`, or another implementation of the same square system).

    Each continuation step is checked for continuity: the same step taken as two half steps
    must end within :data:`CONTINUITY_TOL` of it (a Newton step of up to ``max_step`` can
    settle on another arm configuration with the same pose, e.g. the shoulder turned over,
    or step over a stretch of the path outside the joint limits). A step that fails the
    check is taken again in halves (:data:`MIN_CHECKED_STEP`).

    Args:
        newton: the Newton solve of one step (:data:`NewtonStep`); kin: the robot's
            kinematics; angle_links: the shoulder, elbow and wrist links whose centres give
            the elbow angle.
        q: (n, dof) or (dof,) start configurations; their poses of ``link`` are kept.
        psi: (n,) or scalar target elbow angles (radians).
        max_step: largest change of psi per continuation step (radians). Where the path
            stays within the limits and away from the shoulder's singularity (a2 = 0) the
            result does not depend on it (the same branch to 1e-6 rad on all 48 shipped
            grasps of the default robot from 0.05 to 0.4); near it a coarse and a fine
            continuation may pass it on different branches; a path that leaves the limits
            stops within one step of the limit.

    Returns:
        (q_new (n, dof), ok (n,)): ok is False where the path left the joint limits,
        crossed a singularity, or did not converge; q_new is then the last valid point.
    """
    q = np.array(np.atleast_2d(q), dtype=float)
    n = q.shape[0]
    poses = kin.forward(q, [link, *angle_links])
    target = poses[link]
    psi0 = elbow_angle(*(poses[name][:, :3, 3] for name in angle_links))
    delta = np.angle(np.exp(1j * (np.broadcast_to(np.asarray(psi, float), (n,)) - psi0)))
    steps = max(1, int(np.ceil(np.abs(delta).max() / max_step))) if n else 1
    ok = np.ones(n, bool)
    for s in range(1, steps + 1):
        idx = np.flatnonzero(ok)
        start, goal = psi0[idx] + delta[idx] * (s - 1) / steps, psi0[idx] + delta[idx] * s / steps
        trial, good = newton(q[idx], target[idx], goal)
        broken = np.zeros(idx.size, bool)
        if max_step / 2.0 >= MIN_CHECKED_STEP and np.any(good):
            middle, good_middle = newton(q[idx], target[idx], 0.5 * (start + goal))
            end, good_end = newton(middle, target[idx], goal)
            broken = good & ~(good_middle & good_end
                              & (np.abs(end - trial).max(axis=1) <= CONTINUITY_TOL))
        for k in np.flatnonzero(broken):  # taken again in halves (rare), to where it stops
            moved, reached = continue_elbow(newton, kin, link, angle_links, q[idx[k]],
                                            goal[k], max_step=max_step / 2.0)
            trial[k], good[k] = moved[0], reached[0]
        q[idx[good | broken]] = trial[good | broken]
        ok[idx[~good]] = False
        if not np.any(ok):
            break
    return q, ok
