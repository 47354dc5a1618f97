"""Estimators, Wilson interval, streaming accumulator, convergence curves."""

from __future__ import annotations

from decimal import Decimal, localcontext

import numpy as np
import pytest
from scipy import stats as sps

from kinegrasp_env.sampling.stats import (
    StreamingMoments,
    convergence_curve,
    moments,
    normal_quantile,
    skewness,
    wilson_interval,
)


def test_skewness_definition():
    x = np.array([0.0, 1.0, 5.0, 2.0])
    mean, s = x.mean(), x.std(ddof=1)
    assert skewness(x) == pytest.approx(np.mean(((x - mean) / s) ** 3))
    # relation to scipy's biased estimator: ours = scipy * ((n-1)/n)^(3/2)
    n = x.size
    assert skewness(x) == pytest.approx(sps.skew(x) * ((n - 1) / n) ** 1.5)
    assert np.isnan(skewness(np.ones(5)))


def test_moments_match_numpy(rng):
    x = rng.gamma(2.0, size=(500, 3))
    m = moments(x)
    np.testing.assert_allclose(m.mean, x.mean(axis=0))
    np.testing.assert_allclose(m.cov, np.cov(x.T, ddof=1))
    np.testing.assert_allclose(m.skew, skewness(x))


def test_wilson_interval():
    lo, hi = wilson_interval(50, 100)
    # textbook value for 50/100: (0.4038, 0.5962)
    assert lo == pytest.approx(0.4038, abs=1e-4) and hi == pytest.approx(0.5962, abs=1e-4)
    lo, hi = wilson_interval(0, 20)
    assert lo == 0.0 and 0.1 < hi < 0.2
    lo, hi = wilson_interval(20, 20)
    assert hi == 1.0 and 0.8 < lo < 0.9
    assert wilson_interval(0, 0) == (0.0, 1.0)
    with pytest.raises(ValueError):
        wilson_interval(5, 3)


def test_wilson_interval_contains_its_estimate_at_both_ends():
    """p-hat = 0 and p-hat = 1 for every n up to 10,000: the interval reaches the estimate
    exactly (the closed form alone gives 0.9999999999999999 for 10/10) and stays in [0, 1]."""
    for n in range(1, 10_001):
        lo, hi = wilson_interval(0, n)
        assert lo == 0.0 and 0.0 < hi <= 1.0, n
        lo, hi = wilson_interval(n, n)
        assert hi == 1.0 and 0.0 <= lo < 1.0, n
    assert wilson_interval(10, 10)[1] == 1.0  # the case that broke Table I's error bars


def test_wilson_interval_brackets_every_estimate():
    """lo <= k/n <= hi and 0 <= lo <= hi <= 1 for every k at every n up to 300."""
    for n in range(1, 301):
        for k in range(n + 1):
            lo, hi = wilson_interval(k, n)
            assert 0.0 <= lo <= k / n <= hi <= 1.0, (k, n, lo, hi)


def exact_wilson(k: int, n: int, z: float) -> tuple[Decimal, Decimal]:
    """The Wilson bounds as the roots of n (p_hat - p)^2 = z^2 p (1 - p), i.e.
    (n + z^2) p^2 - (2 k + z^2) p + k^2 / n = 0, by the quadratic formula in 50-digit
    decimal arithmetic (not the centre +- half form the code uses)."""
    with localcontext() as ctx:
        ctx.prec = 50
        zz = Decimal(z) ** 2
        a, b, c = n + zz, -(2 * k + zz), Decimal(k) ** 2 / n
        root = (b * b - 4 * a * c).sqrt()
        return (-b - root) / (2 * a), (-b + root) / (2 * a)


@pytest.mark.parametrize(("k", "n", "confidence"), [
    (0, 1, 0.95), (1, 1, 0.95), (3, 7, 0.95), (50, 100, 0.95), (9_990, 10_000, 0.95),
    (1, 10_000, 0.99), (613, 1_000, 0.9), (250, 250, 0.8)])
def test_wilson_interval_against_exact_roots(k, n, confidence):
    z = float(sps.norm.ppf(0.5 + confidence / 2))
    want_lo, want_hi = exact_wilson(k, n, z)
    lo, hi = wilson_interval(k, n, confidence)
    # the float closed form agrees to an ulp or two: measured <= 1.9e-16 absolute over 3,000
    # random (k <= n <= 10,000, confidence in 0.8 .. 0.99); allow 1e-15. At k = 0 and k = n
    # the exact bound is the estimate itself, which the clip returns.
    assert abs(Decimal(lo) - want_lo) < Decimal("1e-15")
    assert abs(Decimal(hi) - want_hi) < Decimal("1e-15")


def test_wilson_coverage():
    """The 95% interval covers the true p in about 95% of repetitions."""
    rng = np.random.default_rng(0)
    p, n, reps = 0.83, 200, 4000
    hits = rng.binomial(n, p, size=reps)
    covered = np.mean([lo <= p <= hi for lo, hi in (wilson_interval(int(h), n) for h in hits)])
    # binomial sd of the coverage over 4000 repetitions is ~0.0035; allow 4 sd
    assert abs(covered - 0.95) < 0.015


@pytest.mark.parametrize("chunks", [1, 2, 7, 50])
def test_streaming_equals_batch(rng, chunks):
    x = rng.lognormal(size=(1000, 2))
    acc = StreamingMoments(2)
    for part in np.array_split(x, chunks):
        acc.update(part)
    got, want = acc.result(), moments(x)
    assert got.n == 1000
    np.testing.assert_allclose(got.mean, want.mean, rtol=1e-12)
    np.testing.assert_allclose(got.cov, want.cov, rtol=1e-10)
    np.testing.assert_allclose(got.skew, want.skew, rtol=1e-9)


def test_streaming_merge_is_order_free(rng):
    x = rng.normal(size=(300, 1)) ** 2
    parts = [StreamingMoments(1).update(p) for p in np.array_split(x, 5)]
    forward, backward = StreamingMoments(1), StreamingMoments(1)
    for p in parts:
        forward.merge(p)
    for p in reversed(parts):
        backward.merge(p)
    np.testing.assert_allclose(forward.result().skew, backward.result().skew, rtol=1e-10)
    assert np.isnan(StreamingMoments(1).update(np.ones(1)).result().cov).all()


def test_convergence_errors_shrink_like_one_over_sqrt_n():
    def draw(n, rng):
        return rng.normal(size=(n, 2)) * [1.0, 2.0]

    curve = convergence_curve(draw, [10, 100, 1000, 10000], trials=20, truth_samples=200_000,
                              seed=1)
    assert np.all(np.diff(curve.mean_error) < 0)
    assert np.all(np.diff(curve.cov_error) < 0)
    # slope about -1/2 in log-log
    slope = np.polyfit(np.log(curve.sizes), np.log(curve.mean_error), 1)[0]
    assert -0.65 < slope < -0.35
    again = convergence_curve(draw, [10, 100, 1000, 10000], trials=20, truth_samples=200_000,
                              seed=1)
    np.testing.assert_array_equal(curve.mean_error, again.mean_error)


@pytest.mark.parametrize("confidence", [0.95, 0.99, 0.999, 0.8])
def test_normal_quantile_is_scipys(confidence):
    """The two-sided quantile equals scipy.stats.norm.ppf(0.5 + c/2) to the bit, the stored
    95% value included (an independent implementation: scipy's distribution object)."""
    assert normal_quantile(confidence) == float(sps.norm.ppf(0.5 + confidence / 2))
