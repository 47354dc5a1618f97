"""The environment's reward from one batch of closings per grasp (``reward="batch"``).

Every step keeps the palm pose of the episode's grasp and moves only the elbow; a draw's
outcome then depends only on the palm's deviation (:mod:`kinegrasp_env.montecarlo.
palm_batch`; the batch moves the hand alone, the arm links staying where the grasp's own
configuration puts them), and the noise level only changes its spread. Every robot of the
env: its engines, a 7-joint arm's self-motion, a 6-joint arm's IK branches.
The first episode of a grasp draws one batch of closings from a mixture of the deviation's
first-order Gaussians at the grasp's elbow and at angles around it (every
:data:`SPAN_STEP` radians within :data:`SPAN`, where reachable; a 6-joint arm: at every IK
branch of the grasp's palm pose), each at
:data:`SIGMA_LEVELS` noise levels spread over the env's ``sigma_range``; the batch is kept
for every later episode of that grasp, and each step's reward is it re-weighted to the
current configuration and noise: no draws per step. The batch's seed comes from the grasp
alone, so a reward does not depend on which episodes came before.

What changes for an agent: the reward is a deterministic, smooth function of the grasp, the
elbow angle and sigma (the batch's error is fixed per grasp, where the draws' reward is a
fresh estimate each step): less noise to learn through, and one systematic error per grasp
it could fit. Where the effective sample size falls below the env's ``n_draws``, sigma is
0, or the step's configuration starts in collision (an arm link in the object or the table,
which the batch, closed with the arm at the grasp's own configuration, cannot see), the
step takes draws as usual; ``info["reward_method"]`` says which.
"""

from __future__ import annotations

import zlib

import numpy as np

from kinegrasp_env.montecarlo.draws import OUTCOMES
from kinegrasp_env.montecarlo.palm_batch import (
    PalmBatch,
    PalmJacobian,
    close_batch,
    gaussian_terms,
)
from kinegrasp_env.robot.branch_motion import BranchMotion
from kinegrasp_env.robot.null_motion import ArmSelfMotion
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.reweight import BatchTooSmall, least_batch

#: Elbow angles (radians) either side of the episode's start the batch covers.
SPAN = 1.2
#: The spacing of the covered angles (radians).
SPAN_STEP = 0.3
#: Noise levels of the batch's mixture, spread geometrically over the env's sigma range.
SIGMA_LEVELS = 5


class BatchReward:
    """One grasp's batch and its re-weighted estimates.

    Args:
        batch: the closings (:class:`~kinegrasp_env.montecarlo.palm_batch.PalmBatch`).
        jacobian: the flange's body Jacobian (shared by the env's batches).
    """

    def __init__(self, batch: PalmBatch, jacobian: PalmJacobian) -> None:
        self.batch, self.jacobian = batch, jacobian

    @classmethod
    def build(cls, engine: str, object_name: str, q0: np.ndarray, moved: list[np.ndarray],
              sigmas: list[float], size: int, seed: int,
              jacobian: PalmJacobian, robot: str) -> BatchReward:
        """The batch of ``size`` closings of a grasp of ``robot`` reached at q0 (dof,): its
        mixture over q0 and the configurations ``moved`` (each (dof,): the same palm pose),
        each at every noise level of ``sigmas`` (radians)."""
        qs = np.stack([q0, *moved])
        covs = np.concatenate([jacobian.covariance(qs, s) for s in sigmas])
        batch = close_batch(q0, object_name, covs, size, seed, engine=engine, robot=robot)
        return cls(batch, jacobian)

    def estimate(self, q: np.ndarray, noise: tuple[np.ndarray, np.ndarray], minimum: int
                 ) -> dict | None:
        """The reward's estimate at configuration q (dof,) and Gaussian noise ``noise``
        (:func:`batch_noise`'s joint and palm covariances) (the keys of the draws'
        estimate), or None where the effective sample size is below ``minimum``."""
        cov, mean = self.jacobian.gaussian(np.asarray(q, dtype=float)[None], *noise)
        est = self.batch.estimate(cov[0], mean=mean[0])
        if not est.ess >= minimum:
            return None
        return {"p_fc": est.p_fc.value, "p_fc_ci": est.p_fc.interval,
                "q_mean": est.q_mean if est.p_fc.value > 0 else 0.0,
                "draws": len(self.batch), "effective_draws": est.ess,
                "outcome_shares": {name: float(v) for name, v in
                                   zip(OUTCOMES, est.outcome_shares, strict=True)},
                "score_value": est.p_fc.value, "reward_method": "batch"}


def covered_angles(psi0: float) -> list[float]:
    """The elbow angles (radians) besides ``psi0`` the batch covers."""
    steps = round(SPAN / SPAN_STEP)
    return [psi0 + sign * k * SPAN_STEP for k in range(1, steps + 1) for sign in (-1.0, 1.0)]


def covered_configurations(q0: np.ndarray,
                           elbow: ArmSelfMotion | BranchMotion) -> list[np.ndarray]:
    """The configurations (each (dof,): q0's palm pose) a grasp's batch covers besides
    q0: the elbow angles of :func:`covered_angles`, where reachable; a 6-joint arm's other
    IK branches.

    Args:
        q0: (dof,) the grasp's configuration, radians.
        elbow: the arm's elbow coordinate: its self-motion, or its IK branches
            (``angle_links`` None: an arm without self-motion).
    """
    if elbow.angle_links is None:
        own, _ = elbow.branch_of(q0)
        return [np.concatenate([arm, q0[elbow.arm:]])
                for k, arm in enumerate(elbow.branches(q0)) if k != own]
    psis = covered_angles(float(elbow.elbow_angle(q0[None])[0]))
    moved = [elbow.set_elbow_angle(q0, psi) for psi in psis]
    return [q for q, reached in moved if reached]


def check_batch_size(size: int, self_motion: bool, sigma_range: tuple[float, float]) -> None:
    """ValueError (one line) where a batch of ``size`` closings cannot cover the targets of
    every grasp of an arm with a self-motion (``self_motion``: a 7-joint arm) at the noise
    levels of ``sigma_range`` (radians): its configurations (the grasp's and its covered
    angles) times its noise levels, beside the defensive component
    (:func:`~kinegrasp_env.sampling.reweight.least_batch`). A 6-joint arm's configurations
    are its IK branches of the grasp's palm pose, known at its first batch (where a batch
    too small for them is refused: :func:`batch_size_error`)."""
    if not self_motion or max(sigma_range) <= 0:  # no batch: every step takes draws
        return
    configurations = 1 + len(covered_angles(0.0))
    levels = len(sigma_levels(*sigma_range))
    need = least_batch(configurations * levels)
    if size < need:
        raise ValueError(f"batch_size {size} is too small: a grasp's batch covers up to "
                         f"{configurations} configurations x {levels} noise "
                         f"level{'s' if levels > 1 else ''} and needs at least {need} "
                         "closings")


def batch_size_error(size: int, grasp: str, error: BatchTooSmall) -> ValueError:
    """The one-line error of a ``batch_size`` too small for a grasp's batch (``grasp``: the
    grasp, in words), from the mixture's own refusal."""
    return ValueError(f"batch_size {size} is too small for {grasp}: {error}")


def sigma_levels(low: float, high: float) -> list[float]:
    """:data:`SIGMA_LEVELS` noise levels (radians) spread geometrically over [low, high]
    (one where they are equal; a zero low end starts the spread at high / 10)."""
    if high <= low:
        return [float(high)]
    start = low if low > 0 else high / 10.0
    return np.geomspace(start, high, SIGMA_LEVELS).tolist()


def batch_noise(noise: JointNoise | NoiseModel, arm: int
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """((arm, arm) joint covariance, rad^2; (6, 6) palm covariance) of a noise a batch
    re-weights to (:func:`~kinegrasp_env.montecarlo.palm_batch.gaussian_terms`: zero-mean
    Gaussian noise on the arm's joints, and on the palm beside it, ``JointNoise`` or a noise
    model), or None where it does not: another distribution, a bias, another source, no
    joint noise (sigma 0, or palm noise alone: the batch covers joint noise levels), or joint
    noise that leaves the palm's deviation without error in a direction."""
    try:
        terms = gaussian_terms(noise, arm)
    except ValueError:
        return None
    return terms if np.any(terms[0]) else None


def grasp_seed(key: tuple) -> int:
    """The batch seed of a grasp (its object, id and palm pose): the same in every env."""
    return zlib.crc32(repr(key).encode())

