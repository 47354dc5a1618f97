"""Self-normalised importance weights for Gaussian targets.

One batch of draws x_1..x_n (n, d) from a proposal g answers the expectation of any f under
any target density p whose support g covers:

    E_p[f] ~ sum_i w_i f(x_i) / sum_i w_i,      w_i = p(x_i) / g(x_i),

with the effective sample size ESS = (sum w)^2 / sum w^2 (how many direct draws the batch
is worth for that target) and the delta-method standard error
sqrt(sum w_i^2 (f_i - E)^2) / sum w_i (Owen, *Monte Carlo theory, methods and examples*,
ch. 9). The proposal here is a *stratified Gaussian mixture*: n_k = n / K draws from each of K
zero-mean components N(0, S_k), weighted with the mixture's density (the balance heuristic),
so that a target equal to one component has weights below about K / (1 - the defensive
share), and a *defensive* component
(the components' mean covariance, widened) keeps the weights bounded for targets between
them. A target may have a mean of its own, N(m, S) (a mean small against S's spread keeps
the weights as tame). The score d log p / dt of a target N(m(t), S(t)) along a parameter t
gives the estimate's derivative, dE/dt ~ sum_i w_i (f_i - E) s_i / sum_i w_i.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.sampling.stats import wilson_interval

#: The defensive component's covariance: the components' mean, times this squared scale.
DEFENSIVE_SCALE = 1.5
#: The share of the draws given to the defensive component.
DEFENSIVE_SHARE = 0.1


def _checked_covariances(covariances: np.ndarray) -> np.ndarray:
    cov = np.asarray(covariances, dtype=float)
    if cov.ndim == 2:
        cov = cov[None]
    if cov.ndim != 3 or cov.shape[1] != cov.shape[2] or not len(cov):
        raise ValueError(f"covariances must have shape (K, d, d), got {np.shape(covariances)}")
    if not np.all(np.isfinite(cov)):
        raise ValueError("covariances have NaN or infinite entries")
    return 0.5 * (cov + np.swapaxes(cov, 1, 2))


def gaussian_logpdf(x: np.ndarray, covariance: np.ndarray, mean: np.ndarray | None = None
                    ) -> np.ndarray:
    """(n,) log density of N(mean (d,) (default 0), covariance (d, d)) at points x (n, d).

    Raises:
        ValueError: the covariance is not positive definite.
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    if mean is not None:
        x = x - np.asarray(mean, dtype=float)
    cov = _checked_covariances(covariance)[0]
    try:
        chol = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ValueError("the covariance is not positive definite (a joint noise that "
                         "leaves a direction of the palm's pose without error)") from None
    z = np.linalg.solve(chol, x.T)
    d = cov.shape[0]
    return (-0.5 * np.sum(z * z, axis=0) - np.sum(np.log(np.diag(chol)))
            - 0.5 * d * math.log(2.0 * math.pi))


def gaussian_score(x: np.ndarray, covariance: np.ndarray, derivative: np.ndarray,
                   mean: np.ndarray | None = None, mean_derivative: np.ndarray | None = None
                   ) -> np.ndarray:
    """(n,) d/dt log N(x; m(t), S(t)) at points x (n, d), given S (d, d), dS/dt (d, d) and,
    where the mean moves, m (d,) and dm/dt (d,): with r = x - m,
    -tr(S^-1 S') / 2 + r^T S^-1 S' S^-1 r / 2 + r^T S^-1 m'."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    if mean is not None:
        x = x - np.asarray(mean, dtype=float)
    inv = np.linalg.inv(_checked_covariances(covariance)[0])
    a = inv @ np.asarray(derivative, dtype=float) @ inv
    out = -0.5 * np.trace(inv @ derivative) + 0.5 * np.einsum("ni,ij,nj->n", x, a, x)
    if mean_derivative is not None:
        out = out + x @ (inv @ np.asarray(mean_derivative, dtype=float))
    return out


def least_batch(targets: int, defensive_share: float = DEFENSIVE_SHARE) -> int:
    """The smallest batch of closings whose mixture covers ``targets`` components and a
    defensive one (its ``defensive_share`` of the batch, at least one closing): one closing
    per target beside the defensive component's."""
    need = targets + 1
    while need - _defensive_count(need, defensive_share) < targets:
        need += 1
    return need


def _defensive_count(n: int, share: float) -> int:
    """The defensive component's closings in a batch of n."""
    return max(1, round(share * n))


class BatchTooSmall(ValueError):
    """A batch of closings too small for its mixture: fewer draws than targets plus the
    defensive component's share.

    Attributes:
        need: the smallest batch that covers them.
    """

    def __init__(self, n: int, targets: int, need: int, share: float = DEFENSIVE_SHARE) -> None:
        super().__init__(f"a batch of {n} closings cannot cover {targets} targets and a "
                         f"defensive component: it needs at least {need} (a closing per target "
                         f"beside the defensive component's {share:.0%} share)")
        self.need = need


@dataclass(frozen=True)
class MixtureProposal:
    """A stratified mixture of zero-mean Gaussians and a defensive one.

    Attributes:
        covariances: (K, d, d) the components (the targets of interest).
        defensive: (d, d) the defensive component's covariance.
        counts: (K + 1,) draws per component (the last: defensive) for a batch of n.
    """

    covariances: np.ndarray
    defensive: np.ndarray
    counts: np.ndarray

    @classmethod
    def covering(cls, covariances: np.ndarray, n: int, *,
                 defensive_scale: float = DEFENSIVE_SCALE,
                 defensive_share: float = DEFENSIVE_SHARE) -> MixtureProposal:
        """The proposal of n draws over components (K, d, d) (a (d, d) is one component)."""
        cov = _checked_covariances(covariances)
        if not 0.0 < defensive_share < 1.0 or defensive_scale < 1.0:
            raise ValueError("the defensive share must lie in (0, 1) and its scale be >= 1, "
                             f"got {defensive_share:g} and {defensive_scale:g}")
        n_def = _defensive_count(n, defensive_share)
        if n - n_def < len(cov):
            raise BatchTooSmall(n, len(cov), least_batch(len(cov), defensive_share),
                                defensive_share)
        for c in cov:
            try:
                np.linalg.cholesky(c)
            except np.linalg.LinAlgError:
                raise ValueError("a target covariance is not positive definite (a noise that "
                                 "leaves a direction of the palm's pose without error)"
                                 ) from None
        base, extra = divmod(n - n_def, len(cov))
        counts = np.array([base + (k < extra) for k in range(len(cov))] + [n_def])
        return cls(cov, defensive_scale**2 * cov.mean(axis=0), counts)

    @property
    def shares(self) -> np.ndarray:
        """(K + 1,) the mixture's weights: each component's share of the draws."""
        return self.counts / self.counts.sum()

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """(n, d) draws, component by component (stratified)."""
        parts = []
        for cov, count in zip([*self.covariances, self.defensive], self.counts, strict=True):
            chol = np.linalg.cholesky(cov)
            parts.append(rng.standard_normal((count, cov.shape[0])) @ chol.T)
        return np.vstack(parts)

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        """(n,) log density of the mixture at x (n, d)."""
        logs = np.stack([gaussian_logpdf(x, c) for c in [*self.covariances, self.defensive]])
        logs += np.log(self.shares)[:, None]
        top = logs.max(axis=0)
        return top + np.log(np.exp(logs - top).sum(axis=0))


@dataclass(frozen=True)
class WeightedEstimate:
    """A self-normalised importance-sampling estimate.

    Attributes:
        value: the estimate of E_p[f].
        se: its delta-method standard error.
        ess: the effective sample size (draws).
        derivative: dE/dt along a target parameter (NaN unless asked for).
        derivative_se: its standard error (NaN unless asked for).
    """

    value: float
    se: float
    ess: float
    derivative: float = math.nan
    derivative_se: float = math.nan

    @property
    def interval(self) -> tuple[float, float]:
        """The 95% Wilson score interval of a probability at the estimate's effective number
        of draws n: p (1 - p) / se^2 (the binomial n of the same standard error), at most the
        ESS (where every weighted draw ended alike, se is 0 or round-off and p (1 - p) / se^2
        unbounded: a plain normal interval would have zero width, though the draws only bound
        how rare the other outcome is); (0, 1) without draws."""
        p = min(max(self.value, 0.0), 1.0)
        n = self.ess
        if 0.0 < p < 1.0 and self.se > 0:
            n = min(n, p * (1.0 - p) / self.se**2)
        if not (math.isfinite(n) and n > 0):
            return 0.0, 1.0
        return wilson_interval(p * n, n)


def normalised_weights(log_target: np.ndarray, log_proposal: np.ndarray) -> np.ndarray:
    """(n,) weights p / g summing to 1, from log densities (n,) (overflow-safe)."""
    log_w = np.asarray(log_target, dtype=float) - np.asarray(log_proposal, dtype=float)
    w = np.exp(log_w - log_w.max())
    return w / w.sum()


def weighted_estimate(values: np.ndarray, log_target: np.ndarray, log_proposal: np.ndarray,
                      score: np.ndarray | None = None) -> WeightedEstimate:
    """E_p[f] from draws with values f (n,), log target and log proposal densities (n,);
    with ``score`` (n,) = d log p / dt, its derivative along t too (a delta-method standard
    error from the influence function)."""
    f = np.asarray(values, dtype=float)
    w = normalised_weights(log_target, log_proposal)
    value = float(w @ f)
    resid = f - value
    se = float(np.sqrt(np.sum(w * w * resid * resid)))
    ess = float(1.0 / np.sum(w * w))
    if score is None:
        return WeightedEstimate(value, se, ess)
    s = np.asarray(score, dtype=float)
    mean_s = float(w @ s)
    derivative = float(w @ (resid * s))
    # influence of draw i on sum w (f - E)(s - s_bar): the product minus its mean
    influence = resid * (s - mean_s) - derivative
    derivative_se = float(np.sqrt(np.sum(w * w * influence * influence)))
    return WeightedEstimate(value, se, ess, derivative, derivative_se)
