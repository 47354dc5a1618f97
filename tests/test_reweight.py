"""Importance re-weighting against cases with a known answer.

The outcome field is a half-space, f(x) = [u . x < c]: under N(0, S) its probability is
Phi(c / sqrt(u^T S u)) exactly, and its derivative along S(t) = S0 + t S1 follows by the
chain rule, so every estimate is checked against a closed form, not against the code. The
densities are checked against scipy's, the score against a finite difference of scipy's.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from kinegrasp_env.sampling.reweight import (
    MixtureProposal,
    gaussian_logpdf,
    gaussian_score,
    weighted_estimate,
)

D = 6


def random_covariance(rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    a = rng.standard_normal((D, D))
    return scale * (a @ a.T / D + 0.1 * np.eye(D))


def halfspace_probability(u: np.ndarray, c: float, cov: np.ndarray) -> float:
    return float(stats.norm.cdf(c / np.sqrt(u @ cov @ u)))


@pytest.fixture(scope="module")
def setting():
    rng = np.random.default_rng(11)
    covs = np.stack([random_covariance(rng) for _ in range(4)])
    u = rng.standard_normal(D)
    u /= np.linalg.norm(u)
    return covs, u, 0.4


def test_logpdf_matches_scipy():
    rng = np.random.default_rng(0)
    cov = random_covariance(rng)
    x = rng.standard_normal((50, D))
    ref = stats.multivariate_normal(np.zeros(D), cov).logpdf(x)
    np.testing.assert_allclose(gaussian_logpdf(x, cov), ref, rtol=1e-12, atol=1e-12)


def test_mixture_logpdf_is_the_weighted_sum_of_scipy_densities(setting):
    covs, _, _ = setting
    proposal = MixtureProposal.covering(covs, 1000)
    x = np.random.default_rng(1).standard_normal((20, D))
    dens = [stats.multivariate_normal(np.zeros(D), c).pdf(x)
            for c in [*proposal.covariances, proposal.defensive]]
    ref = np.log(np.tensordot(proposal.shares, np.stack(dens), axes=1))
    np.testing.assert_allclose(proposal.logpdf(x), ref, rtol=1e-12)
    assert proposal.counts.sum() == 1000


def test_score_is_the_derivative_of_scipys_log_density():
    rng = np.random.default_rng(2)
    s0, s1 = random_covariance(rng), random_covariance(rng, 0.1)
    x = rng.standard_normal((10, D))
    h = 1e-6

    def logp(t):
        return stats.multivariate_normal(np.zeros(D), s0 + t * s1).logpdf(x)

    numeric = (logp(h) - logp(-h)) / (2 * h)
    np.testing.assert_allclose(gaussian_score(x, s0, s1), numeric, rtol=1e-6, atol=1e-7)


def _estimates(covs, target, u, c, n, seed, derivative=None):
    proposal = MixtureProposal.covering(covs, n)
    x = proposal.sample(np.random.default_rng(seed))
    f = x @ u < c
    score = None if derivative is None else gaussian_score(x, target, derivative)
    return weighted_estimate(f, gaussian_logpdf(x, target), proposal.logpdf(x), score)


def test_every_target_within_four_standard_errors(setting):
    """Each component and the mid-point of two: the estimate within 4 SE of the closed
    form (a false alarm once in ~16,000), and the ESS a sizeable share of the batch."""
    covs, u, c = setting
    targets = [*covs, 0.5 * (covs[0] + covs[1])]
    for k, target in enumerate(targets):
        est = _estimates(covs, target, u, c, 8000, seed=100 + k)
        truth = halfspace_probability(u, c, target)
        assert abs(est.value - truth) <= 4 * est.se, (k, est, truth)
        assert est.ess > 1000


def test_interval_covers_at_its_level(setting):
    """Over 300 independent batches the 95% interval covers the closed form in 90-99% of
    them (a binomial(300, 0.95) count lies in that band with probability > 0.99)."""
    covs, u, c = setting
    target = 0.5 * (covs[1] + covs[2])
    truth = halfspace_probability(u, c, target)
    hits = 0
    for seed in range(300):
        lo, hi = _estimates(covs, target, u, c, 1000, seed).interval
        hits += lo <= truth <= hi
    assert 0.90 <= hits / 300 <= 0.99, hits


def test_derivative_matches_the_chain_rule(setting):
    """dP/dt along S(t) = S + t S1 at t = 0: Phi'(z) dz/dt with z = c / sqrt(u^T S u)
    (S1 a growth of the whole target and a stretch along u: the score's variance stays
    moderate, as it does for the palm's covariance along the self-motion)."""
    covs, u, c = setting
    target = covs[0]
    s1 = 0.3 * target + 0.5 * np.outer(u, u)
    var = u @ target @ u
    exact = stats.norm.pdf(c / np.sqrt(var)) * (-0.5 * c * var**-1.5 * (u @ s1 @ u))
    est = _estimates(covs, target, u, c, 20000, seed=7, derivative=s1)
    assert abs(est.derivative - exact) <= 4 * est.derivative_se, (est, exact)
    assert est.derivative_se < abs(exact) / 3


def test_proposal_refuses_a_batch_too_small(setting):
    covs, _, _ = setting
    with pytest.raises(ValueError, match="at least 5"):
        MixtureProposal.covering(covs, 3)
    assert np.all(MixtureProposal.covering(covs, 5).counts >= 1)
    many = np.repeat(covs, 19, axis=0)  # 76 targets: 80 draws leave some without one
    with pytest.raises(ValueError, match="at least 84"):
        MixtureProposal.covering(many, 80)
    assert np.all(MixtureProposal.covering(many, 84).counts >= 1)
    with pytest.raises(ValueError, match="not positive definite"):
        MixtureProposal.covering(np.zeros((1, D, D)), 10)


def test_a_degenerate_target_is_a_one_line_error():
    with pytest.raises(ValueError, match="not positive definite"):
        gaussian_logpdf(np.zeros((1, D)), np.zeros((D, D)))


def _wilson(p: float, n: float, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson's score interval written out (p of n draws)."""
    centre, half = p + z * z / (2 * n), z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (centre - half) / (1 + z * z / n), (centre + half) / (1 + z * z / n)


def test_the_interval_is_wilsons_at_the_effective_number_of_draws():
    """n = p (1 - p) / se^2 where that is below the ESS (the binomial n of the same standard
    error), the ESS where it is above it (se 0 or round-off: every weighted draw alike)."""
    from kinegrasp_env.sampling.reweight import WeightedEstimate

    wide = WeightedEstimate(0.3, 0.03, 1000.0)  # n = 0.21 / 0.0009 = 233.3
    assert wide.interval == pytest.approx(_wilson(0.3, 0.21 / 0.0009), rel=1e-9)
    capped = WeightedEstimate(0.3, 0.001, 1000.0)  # 210,000 > the ESS
    assert capped.interval == pytest.approx(_wilson(0.3, 1000.0), rel=1e-9)
    held = WeightedEstimate(1.0, 0.0, 250.0)
    assert held.interval == pytest.approx(_wilson(1.0, 250.0), rel=1e-9)
    assert held.interval[0] < 1.0
