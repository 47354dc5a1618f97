"""Joint-noise samplers: stated std, zero mean, support, reproducibility."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinegrasp_env.sampling.noise import DISTRIBUTIONS, METHODS, JointNoise

N = 200_000


@pytest.mark.parametrize("kind", DISTRIBUTIONS)
def test_std_mean_and_support(kind):
    sigma = np.array([0.01, 0.02, 0.0333])
    eps = JointNoise(tuple(sigma), kind).sample(N, 3, np.random.default_rng(3))
    # std of the sample std ~ sigma * sqrt((kurtosis - 1) / (4 N)) <= sigma * 0.0025 here;
    # 5 standard errors:
    np.testing.assert_allclose(eps.std(axis=0), sigma, rtol=0.0125)
    # mean: 5 standard errors
    assert np.all(np.abs(eps.mean(axis=0)) < 5 * sigma / math.sqrt(N))
    half = JointNoise(0.01, kind).half_width
    if math.isfinite(half):
        assert np.all(np.abs(eps) <= half * sigma + 1e-15)
        # the support is used up to its edge
        assert np.all(np.abs(eps).max(axis=0) > 0.95 * half * sigma)


@pytest.mark.parametrize("kind", DISTRIBUTIONS)
@pytest.mark.parametrize("method", METHODS)
def test_reproducible_and_seed_sensitive(kind, method):
    noise = JointNoise(0.02, kind)
    a = noise.sample(257, 7, np.random.default_rng(5), method=method)
    b = noise.sample(257, 7, np.random.default_rng(5), method=method)
    c = noise.sample(257, 7, np.random.default_rng(6), method=method)
    assert a.shape == (257, 7)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("kind", DISTRIBUTIONS)
def test_variance_reduction_samplers_have_the_right_moments(kind):
    noise = JointNoise(0.05, kind)
    anti = noise.sample(10_001, 4, 1, method="antithetic")
    np.testing.assert_array_equal(anti[0:-1:2], -anti[1::2])
    sobol = noise.sample(4096, 4, 1, method="sobol")
    # Sobol points are far more even than random ones: std within 1% at n = 4096
    np.testing.assert_allclose(sobol.std(axis=0), 0.05, rtol=0.01)
    assert np.abs(sobol.mean(axis=0)).max() < 0.05 * 0.01


@pytest.mark.parametrize("kind", DISTRIBUTIONS)
def test_characteristic_function_matches_samples(kind):
    noise = JointNoise(0.4, kind)
    eps = noise.sample(400_000, 1, 2)[:, 0]
    for t in (0.5, 1.0, 3.0):
        empirical = np.cos(t * eps).mean()
        assert abs(empirical - noise.characteristic(t, 0.4)) < 5 / math.sqrt(400_000)


def test_bad_noise_arguments():
    with pytest.raises(ValueError, match="sigma must be finite and >= 0"):
        JointNoise(-0.1)
    with pytest.raises(ValueError, match="sigma must be finite"):
        JointNoise(float("nan"))
    with pytest.raises(ValueError, match="unknown noise type 'cauchy'"):
        JointNoise(0.1, "cauchy")
    with pytest.raises(ValueError, match="sigma has 3 entries but the noise acts on 7 joints"):
        JointNoise((0.1, 0.1, 0.1)).sample(10, 7, 0)
    with pytest.raises(ValueError, match="unknown sampling method"):
        JointNoise(0.1).sample(10, 7, 0, method="lhs")


def test_zero_sigma_gives_zero_noise():
    for kind in DISTRIBUTIONS:
        assert not JointNoise(0.0, kind).sample(100, 7, 0).any()


def test_sigma_is_stored_as_floats_and_checked_up_front():
    """An int or numpy scalar sigma is a float (a list a tuple of floats); a string, a bool or
    a sigma above pi is one ValueError at construction, not a failure after the draws."""
    assert JointNoise(0).sigma == 0.0 and type(JointNoise(0).sigma) is float
    assert type(JointNoise(np.float32(0.0133)).sigma) is float
    assert JointNoise([1, np.float64(0.5)]).sigma == (1.0, 0.5)
    for bad in ("0.0133", True, ["0.1", 0.2], [[0.1, 0.2]]):
        with pytest.raises(ValueError, match="sigma must be a number of radians or one per"):
            JointNoise(bad)
    with pytest.raises(ValueError, match=r"^sigma must be <= pi \(3\.14159 rad\), got 4$"):
        JointNoise((0.01, 4.0))


def test_every_layer_words_the_sigma_bound_alike(capsys):
    """A joint sigma above pi is refused by one rule (``check_sigma_bound``) in the same
    words, whichever layer took it: the library's noise, the env's reset option, a noise
    spec (its field's name), a sweep spec (its place first), a command's ``--sigma``."""
    from kinegrasp_env.cli.main import main
    from kinegrasp_env.envs.arguments import reset_sigma
    from kinegrasp_env.montecarlo.sweep import SpecError, SweepSpec
    from kinegrasp_env.sampling.noise_spec import NoiseSpecError, noise_model_from_spec

    words = "must be <= pi (3.14159 rad), got 4"
    messages = []
    for call, error in [(lambda: JointNoise(4.0), ValueError),
                        (lambda: reset_sigma(4.0), ValueError),
                        (lambda: noise_model_from_spec({"joints": {"sigma": 4.0}}),
                         NoiseSpecError),
                        (lambda: noise_model_from_spec({"hand": {"spread_sigma": 4}}),
                         NoiseSpecError),
                        (lambda: SweepSpec.from_dict({"objects": ["cube"], "sigmas": [4.0]}),
                         SpecError)]:
        with pytest.raises(error) as info:
            call()
        messages.append(str(info.value))
    assert main(["evaluate", "--sigma", "4"]) == 2
    messages.append(capsys.readouterr().err.strip())
    assert messages[:2] == [f"sigma {words}"] * 2
    assert messages[2:4] == [f"noise spec: joints.sigma {words}",
                             f"noise spec: hand.spread_sigma {words}"]
    assert messages[4].endswith(f": sigma {words}")
    assert messages[5] == f"kinegrasp evaluate: error: --sigma {words}"
