"""Planar arms: Monte Carlo end-effector moments against the closed form."""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.robot.planar import PlanarArm
from kinegrasp_env.sampling.noise import DISTRIBUTIONS, JointNoise


def test_forward_kinematics_by_hand():
    arm = PlanarArm((2.0, 2.0))
    np.testing.assert_allclose(arm.forward(np.array([0.0, np.pi / 2])), [2.0, 2.0], atol=1e-12)
    joints = arm.joint_positions(np.array([np.pi / 2, -np.pi / 2]))
    np.testing.assert_allclose(joints, [[0, 0], [0, 2], [2, 2]], atol=1e-12)


@pytest.mark.parametrize("kind", DISTRIBUTIONS)
@pytest.mark.parametrize(("links", "q0"), [((2.0, 2.0), (0.0, 1.5708)),
                                           ((1.0, 1.5, 0.7), (0.3, 1.2, -0.7))])
def test_sampled_moments_agree_with_closed_form(kind, links, q0):
    arm = PlanarArm(links)
    noise = JointNoise(0.15, kind)  # large enough for the nonlinearity to matter
    n = 200_000
    samples = arm.sample(np.array(q0), noise, n, np.random.default_rng(7))
    mean, cov = arm.exact_moments(np.array(q0), noise)
    # the mean is biased away from the nominal point: check that the test can tell
    assert np.linalg.norm(mean - arm.forward(np.array(q0))) > 0.005
    se_mean = np.sqrt(np.diag(cov) / n)
    assert np.all(np.abs(samples.mean(axis=0) - mean) < 4 * se_mean)
    # standard error of a sample covariance entry: sqrt(var(x_i x_j) / n), estimated
    centred = samples - mean
    for i in range(2):
        for j in range(2):
            prod = centred[:, i] * centred[:, j]
            se = prod.std() / np.sqrt(n)
            assert abs(prod.mean() - cov[i, j]) < 4 * se


def test_bad_planar_arm():
    with pytest.raises(ValueError, match="link lengths must be finite and > 0"):
        PlanarArm((1.0, -1.0))
    with pytest.raises(ValueError, match="2-link arm needs 2 joint angles, got 3"):
        PlanarArm((1.0, 1.0)).forward(np.zeros(3))
