"""Statistics of the null-space variants of one palm pose from one batch of closings.

Variants that reach the same palm pose with other arm configurations (the paper's Fig. 10)
differ only in how joint noise moves the palm (:mod:`kinegrasp_env.montecarlo.palm_batch`):
one batch of closings over the palm's deviation, drawn from a mixture of the variants'
Gaussians (first-order covariance, second-order mean), gives each variant's P(FC) and Q's
moments by importance weights. A variant whose effective sample size falls below the draws
asked for is evaluated directly.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from kinegrasp_env.montecarlo.grasp_stats import GraspStats
from kinegrasp_env.montecarlo.palm_batch import (
    BATCH_FACTOR,
    PalmJacobian,
    close_batch,
    close_deltas,
)
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.grasps import Grasp

#: Palm poses of variants agree to this (metres and rotation-matrix entries).
SAME_POSE_TOL = 1e-6


def variant_stats(grasps: list[Grasp], sigma: float, samples: int, seed: int, *,
                  robot: RobotDescription, direct: Callable[[Grasp], Any],
                  engine: str = "pybullet", friction: float = 0.5,
                  on_batch: Callable[[], None] | None = None) -> list:
    """Per variant (same object, same palm pose) of ``robot`` (an arm of six or more joints:
    its palm error and engines close the batch) at Gaussian joint noise ``sigma`` (radians):
    a :class:`GraspStats` re-weighted from one batch of ``BATCH_FACTOR * samples`` closings
    (``samples`` then reads as the estimate's effective sample size, rounded; its interval
    is the normal one of the weights' standard error; ``outcomes`` is empty), or
    ``direct(grasp)`` (its evaluation on ``samples`` draws) where the effective sample size
    is below ``samples``. ``on_batch()`` is called once the batch is closed, before any
    direct evaluation.

    Raises:
        ValueError: the grasps are not variants of one palm pose of one object, or the
            robot's arm has fewer than six joints (:class:`~kinegrasp_env.montecarlo.
            palm_batch.PalmJacobian`).
    """
    first = grasps[0]
    for g in grasps[1:]:
        if g.object != first.object or not np.allclose(g.palm_pose, first.palm_pose,
                                                       atol=SAME_POSE_TOL):
            raise ValueError(f"grasp {g.id} is not a variant of grasp {first.id}'s palm pose "
                             f"(one batch answers variants of one palm pose only)")
    name = robot.name
    q0 = np.stack([np.asarray(g.q0, dtype=float) for g in grasps])
    jacobian = PalmJacobian(robot)
    covs, means = jacobian.covariance(q0, sigma), jacobian.mean(q0, sigma)
    batch = close_batch(q0[0], first.object, covs, BATCH_FACTOR * samples, seed, engine=engine,
                        friction=friction, robot=name)
    _, quality = close_deltas(q0[0], np.zeros((1, 6)), first.object, engine=engine,
                              friction=friction, robot=name)
    nominal = float(quality[0])
    if on_batch is not None:
        on_batch()
    out = []
    for grasp, cov, mean in zip(grasps, covs, means, strict=True):
        est = batch.estimate(cov, mean=mean)
        if est.ess < samples:
            out.append(direct(grasp))
            continue
        p = est.p_fc
        out.append(GraspStats(p.value, p.interval, est.q_mean, est.q_std**2, est.q_std,
                              est.q_skew, nominal, nominal - est.q_mean, round(p.ess),
                              {}, sigma, "gaussian", seed, engine))
    return out
