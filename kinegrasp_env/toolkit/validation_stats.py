"""Statistics of ``kinegrasp validate``: confusion matrices of per-draw outcomes, Spearman's
rank correlation across grasps and its bootstrap interval.

All functions are pure numpy; the bootstrap takes a seed (same seed, same interval).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def confusion(predicted: np.ndarray, actual: np.ndarray) -> np.ndarray:
    """2 x 2 counts of two per-draw booleans (n,): rows ``predicted`` False/True, columns
    ``actual`` False/True, e.g. ``[[no FC & dropped, no FC & held], [FC & dropped, FC & held]]``.
    """
    predicted = np.asarray(predicted, bool)
    actual = np.asarray(actual, bool)
    if predicted.shape != actual.shape:
        raise ValueError(f"shapes differ: {predicted.shape} and {actual.shape}")
    return np.array([[np.sum(~predicted & ~actual), np.sum(~predicted & actual)],
                     [np.sum(predicted & ~actual), np.sum(predicted & actual)]], dtype=int)


def average_ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 1..n of x (n,), ties sharing the mean of their ranks."""
    x = np.asarray(x, float)
    order = np.argsort(x, kind="stable")
    sorted_x = x[order]
    # first index of each run of equal values, and the run lengths
    starts = np.flatnonzero(np.r_[True, sorted_x[1:] != sorted_x[:-1]])
    lengths = np.diff(np.r_[starts, x.size])
    mean_rank = starts + (lengths + 1) / 2.0
    ranks = np.empty(x.size)
    ranks[order] = np.repeat(mean_rank, lengths)
    return ranks


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rank correlation of x and y (n,) (Pearson's of the average ranks); NaN
    when either is constant or n < 2."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"need two 1-D arrays of one length, got {x.shape} and {y.shape}")
    if x.size < 2:
        return float("nan")
    rx = average_ranks(x) - (x.size + 1) / 2.0
    ry = average_ranks(y) - (y.size + 1) / 2.0
    denominator = np.sqrt(np.sum(rx * rx) * np.sum(ry * ry))
    if denominator == 0:
        return float("nan")
    return float(np.clip(np.sum(rx * ry) / denominator, -1.0, 1.0))


#: Fewest grasps a bootstrap interval of rho is given for: n grasps have C(2n - 1, n)
#: distinct resamples (10 for 3 grasps, 35 for 4, 126 for 5), too few below 5 for the
#: percentiles of a 95% interval, and many of them constant (rho undefined).
MIN_INTERVAL_GRASPS = 5


@dataclass
class Correlation:
    """Spearman's rho of two per-grasp columns with a percentile bootstrap interval.

    Attributes:
        rho: the estimate (NaN: a column is constant).
        ci: (low, high) percentile interval of rho over bootstrap resamples of the grasps
            (NaN for fewer than :data:`MIN_INTERVAL_GRASPS` grasps).
        confidence: the interval's level; resamples: how many were drawn; undefined: how many
            of them gave a constant column (left out of the interval).
        n: number of grasps.
    """

    rho: float
    ci: tuple[float, float]
    confidence: float
    resamples: int
    undefined: int
    n: int

    def to_json(self) -> dict:
        return {"rho": none_if_nan(self.rho), "ci": [none_if_nan(v) for v in self.ci],
                "confidence": self.confidence, "resamples": self.resamples,
                "undefined": self.undefined, "n": self.n}


def none_if_nan(value: float) -> float | None:
    return None if not np.isfinite(value) else float(value)


def bootstrap_spearman(x: np.ndarray, y: np.ndarray, seed: int | np.random.Generator = 0,
                       resamples: int = 2000, confidence: float = 0.95) -> Correlation:
    """Spearman's rho of the pairs (x[i], y[i]) (n,) and a percentile bootstrap interval
    from ``resamples`` resamples of the n pairs with replacement (seeded); no interval (NaN,
    no resample drawn) for fewer than :data:`MIN_INTERVAL_GRASPS` pairs."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    rho = spearman(x, y)
    if x.size < MIN_INTERVAL_GRASPS:  # no resample drawn
        return Correlation(rho, (float("nan"), float("nan")), confidence, 0, 0, int(x.size))
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, x.size, size=(resamples, x.size)) if x.size else np.zeros((0, 0))
    values = np.array([spearman(x[p], y[p]) for p in picks.astype(int)])
    finite = values[np.isfinite(values)]
    if finite.size:
        tail = (1.0 - confidence) / 2.0
        lo, hi = (float(v) for v in np.quantile(finite, [tail, 1.0 - tail]))
    else:
        lo = hi = float("nan")
    return Correlation(rho, (lo, hi), confidence, resamples, int(values.size - finite.size),
                       int(x.size))
