"""Planar serial arms (any number of revolute links) and their exact end-effector moments.

The end effector of a planar arm with link lengths l_i and joint angles q is
p = sum_i l_i (cos theta_i, sin theta_i), theta_i = q_1 + ... + q_i. With independent
symmetric zero-mean joint noise, E[cos(c . eps)] = prod_j phi_j(c_j) and E[sin(c . eps)] = 0,
phi_j the (real) characteristic function of eps_j; this gives the mean and covariance of p
in closed form (:func:`exact_moments`), an independent check of the Monte Carlo estimators.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.sampling.noise import JointNoise


@dataclass(frozen=True)
class PlanarArm:
    """A planar serial arm.

    Attributes:
        lengths: (k,) link lengths, metres, all > 0.
    """

    lengths: tuple[float, ...]

    def __post_init__(self) -> None:
        lengths = np.asarray(self.lengths, dtype=float)
        if lengths.ndim != 1 or lengths.size < 1:
            raise ValueError(f"need at least one link length, got {self.lengths!r}")
        if not np.all(np.isfinite(lengths)) or np.any(lengths <= 0):
            raise ValueError(f"link lengths must be finite and > 0, got {self.lengths!r}")
        object.__setattr__(self, "lengths", tuple(float(v) for v in lengths))

    @property
    def dof(self) -> int:
        return len(self.lengths)

    def _check(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != self.dof:
            raise ValueError(f"{self.dof}-link arm needs {self.dof} joint angles, got "
                             f"{q.shape[-1]}")
        return q

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """Positions (..., k + 1, 2) of the base, every joint and the end effector."""
        q = self._check(q)
        theta = np.cumsum(q, axis=-1)
        lengths = np.asarray(self.lengths)[:, None]
        steps = np.stack([np.cos(theta), np.sin(theta)], axis=-1) * lengths
        zeros = np.zeros((*q.shape[:-1], 1, 2))
        return np.concatenate([zeros, np.cumsum(steps, axis=-2)], axis=-2)

    def forward(self, q: np.ndarray) -> np.ndarray:
        """End-effector positions (..., 2) for joint angles (..., k)."""
        q = self._check(q)
        theta = np.cumsum(q, axis=-1)
        lengths = np.asarray(self.lengths)
        return np.stack([np.cos(theta) @ lengths, np.sin(theta) @ lengths], axis=-1)

    def sample(self, q0: np.ndarray, noise: JointNoise, n: int,
               rng: int | np.random.Generator | None = None, method: str = "mc") -> np.ndarray:
        """End-effector positions (n, 2) of q0 + eps, eps ~ ``noise``."""
        q0 = self._check(q0)
        return self.forward(q0 + noise.sample(n, self.dof, rng, method=method))

    def exact_moments(self, q0: np.ndarray, noise: JointNoise) -> tuple[np.ndarray, np.ndarray]:
        """Exact mean (2,) and covariance (2, 2) of the end effector under ``noise``."""
        q0 = self._check(q0)
        k = self.dof
        sig = noise.sigma_vector(k)
        theta = np.cumsum(q0)
        lengths = np.asarray(self.lengths)
        coef = np.tril(np.ones((k, k)))  # coef[i, j] = 1 if joint j moves link i

        def ecos(c: np.ndarray) -> float:  # E[cos(c . eps)]
            return float(np.prod([noise.characteristic(c[j], sig[j]) for j in range(k)]))

        phi = np.array([ecos(coef[i]) for i in range(k)])
        mean = np.array([np.sum(lengths * np.cos(theta) * phi),
                         np.sum(lengths * np.sin(theta) * phi)])
        second = np.zeros((2, 2))
        for i in range(k):
            for j in range(k):
                w = lengths[i] * lengths[j] / 2.0
                minus, plus = ecos(coef[i] - coef[j]), ecos(coef[i] + coef[j])
                d, s = theta[i] - theta[j], theta[i] + theta[j]
                second[0, 0] += w * (np.cos(d) * minus + np.cos(s) * plus)
                second[1, 1] += w * (np.cos(d) * minus - np.cos(s) * plus)
                second[0, 1] += w * (np.sin(s) * plus - np.sin(d) * minus)
        second[1, 0] = second[0, 1]
        return mean, second - np.outer(mean, mean)
