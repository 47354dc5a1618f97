"""Sobol sensitivity indices of a scalar output, with bootstrap intervals.

Factors are independent blocks of random inputs (a block may hold many variables: its index
is the group index of them all). With two independent sample matrices A and B of N rows and,
for each factor i, A_B^i = A with factor i's block taken from B, the outputs y_A, y_B,
y_AB^i (N,) give (Saltelli et al. 2010, "Variance based sensitivity analysis of model
output", estimators (b) and (f) of their Table 2):

* first order  S_i  = mean(y_B (y_AB^i - y_A)) / V   (Saltelli 2010);
* total        ST_i = mean((y_A - y_AB^i)^2) / (2 V) (Jansen 1999);

V = the sample variance (n - 1) of y_A and y_B together. S_i is the share of V that factor
i explains alone, ST_i the share it takes part in (alone or through interactions); for an
additive output they are equal. Intervals: percentile bootstrap over the N rows (the same
resampled rows for y_A, y_B and every y_AB^i). V = 0 (a constant output) gives NaN.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.sampling.noise import SeedLike, as_generator

#: Bootstrap resamples processed at once (bounds the memory to this x N x factors).
BOOTSTRAP_BATCH = 64


@dataclass(frozen=True)
class SobolIndex:
    """First-order and total index of one factor, with their bootstrap intervals."""

    first: float
    first_ci: tuple[float, float]
    total: float
    total_ci: tuple[float, float]


def estimates(y_a: np.ndarray, y_b: np.ndarray, y_ab: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """(first (k, ...), total (k, ...)) from y_A, y_B (..., N) and y_AB (k, ..., N)."""
    variance = np.var(np.concatenate([y_a, y_b], axis=-1), axis=-1, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        first = np.mean(y_b * (y_ab - y_a), axis=-1) / variance
        total = 0.5 * np.mean((y_a - y_ab) ** 2, axis=-1) / variance
    bad = variance == 0
    return np.where(bad, np.nan, first), np.where(bad, np.nan, total)


def sobol_indices(y_a, y_b, y_ab: Mapping[str, np.ndarray], *, bootstrap: int = 1000,
                  confidence: float = 0.95, seed: SeedLike = 0) -> dict[str, SobolIndex]:
    """First-order and total Sobol index of every factor (module docstring).

    Args:
        y_a, y_b: (N,) outputs at the rows of A and of B.
        y_ab: factor name -> (N,) outputs at A with that factor's block from B.
        bootstrap: resamples for the intervals (0: intervals are (nan, nan)).
        confidence: of the percentile intervals.
        seed: of the resampling.
    """
    y_a, y_b = np.asarray(y_a, dtype=float), np.asarray(y_b, dtype=float)
    names = list(y_ab)
    stack = np.array([np.asarray(y_ab[k], dtype=float) for k in names])
    n = y_a.size
    if y_b.shape != (n,) or stack.shape != (len(names), n) or n < 2:
        raise ValueError(f"y_A, y_B and every y_AB must have the same length N >= 2, got "
                         f"{y_a.shape}, {y_b.shape}, {stack.shape}")
    first, total = estimates(y_a, y_b, stack)
    lo_q, hi_q = 50 * (1 - confidence), 50 * (1 + confidence)
    boot_first, boot_total = np.full((len(names), 0), np.nan), np.full((len(names), 0), np.nan)
    if bootstrap > 0:
        gen = as_generator(seed)
        parts_f, parts_t = [], []
        for start in range(0, bootstrap, BOOTSTRAP_BATCH):
            rows = gen.integers(0, n, size=(min(BOOTSTRAP_BATCH, bootstrap - start), n))
            f, t = estimates(y_a[rows], y_b[rows], stack[:, rows])
            parts_f.append(f)
            parts_t.append(t)
        boot_first, boot_total = np.concatenate(parts_f, 1), np.concatenate(parts_t, 1)
    out = {}
    for i, name in enumerate(names):
        out[name] = SobolIndex(float(first[i]), _interval(boot_first[i], lo_q, hi_q),
                               float(total[i]), _interval(boot_total[i], lo_q, hi_q))
    return out


def _interval(samples: np.ndarray, lo_q: float, hi_q: float) -> tuple[float, float]:
    finite = samples[np.isfinite(samples)]
    if finite.size == 0:
        return (np.nan, np.nan)
    return float(np.percentile(finite, lo_q)), float(np.percentile(finite, hi_q))
