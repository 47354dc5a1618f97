"""End-effector noise study (paper section IV-A, Figs. 2-3): samplers and convergence curves.

The KUKA's end effector is the palm frame origin of the shipped arm+hand model; only the 7
arm joints are noisy.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.model import ARM_JOINTS, PALM_LINK, kuka_sdh
from kinegrasp_env.robot.planar import PlanarArm
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.stats import ConvergenceCurve, convergence_curve

#: Noise levels of the paper's Fig. 3 and Table I (radians).
PAPER_SIGMAS: tuple[float, ...] = (0.0033, 0.0133, 0.0233, 0.0333)
#: A comfortable KUKA configuration (elbow bent, palm pointing forward-down), radians.
DEFAULT_KUKA_Q0: tuple[float, ...] = (0.0, 0.6, 0.0, -1.2, 0.0, 0.8, 0.0)
#: Planar arm of Fig. 3 (two unit links) and its configuration.
DEFAULT_PLANAR_LINKS: tuple[float, ...] = (1.0, 1.0)
DEFAULT_PLANAR_Q0: tuple[float, ...] = (0.3, 1.2)
CONVERGENCE_SIZES: tuple[int, ...] = (10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000)


@lru_cache(maxsize=1)
def kuka_arm() -> tuple[Kinematics, np.ndarray]:
    """The default robot's kinematics and the indices of its arm joints in its q, shape (7,)."""
    model = kuka_sdh()
    return Kinematics(model), model.index(ARM_JOINTS)


def check_kuka_q0(q0: Sequence[float]) -> np.ndarray:
    """Validate a 7-vector of arm joint angles (finite, within limits) and return it."""
    q0 = np.asarray(q0, dtype=float)
    kin, arm = kuka_arm()
    if q0.shape != (arm.size,):
        raise ValueError(f"the KUKA arm needs {arm.size} joint angles, got {q0.size}")
    if not np.all(np.isfinite(q0)):
        raise ValueError(f"joint angles must be finite, got {q0.tolist()}")
    lo, hi = kin.model.lower[arm], kin.model.upper[arm]
    bad = np.flatnonzero((q0 < lo) | (q0 > hi))
    if bad.size:
        j = bad[0]
        raise ValueError(f"joint {j + 1} angle {q0[j]:g} outside its limits "
                         f"[{lo[j]:.4f}, {hi[j]:.4f}]")
    return q0


def kuka_end_effector(q_arm: np.ndarray) -> np.ndarray:
    """Palm positions (n, 3), metres, for arm configurations (n, 7)."""
    kin, arm = kuka_arm()
    q_arm = np.atleast_2d(np.asarray(q_arm, dtype=float))
    q = np.zeros((q_arm.shape[0], kin.model.dof))
    q[:, arm] = q_arm
    return kin.pose(q, PALM_LINK)[:, :3, 3]


def sample_kuka_end_effector(q0: Sequence[float], noise: JointNoise, n: int,
                             rng: int | np.random.Generator | None = None,
                             method: str = "mc", chunk: int = 50_000) -> np.ndarray:
    """Palm positions (n, 3) of q0 + eps for the KUKA arm (eps ~ ``noise`` on 7 joints)."""
    q0 = check_kuka_q0(q0)
    eps = noise.sample(n, q0.size, rng, method=method)
    return np.concatenate([kuka_end_effector(q0 + eps[i:i + chunk])
                           for i in range(0, max(n, 1), chunk)])[:n]


def planar_convergence(arm: PlanarArm, q0: Sequence[float], sigma: float, *,
                       kind: str = "gaussian", sizes: Sequence[int] = CONVERGENCE_SIZES,
                       trials: int = 10, truth_samples: int = 100_000,
                       seed: int | np.random.Generator = 0) -> ConvergenceCurve:
    """Convergence of the planar end-effector estimators (ground truth sampled, as the paper)."""
    noise = JointNoise(sigma, kind)
    q0 = np.asarray(q0, dtype=float)
    return convergence_curve(lambda n, rng: arm.sample(q0, noise, n, rng), sizes, trials=trials,
                             truth_samples=truth_samples, seed=seed)


def kuka_convergence(q0: Sequence[float], sigma: float, *, kind: str = "gaussian",
                     sizes: Sequence[int] = CONVERGENCE_SIZES, trials: int = 10,
                     truth_samples: int = 100_000,
                     seed: int | np.random.Generator = 0) -> ConvergenceCurve:
    """Convergence of the KUKA palm-position estimators."""
    noise = JointNoise(sigma, kind)
    return convergence_curve(lambda n, rng: sample_kuka_end_effector(q0, noise, n, rng), sizes,
                             trials=trials, truth_samples=truth_samples, seed=seed)
