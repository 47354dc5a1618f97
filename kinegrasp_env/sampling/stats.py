"""Estimators, confidence intervals, streaming accumulators and convergence curves.

Definitions (pinned in docs/conventions.md), for draws X_1..X_n:

* mean = (1/n) sum X_i;
* sample std and covariance with the (n - 1) denominator;
* skewness M3 = (1/n) sum ((X_i - mean) / std)^3, std the sample std;
* P(FC) = fraction of successes, with a Wilson score interval (95% by default).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

#: normal_quantile(0.95), scipy.special.ndtri(0.975) as a double (the test suite checks it
#: against scipy), so that the common intervals need no scipy import.
Z95 = 1.959963984540054


@functools.lru_cache(maxsize=32)
def normal_quantile(confidence: float) -> float:
    """Two-sided standard normal quantile z with P(|Z| <= z) = confidence (cached):
    scipy's ``ndtri(0.5 + confidence / 2)``."""
    if confidence == 0.95:
        return Z95
    from scipy import special

    return float(special.ndtri(0.5 + confidence / 2.0))


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion; (0, 1) when n = 0.

    The bounds are clipped so that ``lo <= successes / n <= hi`` always holds (in floating
    point the closed form can land one ulp on the wrong side of the estimate, e.g.
    10/10 gives an upper bound of 0.9999999999999999) and so that ``0 <= lo <= hi <= 1``.
    """
    if n < 0 or successes < 0 or successes > n:
        raise ValueError(f"need 0 <= successes <= n, got successes={successes}, n={n}")
    if n == 0:
        return 0.0, 1.0
    z = normal_quantile(confidence)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return min(max(0.0, centre - half), p), max(min(1.0, centre + half), p)


def paired_interval(d: np.ndarray, confidence: float = 0.95) -> tuple[float, float, float]:
    """(mean, lo, hi) of paired differences d (n,), Student-t interval."""
    n = d.size
    mean = float(d.mean())
    if n < 2:
        return mean, -math.inf, math.inf
    from scipy import stats

    half = float(stats.t.ppf(0.5 + confidence / 2, n - 1) * d.std(ddof=1) / math.sqrt(n))
    return mean, mean - half, mean + half


def skewness(x: np.ndarray, axis: int = 0) -> np.ndarray:
    """M3 = (1/n) sum(((x - mean) / s)^3) along ``axis``, s the sample std (n - 1).

    Returns nan where n < 2 or s = 0.
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[axis]
    if n < 2:
        return np.full(np.delete(x.shape, axis), np.nan) if x.ndim > 1 else np.float64(np.nan)
    mean = x.mean(axis=axis, keepdims=True)
    std = x.std(axis=axis, ddof=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (x - mean) / std
        out = np.mean(z**3, axis=axis)
    return np.where(np.squeeze(std, axis=axis) > 0, out, np.nan)


@dataclass(frozen=True)
class Moments:
    """Sample moments of n vectors of dimension d.

    Attributes:
        n: number of samples.
        mean: (d,).
        cov: (d, d) sample covariance (n - 1).
        skew: (d,) per-coordinate skewness (docs/conventions.md).
    """

    n: int
    mean: np.ndarray
    cov: np.ndarray
    skew: np.ndarray

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov))


def moments(samples: np.ndarray) -> Moments:
    """Moments of samples (n, d) (or (n,) treated as d = 1)."""
    x = np.asarray(samples, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    n = x.shape[0]
    cov = np.cov(x, rowvar=False, ddof=1).reshape(x.shape[1], x.shape[1]) if n > 1 else \
        np.full((x.shape[1], x.shape[1]), np.nan)
    return Moments(n, x.mean(axis=0) if n else np.full(x.shape[1], np.nan), cov, skewness(x))


class StreamingMoments:
    """Mergeable accumulator of count, mean, co-moment matrix and third central moments.

    Feed batches with :meth:`update`, combine partial results from chunks or workers with
    :meth:`merge` (exact pairwise formulas of Chan et al. / Pebay), read :meth:`result`.

    Args:
        dim: dimension d of the vectors.
    """

    def __init__(self, dim: int = 1) -> None:
        self.dim = dim
        self.n = 0
        self.mean = np.zeros(dim)
        self.m2 = np.zeros((dim, dim))
        self.m3 = np.zeros(dim)

    @classmethod
    def from_state(cls, n: int, mean, m2, m3) -> StreamingMoments:
        """Accumulator with a saved state: count, mean (d,), m2 (d, d), m3 (d,)."""
        mean = np.atleast_1d(np.asarray(mean, dtype=float))
        out = cls(mean.size)
        out.n, out.mean = int(n), mean
        out.m2 = np.asarray(m2, dtype=float).reshape(mean.size, mean.size)
        out.m3 = np.atleast_1d(np.asarray(m3, dtype=float))
        return out

    def update(self, batch: np.ndarray) -> StreamingMoments:
        """Add a batch (k, d) (or (k,) for d = 1); returns self."""
        x = np.asarray(batch, dtype=float).reshape(-1, self.dim)
        if x.shape[0] == 0:
            return self
        other = StreamingMoments(self.dim)
        other.n = x.shape[0]
        other.mean = x.mean(axis=0)
        centred = x - other.mean
        other.m2 = centred.T @ centred
        other.m3 = np.sum(centred**3, axis=0)
        return self.merge(other)

    def merge(self, other: StreamingMoments) -> StreamingMoments:
        """Fold ``other`` into self; returns self."""
        if other.dim != self.dim:
            raise ValueError(f"cannot merge dimension {other.dim} into {self.dim}")
        if other.n == 0:
            return self
        if self.n == 0:
            self.n, self.mean = other.n, other.mean.copy()
            self.m2, self.m3 = other.m2.copy(), other.m3.copy()
            return self
        na, nb = self.n, other.n
        n = na + nb
        delta = other.mean - self.mean
        var_a, var_b = np.diag(self.m2), np.diag(other.m2)
        self.m3 = (self.m3 + other.m3 + delta**3 * na * nb * (na - nb) / n**2
                   + 3.0 * delta * (na * var_b - nb * var_a) / n)
        self.m2 = self.m2 + other.m2 + np.outer(delta, delta) * na * nb / n
        self.mean = self.mean + delta * nb / n
        self.n = n
        return self

    def result(self) -> Moments:
        """Current :class:`Moments` (nan entries where n is too small)."""
        if self.n < 2:
            nan_cov = np.full((self.dim, self.dim), np.nan)
            return Moments(self.n, self.mean.copy() if self.n else np.full(self.dim, np.nan),
                           nan_cov, np.full(self.dim, np.nan))
        cov = self.m2 / (self.n - 1)
        std = np.sqrt(np.diag(cov))
        with np.errstate(invalid="ignore", divide="ignore"):
            skew = np.where(std > 0, (self.m3 / self.n) / std**3, np.nan)
        return Moments(self.n, self.mean.copy(), cov, skew)


@dataclass(frozen=True)
class ConvergenceCurve:
    """Estimator errors against sample count, averaged over trials.

    Attributes:
        sizes: (m,) sample counts.
        mean_error: (m,) average L2 norm of (sample mean - true mean).
        cov_error: (m,) average Frobenius norm of (sample cov - true cov).
        skew_error: (m,) average L2 norm of (sample skewness - true skewness).
        truth: the ground-truth moments.
        trials: number of trials averaged.
    """

    sizes: np.ndarray
    mean_error: np.ndarray
    cov_error: np.ndarray
    skew_error: np.ndarray
    truth: Moments
    trials: int


def convergence_curve(draw: Callable[[int, np.random.Generator], np.ndarray],
                      sizes: Sequence[int], *, trials: int = 10, truth_samples: int = 100_000,
                      seed: int | np.random.Generator | None = 0,
                      truth: Moments | None = None) -> ConvergenceCurve:
    """Errors of the mean, covariance and skewness estimators vs sample count (paper Fig. 3).

    Args:
        draw: ``draw(n, rng) -> (n, d)`` samples of the quantity (e.g. end-effector position).
        sizes: sample counts to evaluate (each >= 2).
        trials: independent repetitions averaged per size.
        truth_samples: draws for the ground truth (ignored if ``truth`` is given).
        seed: seed or Generator; the ground truth and every trial use child streams of it.
        truth: ground-truth moments, if known in closed form.
    """
    sizes = np.asarray(sizes, dtype=int)
    if np.any(sizes < 2):
        raise ValueError(f"every sample size must be >= 2, got {sizes.tolist()}")
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    base = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    streams = base.spawn(trials + 1)
    if truth is None:
        truth = moments(draw(truth_samples, streams[0]))
    errors = np.zeros((3, sizes.size))
    for rng in streams[1:]:
        big = np.asarray(draw(int(sizes.max()), rng), dtype=float)
        big = big.reshape(big.shape[0], -1)
        for j, n in enumerate(sizes):
            est = moments(big[:n])
            errors[0, j] += np.linalg.norm(est.mean - truth.mean)
            errors[1, j] += np.linalg.norm(est.cov - truth.cov)
            errors[2, j] += np.linalg.norm(est.skew - truth.skew)
    errors /= trials
    return ConvergenceCurve(sizes, errors[0], errors[1], errors[2], truth, trials)
