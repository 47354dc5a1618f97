"""The self-motion of any 7-joint arm of a robot description: the palm held, the elbow moved.

A 7-joint arm is redundant for the 6-D palm pose: its configurations with one palm pose form
a curve (away from singularities). The curve is parametrised by the arm angle psi of the
description's ``arm_angle_links`` (shoulder, elbow, wrist:
:func:`kinegrasp_env.robot.kinematics.elbow_angle`), and :meth:`ArmSelfMotion.set_elbow_angle`
moves along it by continuation: each step solves the square 7x7 Newton system

    [J_palm (6x7); d psi / dq (1x7)] dq = [palm pose error (6); psi* - psi(q) (1)]

with the palm's geometric Jacobian (:meth:`~kinegrasp_env.robot.kinematics.Kinematics.
jacobian`, arm columns) and psi's gradient by central differences; the first 6 rows keep
dq in the Jacobian's null space to first order, the last one moves the elbow. Nothing in it
names a joint or link. The continuation, with its continuity check, is the one
:mod:`kinegrasp_env.robot.ik` runs for the default robot's fixed chain
(:func:`~kinegrasp_env.robot.self_motion.continue_elbow`: on the default robot's description
the two give the same configurations); its Newton runs compiled where the chain base -> palm
is driven by the arm joints directly (every catalog robot's:
:func:`~kinegrasp_env.robot.self_motion.compiled_step`), else in the batched numpy
kinematics, a step converged where the residual is below
:data:`~kinegrasp_env.robot.self_motion.CONVERGED_TOL` (the compiled step's rule). A move of
0.3 rad is one continuation step (three Newton solves: ``python
benchmarks/bench_self_motion.py``; within env steps: ``python benchmarks/bench_env.py``).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics, elbow_angle, pose_error
from kinegrasp_env.robot.self_motion import (
    CONVERGED_TOL,
    ArmChain,
    arm_chain,
    compiled_step,
    continue_elbow,
)

#: Central-difference step of psi's gradient (radians).
GRADIENT_STEP = 1e-6
#: Largest change of one joint per Newton iteration (radians).
MAX_JOINT_STEP = 0.2


class ArmSelfMotion:
    """Elbow angle and self-motion of a description robot's 7 arm joints.

    Args:
        description: the robot (7 arm joints and ``arm_angle_links``).
        kin: its kinematics (default: built from ``description.model``).

    Raises:
        ValueError: an arm of another number of joints, or no arm angle links.
    """

    def __init__(self, description: RobotDescription, kin: Kinematics | None = None) -> None:
        if not description.has_self_motion:
            raise ValueError(f"robot {description.name!r} has {description.arm_dof} arm joints;"
                             " the self-motion needs 7 and arm_angle_links")
        self.description = description
        self.kin = Kinematics(description.model) if kin is None else kin
        self.arm = np.arange(description.arm_dof)
        self.palm = description.palm_link
        self.angle_links = tuple(description.arm_angle_links)
        self._chain = compiled_chain(self.kin, self.palm, self.arm, self.angle_links)

    def elbow_angle(self, q: np.ndarray) -> np.ndarray:
        """Arm angle psi (n,) radians of configurations q (n, dof)."""
        poses = self.kin.forward(np.atleast_2d(q), self.angle_links)
        s, e, w = (poses[link][:, :3, 3] for link in self.angle_links)
        return elbow_angle(s, e, w)

    def _gradient(self, q: np.ndarray) -> np.ndarray:
        """d psi / d q_arm (n, 7) by central differences (one batched FK of 14 n rows)."""
        n, a = q.shape[0], self.arm.size
        shifted = np.repeat(q[:, None], 2 * a, axis=1)
        for j in range(a):
            shifted[:, 2 * j, j] += GRADIENT_STEP
            shifted[:, 2 * j + 1, j] -= GRADIENT_STEP
        psi = self.elbow_angle(shifted.reshape(n * 2 * a, -1)).reshape(n, a, 2)
        diff = np.angle(np.exp(1j * (psi[..., 0] - psi[..., 1])))
        return diff / (2.0 * GRADIENT_STEP)

    def _newton(self, q: np.ndarray, target: np.ndarray, goal: np.ndarray,
                iterations: int) -> tuple[np.ndarray, np.ndarray]:
        """Newton on the square system from q (n, dof) in numpy: (q, residual norms (n,))."""
        q = q.copy()
        for _ in range(iterations):
            err = pose_error(self.kin.pose(q, self.palm), target)
            d_psi = np.angle(np.exp(1j * (goal - self.elbow_angle(q))))
            residual = np.concatenate([err, d_psi[:, None]], axis=1)
            norm = np.linalg.norm(residual, axis=1)
            if np.all(norm < CONVERGED_TOL):
                return q, norm
            system = np.concatenate([self.kin.jacobian(q, self.palm)[:, :, self.arm],
                                     self._gradient(q)[:, None]], axis=1)
            try:
                step = np.linalg.solve(system, residual[..., None])[..., 0]
            except np.linalg.LinAlgError:
                return q, np.full(q.shape[0], np.inf)  # a singular system: not reached
            step *= np.minimum(1.0, MAX_JOINT_STEP / np.maximum(np.abs(step).max(axis=1),
                                                                1e-300))[:, None]
            q[:, self.arm] += step
        err = pose_error(self.kin.pose(q, self.palm), target)
        d_psi = np.angle(np.exp(1j * (goal - self.elbow_angle(q))))
        return q, np.linalg.norm(np.concatenate([err, d_psi[:, None]], axis=1), axis=1)

    def set_elbow_angle(self, q: np.ndarray, psi: float, *, max_step: float = 0.3,
                        newton_iterations: int = 30) -> tuple[np.ndarray, bool]:
        """Move configuration q (dof,) along its self-motion to elbow angle ``psi`` (radians).

        Continuation steps of at most ``max_step`` radians of psi, each solved by Newton;
        the palm pose of q is kept (module docstring: compiled where the chain allows).

        Returns:
            (q_new (dof,), reached): reached is False where the path left the joint limits,
            met a singularity or did not converge; q_new is then the last valid point.
        """
        if self._chain is not None:
            newton = compiled_step(self._chain, self.kin, self.arm, newton_iterations)
        else:
            def newton(rows, targets, goals):
                trial, norm = self._newton(rows, targets, goals, newton_iterations)
                return trial, (norm < CONVERGED_TOL) & self.kin.model.within_limits(trial)
        moved, ok = continue_elbow(newton, self.kin, self.palm, self.angle_links, q, psi,
                                   max_step=max_step)
        return moved[0], bool(ok[0])


def compiled_chain(kin: Kinematics, palm: str, arm: np.ndarray,
                   angle_links: tuple[str, str, str]) -> ArmChain | None:
    """The chain to ``palm`` for the compiled Newton, or None where a joint on it is not an
    arm joint driven directly (the numpy Newton then runs)."""
    try:
        return arm_chain(kin, palm, arm, angle_links)
    except ValueError:
        return None

