"""End-effector noise study (paper section IV-A, Figs. 2-3): samplers, first-order moments
and convergence curves.

A robot's end effector is the origin of its palm link; only the arm joints are noisy (the
hand stays at its pre-shape, which does not move the palm). :class:`ArmEndEffector` does it
for any catalog robot (a :class:`~kinegrasp_env.robot.description.RobotDescription`), starting
from its description's ``home`` configuration.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.planar import PlanarArm
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.stats import ConvergenceCurve, convergence_curve

#: Noise levels of the paper's Fig. 3 and Table I (radians).
PAPER_SIGMAS: tuple[float, ...] = (0.0033, 0.0133, 0.0233, 0.0333)
#: Planar arm of Fig. 3 (two unit links) and its configuration.
DEFAULT_PLANAR_LINKS: tuple[float, ...] = (1.0, 1.0)
DEFAULT_PLANAR_Q0: tuple[float, ...] = (0.3, 1.2)
CONVERGENCE_SIZES: tuple[int, ...] = (10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000)


class ArmEndEffector:
    """The palm position of a robot's arm under joint noise.

    Args:
        kin: the robot's kinematics.
        arm: (a,) indices of the arm joints in its actuated vector q (dof,).
        palm: the link whose origin is the end effector.
        rest: (dof,) configuration the arm joints are written into (the hand's pre-shape).
        label: how errors name the arm (e.g. ``the KUKA arm``).
    """

    def __init__(self, kin: Kinematics, arm: np.ndarray, palm: str, rest: np.ndarray,
                 label: str) -> None:
        self.kin, self.arm, self.palm, self.label = kin, np.asarray(arm, dtype=int), palm, label
        self.rest = np.asarray(rest, dtype=float)

    @classmethod
    def of(cls, description: RobotDescription, kin: Kinematics | None = None
           ) -> ArmEndEffector:
        """The end effector of a description robot (arm joints first in its q, the hand at
        its ``open`` pre-shape)."""
        kin = Kinematics(description.model) if kin is None else kin
        return cls(kin, np.arange(description.arm_dof), description.palm_link,
                   description.open_configuration(), f"the arm of robot {description.name!r}")

    @property
    def lower(self) -> np.ndarray:
        """(a,) lower joint limits of the arm, radians."""
        return self.kin.model.lower[self.arm]

    @property
    def upper(self) -> np.ndarray:
        """(a,) upper joint limits of the arm, radians."""
        return self.kin.model.upper[self.arm]

    def middle(self) -> np.ndarray:
        """(a,) the middle of each arm joint's range, radians."""
        return 0.5 * (self.lower + self.upper)

    def check_q0(self, q0: Sequence[float]) -> np.ndarray:
        """Validate arm joint angles (a,) (finite, within limits) and return them."""
        q0 = np.asarray(q0, dtype=float)
        if q0.shape != (self.arm.size,):
            raise ValueError(f"{self.label} needs {self.arm.size} joint angles, got {q0.size}")
        if not np.all(np.isfinite(q0)):
            raise ValueError(f"joint angles must be finite, got {q0.tolist()}")
        lo, hi = self.lower, self.upper
        bad = np.flatnonzero((q0 < lo) | (q0 > hi))
        if bad.size:
            j = bad[0]
            raise ValueError(f"joint {j + 1} angle {q0[j]:g} outside its limits "
                             f"[{lo[j]:.4f}, {hi[j]:.4f}]")
        return q0

    def configurations(self, q_arm: np.ndarray) -> np.ndarray:
        """(n, dof) actuated vectors of arm configurations (n, a) (the rest elsewhere)."""
        q_arm = np.atleast_2d(np.asarray(q_arm, dtype=float))
        q = np.repeat(self.rest[None], q_arm.shape[0], axis=0)
        q[:, self.arm] = q_arm
        return q

    def positions(self, q_arm: np.ndarray) -> np.ndarray:
        """Palm positions (n, 3), metres, for arm configurations (n, a)."""
        return self.kin.pose(self.configurations(q_arm), self.palm)[:, :3, 3]

    def sample(self, q0: Sequence[float], noise: JointNoise, n: int,
               rng: int | np.random.Generator | None = None, method: str = "mc",
               chunk: int = 50_000) -> np.ndarray:
        """Palm positions (n, 3) of q0 + eps (eps ~ ``noise`` on the arm joints, (n, a))."""
        q0 = self.check_q0(q0)
        eps = noise.sample(n, q0.size, rng, method=method)
        return np.concatenate([self.positions(q0 + eps[i:i + chunk])
                               for i in range(0, max(n, 1), chunk)])[:n]

    def first_order(self, q0: Sequence[float], noise: JointNoise
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Linearized moments: mean (3,) = p(q0), cov (3, 3) = J Sigma J^T, with J (3, a) the
        palm position's Jacobian in the arm joints and Sigma = diag(sigma^2) (every
        distribution has standard deviation sigma)."""
        q0 = self.check_q0(q0)
        q = self.configurations(q0)
        jac = self.kin.jacobian(q, self.palm)[0, :3][:, self.arm]
        sigma = noise.sigma_vector(self.arm.size)
        return self.positions(q0)[0], (jac * sigma**2) @ jac.T


def planar_convergence(arm: PlanarArm, q0: Sequence[float], sigma: float, *,
                       kind: str = "gaussian", sizes: Sequence[int] = CONVERGENCE_SIZES,
                       trials: int = 10, truth_samples: int = 100_000,
                       seed: int | np.random.Generator = 0) -> ConvergenceCurve:
    """Convergence of the planar end-effector estimators (ground truth sampled, as the paper)."""
    noise = JointNoise(sigma, kind)
    q0 = np.asarray(q0, dtype=float)
    return convergence_curve(lambda n, rng: arm.sample(q0, noise, n, rng), sizes, trials=trials,
                             truth_samples=truth_samples, seed=seed)


def arm_convergence(effector: ArmEndEffector, q0: Sequence[float], sigma: float, *,
                    kind: str = "gaussian", sizes: Sequence[int] = CONVERGENCE_SIZES,
                    trials: int = 10, truth_samples: int = 100_000,
                    seed: int | np.random.Generator = 0) -> ConvergenceCurve:
    """Convergence of a robot arm's palm-position estimators at arm configuration q0."""
    noise = JointNoise(sigma, kind)
    q0 = effector.check_q0(q0)
    return convergence_curve(lambda n, rng: effector.sample(q0, noise, n, rng), sizes,
                             trials=trials, truth_samples=truth_samples, seed=seed)
