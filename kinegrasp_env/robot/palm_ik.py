"""A robot's palm put at a pose: damped least-squares IK on its arm joints
(:func:`solve_palm_ik`, batched over poses), and one palm-pose entry reached, every robot's
the same way (:func:`reach_robot_palm_pose`: IK from the description's ``home``, then random
restarts seeded per pose, then the self-motion to the entry's elbow angle where it gives
one)."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics, pose_error
from kinegrasp_env.robot.palm_pose import IK_RNG_SEED

#: Random restarts of the IK after its start from the description's home.
IK_RESTARTS = 6
#: Damped least-squares iterations per start.
IK_ITERATIONS = 200
#: Batches of further random starts :func:`reach_robot_palm_pose` tries for an elbow angle
#: the first IK solution's self-motion does not reach (the solutions of one batch of 6 starts
#: reached the elbow angle of a planned Panda grasp on 2 of 3 grasps; a reachable angle's
#: branch is found by 25-85% of the solutions on eight planned cube grasps).
ELBOW_BATCHES = 8


def solve_palm_ik(kin: Kinematics, description: RobotDescription, targets: np.ndarray,
                  rng: np.random.Generator, *, restarts: int = IK_RESTARTS,
                  iterations: int = IK_ITERATIONS,
                  damping: float = 1e-2, tol: float = 1e-7, starts: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Arm joints putting the palm at each of ``targets`` (n, 4, 4), batched.

    Damped least squares from ``starts`` (n, arm_dof) radians or metres, default the
    description's ``home`` (by default the middle of the joint ranges), then from
    ``restarts`` uniform random starts within the limits for
    the targets not reached yet; a step is clipped into the limits; success when the
    position error (metres) and the rotation error (radians) are below ``tol``.

    Returns:
        (arm joints (n, arm_dof), success (n,) bool): a target not reached gets the arm of
        its closest attempt (the smallest position plus rotation error).
    """
    model = description.model
    arm = np.arange(description.arm_dof)
    lo, hi = model.lower[arm], model.upper[arm]
    n = len(targets)
    q = np.repeat(description.open_configuration()[None], n, axis=0)
    q[:, arm] = description.home_arm() if starts is None else np.clip(starts, lo, hi)
    done = np.zeros(n, bool)
    closest, miss = q[:, arm].copy(), np.full(n, np.inf)
    eye = np.eye(6)
    for attempt in range(restarts + 1):
        rows = np.flatnonzero(~done)
        if attempt > 0:
            _keep_closest(kin, description, q, targets, rows, closest, miss)
        if rows.size == 0:
            break
        if attempt > 0:
            q[np.ix_(rows, arm)] = rng.uniform(lo, hi, size=(rows.size, arm.size))
        for _ in range(iterations):
            err = pose_error(kin.pose(q[rows], description.palm_link), targets[rows])
            ok = (np.linalg.norm(err[:, :3], axis=1) < tol) & (
                np.linalg.norm(err[:, 3:], axis=1) < tol)
            done[rows[ok]] = True
            rows, err = rows[~ok], err[~ok]
            if rows.size == 0:
                break
            jac = kin.jacobian(q[rows], description.palm_link)[:, :, arm]
            lam = (damping * np.minimum(np.linalg.norm(err, axis=1), 1.0))[:, None, None] ** 2
            jt = np.swapaxes(jac, 1, 2)
            step = (jt @ np.linalg.solve(jac @ jt + lam * eye, err[..., None]))[..., 0]
            step *= np.minimum(1.0, 0.5 / np.maximum(np.abs(step).max(axis=1), 1e-12))[:, None]
            q[np.ix_(rows, arm)] = np.clip(q[np.ix_(rows, arm)] + step, lo, hi)
    _keep_closest(kin, description, q, targets, np.flatnonzero(~done), closest, miss)
    out = q[:, arm].copy()
    out[~done] = closest[~done]
    return out, done


def _keep_closest(kin: Kinematics, description: RobotDescription, q: np.ndarray,
                  targets: np.ndarray, rows: np.ndarray, closest: np.ndarray,
                  miss: np.ndarray) -> None:
    """Where the attempt just ended (``q``'s ``rows``, not reached) came closer to its target
    than any before (``miss``: position plus rotation error), keep its arm in ``closest``."""
    if rows.size == 0:
        return
    err = pose_error(kin.pose(q[rows], description.palm_link), targets[rows])
    size = np.linalg.norm(err[:, :3], axis=1) + np.linalg.norm(err[:, 3:], axis=1)
    better = size < miss[rows]
    miss[rows[better]] = size[better]
    closest[rows[better]] = q[np.ix_(rows[better], np.arange(description.arm_dof))]


def reach_robot_palm_pose(kin: Kinematics, description: RobotDescription, target: np.ndarray,
                          hand: np.ndarray, elbow: float | None = None, *, motion=None,
                          restarts: int = IK_RESTARTS, iterations: int = IK_ITERATIONS
                          ) -> tuple[np.ndarray | None, str]:
    """(q (dof,): arm joints then the pre-shape ``hand``, "") whose palm is at ``target``
    (4, 4) in the robot's base frame, or (None, why).

    IK by :func:`solve_palm_ik`, its restarts seeded by :data:`~kinegrasp_env.robot.
    palm_pose.IK_RNG_SEED`; then, for an ``elbow`` angle (radians), the self-motion
    ``motion`` (:class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`) to it. The
    self-motion of one IK solution may leave the joint limits before the angle where another
    branch of the arm (its shoulder, elbow or wrist flipped) reaches it: the solutions from
    further random starts (up to :data:`ELBOW_BATCHES` batches of ``restarts``, from the same
    seeded stream) are tried in turn until one reaches it."""
    rng = np.random.default_rng(IK_RNG_SEED)
    arm, ok = solve_palm_ik(kin, description, target[None], rng, restarts=restarts,
                            iterations=iterations)
    q = np.concatenate([arm[0], hand])
    if not ok[0]:
        err = pose_error(kin.pose(q[None], description.palm_link), target[None])[0]
        return None, (f"no IK solution within the joint limits (closest: "
                      f"{np.linalg.norm(err[:3]):.3g} m, {np.linalg.norm(err[3:]):.3g} rad off)")
    if elbow is None:
        return q, ""
    moved, reached = motion.set_elbow_angle(q, elbow)
    if reached:
        return moved, ""
    lo, hi = kin.model.lower[:description.arm_dof], kin.model.upper[:description.arm_dof]
    for _ in range(ELBOW_BATCHES):
        starts = rng.uniform(lo, hi, size=(restarts, description.arm_dof))
        arms, found = solve_palm_ik(kin, description, np.repeat(target[None], restarts, axis=0),
                                    rng, restarts=0, iterations=iterations, starts=starts)
        for other in arms[found]:
            moved, reached = motion.set_elbow_angle(np.concatenate([other, hand]), elbow)
            if reached:
                return moved, ""
    return None, (f"elbow angle {elbow:g} rad leaves the joint limits on every IK branch "
                  f"found from {ELBOW_BATCHES * restarts} further starts")
