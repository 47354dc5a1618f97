"""Inverse kinematics of the arm for a palm pose, and the arm's 1-D self-motion.

The 7 arm joints are redundant for the 6-D palm pose: the elbow can swing about the
shoulder-wrist line while the palm stays put. :func:`solve_ik` finds one solution (damped
least squares, joint limits respected, random restarts); :func:`set_elbow_angle` moves a
solution along its self-motion manifold to a requested elbow angle psi (Newton on the square
system "palm pose error = 0, psi(q) = psi*", compiled: :mod:`kinegrasp_env.robot.self_motion`),
keeping the palm pose to ~1e-9 m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.robot.default_robot import (
    ARM_JOINTS,
    ELBOW_LINK,
    PALM_LINK,
    SHOULDER_LINK,
    WRIST_LINK,
)
from kinegrasp_env.robot.kinematics import Kinematics, pose_error
from kinegrasp_env.robot.self_motion import arm_chain, compiled_step, continue_elbow

#: The default robot's shoulder, elbow and wrist links, whose centres give its elbow angle.
ARM_ANGLE_LINKS = (SHOULDER_LINK, ELBOW_LINK, WRIST_LINK)
POSITION_TOL = 1e-7  # metres
ORIENTATION_TOL = 1e-7  # radians


@dataclass(frozen=True)
class IKResult:
    """IK solutions for n targets.

    Attributes:
        q: (n, dof) full configurations (hand part copied from the seed configuration).
        success: (n,) bool, palm reached within tolerance and joints within limits.
        position_error: (n,) metres.
        orientation_error: (n,) radians.
    """

    q: np.ndarray
    success: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray


class ArmIK:
    """IK and self-motion of the arm joints of a robot for a link (default: the palm).

    Args:
        kin: kinematics of the whole robot.
        link: the controlled frame.
        arm_joints: names of the joints IK may move.
    """

    def __init__(self, kin: Kinematics, link: str = PALM_LINK,
                 arm_joints: tuple[str, ...] = ARM_JOINTS) -> None:
        self.kin = kin
        self.link = link
        self.arm_index = kin.model.index(arm_joints)
        self.lower = kin.model.lower[self.arm_index]
        self.upper = kin.model.upper[self.arm_index]
        self._chain = arm_chain(kin, link, self.arm_index, ARM_ANGLE_LINKS)

    def _errors(self, q: np.ndarray, target: np.ndarray) -> np.ndarray:
        return pose_error(self.kin.pose(q, self.link), target)

    def solve(self, target: np.ndarray, q_seed: np.ndarray, *, rng: np.random.Generator | None
              = None, restarts: int = 8, iterations: int = 300, damping: float = 1e-2,
              margin: float = 1e-3) -> IKResult:
        """Damped-least-squares IK for palm targets.

        Args:
            target: (n, 4, 4) or (4, 4) palm poses in the world frame.
            q_seed: (n, dof) or (dof,) start configurations (hand values are kept).
            rng: for the random restarts of targets that fail from the seed.
            restarts: number of random restarts (uniform within joint limits).
            iterations: iterations per attempt.
            damping: DLS damping factor (scaled down as the error shrinks).
            margin: radians kept away from joint limits during the iteration.
        """
        target = np.asarray(target, dtype=float)
        if target.ndim == 2:
            target = target[None]
        n = target.shape[0]
        q = np.array(np.broadcast_to(np.atleast_2d(q_seed), (n, self.kin.model.dof)), float)
        rng = np.random.default_rng(0) if rng is None else rng
        best = q.copy()
        done = np.zeros(n, bool)
        for attempt in range(restarts + 1):
            todo = ~done
            if not np.any(todo):
                break
            start = best[todo].copy()
            if attempt > 0:
                start[:, self.arm_index] = rng.uniform(self.lower, self.upper,
                                                       size=(start.shape[0], self.arm_index.size))
            q_new = self._iterate(start, target[todo], iterations, damping, margin)
            err = self._errors(q_new, target[todo])
            ok = (np.linalg.norm(err[:, :3], axis=1) < POSITION_TOL) & (
                np.linalg.norm(err[:, 3:], axis=1) < ORIENTATION_TOL)
            idx = np.flatnonzero(todo)
            best_err = self._errors(best[idx], target[idx])
            better = ok | (np.linalg.norm(err, axis=1) < np.linalg.norm(best_err, axis=1))
            best[idx[better]] = q_new[better]
            done[idx[ok]] = True
        err = self._errors(best, target)
        pos = np.linalg.norm(err[:, :3], axis=1)
        rot = np.linalg.norm(err[:, 3:], axis=1)
        within = self.kin.model.within_limits(best)
        success = (pos < POSITION_TOL) & (rot < ORIENTATION_TOL) & within
        return IKResult(best, success, pos, rot)

    def _iterate(self, q: np.ndarray, target: np.ndarray, iterations: int, damping: float,
                 margin: float) -> np.ndarray:
        q = q.copy()
        eye = np.eye(6)
        lo, hi = self.lower + margin, self.upper - margin
        for _ in range(iterations):
            err = self._errors(q, target)
            norm = np.linalg.norm(err, axis=1)
            active = norm > 1e-10
            if not np.any(active):
                break
            jac = self.kin.jacobian(q[active], self.link)[:, :, self.arm_index]
            lam = (damping * np.minimum(norm[active], 1.0))[:, None, None] ** 2
            jjt = jac @ np.swapaxes(jac, 1, 2) + lam * eye
            step = np.swapaxes(jac, 1, 2) @ np.linalg.solve(jjt, err[active][..., None])
            step = step[..., 0]
            # limit the step size for robustness far from the solution
            scale = np.minimum(1.0, 0.5 / np.maximum(np.abs(step).max(axis=1), 1e-12))
            arm = q[np.ix_(active, self.arm_index)] + step * scale[:, None]
            q[np.ix_(active, self.arm_index)] = np.clip(arm, lo, hi)
        return q

    # ----------------------------------------------------------------- self-motion
    def elbow_angle(self, q: np.ndarray) -> np.ndarray:
        """Elbow angle psi (n,) of configurations (n, dof); see ``Kinematics.arm_angle``."""
        return self.kin.arm_angle(q, ARM_ANGLE_LINKS)

    def set_elbow_angle(self, q: np.ndarray, psi: np.ndarray | float, *, max_step: float = 0.3,
                        newton_iterations: int = 30) -> tuple[np.ndarray, np.ndarray]:
        """Move along the self-motion manifold to elbow angle ``psi``, palm pose fixed
        (:func:`~kinegrasp_env.robot.self_motion.continue_elbow`: its arguments and
        returns, (q_new (n, dof), ok (n,)); a move of up to 0.3 rad is one continuation
        step, three Newton solves with the continuity check)."""
        return continue_elbow(compiled_step(self._chain, self.kin, self.arm_index,
                                            newton_iterations),
                              self.kin, self.link, ARM_ANGLE_LINKS, q, psi, max_step=max_step)
