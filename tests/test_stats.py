"""Estimators, Wilson interval, streaming accumulator, convergence curves."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from kinegrasp_env.sampling.stats import (
    StreamingMoments,
    convergence_curve,
    moments,
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
