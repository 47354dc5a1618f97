"""One batch of closings over the palm's deviation, re-weighted to any elbow and noise level.

For one palm pose and one hand pre-shape, a draw's outcome depends only on where the hand
truly is: the hand root's deviation delta (6,) from its nominal pose, in the flange frame
(translation t, metres, then rotation vector r, radians: the engines' palm error,
:func:`~kinegrasp_env.sampling.noise_model.offset_transforms`). The arm's links do not close
or score (the engines close the hand alone; an object with a support table is the exception,
refused here). The elbow angle psi and the joint noise change only the distribution of delta:
to first order, joint errors e ~ N(0, S_q) give delta = J_b(q) e ~ N(0, J_b S_q J_b^T), J_b
the flange's body Jacobian (6, 7) (:meth:`PalmJacobian.covariance`); to second order its mean
moves off 0 (:meth:`PalmJacobian.mean`), and the targets are N(m(q), J_b S_q J_b^T). So one
batch of closings over delta drawn from a mixture that covers the targets
(:class:`~kinegrasp_env.sampling.reweight.MixtureProposal`) answers P(FC) and Q's moments at
every psi and sigma by importance weights (:meth:`PalmBatch.estimate`), and, the weights
being smooth in psi, their derivative too.

What the Gaussian model costs (its density against joint noise through the exact
kinematics, with and without the second-order mean) is measured by
``benchmarks/bench_reweight.py``; :func:`linear_draws` gives the model's deltas that
comparison needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics, rigid_inverse, rotation_log
from kinegrasp_env.sampling.noise import as_generator
from kinegrasp_env.sampling.noise_model import offset_transforms
from kinegrasp_env.sampling.reweight import (
    MixtureProposal,
    WeightedEstimate,
    gaussian_logpdf,
    gaussian_score,
    normalised_weights,
    weighted_estimate,
)

ARM = 7
#: Draws per engine call of a batch.
BATCH_CHUNK = 2000
#: The spawn key's first entry of the batches' random streams: a three-entry key, which no
#: chunk stream of a run has (:func:`~kinegrasp_env.sampling.noise_model.chunk_stream`).
BATCH_STREAM = 0xBA7C4
#: Closings per batch, as a multiple of the direct draws per target it stands for.
BATCH_FACTOR = 2
#: The joint step of the second differences of the deviation's mean (radians): the
#: truncation error is O(step^2) of the mean, the round-off ~1e-16 / step^2 of the reach.
MEAN_STEP = 1e-3


def joint_covariance(sigma, dof: int = ARM) -> np.ndarray:
    """(dof, dof) covariance of Gaussian errors on an arm of ``dof`` joints (default 7):
    sigma (radians) a scalar, ``dof`` per-joint values, or a (dof, dof) covariance itself.

    Raises:
        ValueError: another shape, a negative or non-finite entry.
    """
    s = np.asarray(sigma, dtype=float)
    if not np.all(np.isfinite(s)):
        raise ValueError(f"sigma must be finite, got {sigma!r}")
    if s.shape == (dof, dof):
        return 0.5 * (s + s.T)
    if s.ndim == 0 or s.shape == (dof,):
        if np.any(s < 0):
            raise ValueError(f"sigma must be >= 0, got {sigma!r}")
        return np.diag(np.broadcast_to(s, (dof,)) ** 2)
    raise ValueError(f"sigma must be a scalar, {dof} values or a {dof}x{dof} covariance, got "
                     f"shape {s.shape}")


def batch_stream(seed: int, index: int) -> np.random.Generator:
    """The generator of batch ``index`` (0, 1, ...) of a run with ``seed``: independent of
    every chunk's draws of that run."""
    key = (BATCH_STREAM, 0, int(index))
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=key))


def check_batch_object(object_name: str) -> None:
    """ValueError for an object on a support table (its arm links then matter, and one
    batch over the palm's deviation cannot stand for every arm)."""
    from kinegrasp_env.world.objects import load_object

    if load_object(object_name).table is not None:
        raise ValueError(f"object {object_name!r} stands on a support table: the arm's links "
                         f"then matter, and one batch of palm deviations cannot stand for "
                         f"every elbow; use direct draws (--method direct)")


def check_batch_engine(engine: str) -> None:
    """ValueError (one line) unless ``engine`` names an engine that closes a hand moved by a
    palm error (the class's ``takes_errors``: ``fast``, ``pybullet``; the physics engine does
    not split the robot's body), as a batch of palm deviations needs."""
    from kinegrasp_env.montecarlo.engines import error_engines

    takers = error_engines()
    if engine not in takers:
        raise ValueError(f"a batch of palm deviations is closed by an engine that takes palm "
                         f"errors ({' or '.join(takers)}), got engine {engine!r}")


def gaussian_terms(noise, dof: int = ARM) -> tuple[np.ndarray, np.ndarray]:
    """((dof, dof) joint covariance of an arm of ``dof`` joints, (6, 6) palm covariance) of a
    noise whose every source is a
    zero-mean Gaussian on the arm joints or on the palm: Gaussian ``JointNoise`` (scalar or
    per-joint sigma), or a noise model of ``joints`` (Gaussian, independent or with a
    covariance, no bias) and ``palm`` sources. To first order the palm's deviation is then
    N(0, J S_q J^T + S_palm).

    Raises:
        ValueError: another distribution, a bias, or another source (hand, object,
            friction: the deviation of the palm does not carry them).
    """
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.sampling.noise_model import NoiseModel

    if isinstance(noise, JointNoise):
        if noise.kind != "gaussian":
            raise ValueError(f"re-weighting needs Gaussian joint noise, got {noise.kind} "
                             f"noise; use direct draws (--method direct)")
        return _nonzero(joint_covariance(noise.sigma, dof)), np.zeros((6, 6))
    if not isinstance(noise, NoiseModel):
        raise ValueError(f"re-weighting needs joint noise or a noise model, got "
                         f"{type(noise).__name__}")
    extra = [s for s in noise.sources if s not in ("joints", "palm")]
    if extra:
        raise ValueError(f"re-weighting covers the joints and palm sources only, not "
                         f"{', '.join(extra)}; use direct draws (--method direct)")
    joints, palm = noise.joints, noise.palm
    if joints is None:
        cov = np.zeros((dof, dof))
    elif joints.distribution != "gaussian" or joints.bias is not None:
        raise ValueError("re-weighting needs zero-mean Gaussian joint noise (no bias); use "
                         "direct draws (--method direct)")
    else:
        joints.check_count(dof)
        cov = joint_covariance(joints.covariance if joints.covariance is not None
                               else joints.sigma, dof)
    palm_cov = np.zeros((6, 6)) if palm is None else np.diag(palm.variances())
    if not np.any(palm_cov):
        cov = _nonzero(cov)
    return cov, palm_cov


def _nonzero(cov: np.ndarray) -> np.ndarray:
    """``cov`` (dof, dof), or ValueError where it leaves the palm's deviation degenerate (a
    joint noise of rank below 6: every weight would be undefined)."""
    if not np.any(cov):
        raise ValueError("re-weighting needs joint noise, and sigma is 0 (every draw is the "
                         "nominal closing); use direct draws (--method direct)")
    if np.linalg.matrix_rank(cov) < 6:
        raise ValueError("re-weighting needs joint noise on at least six joints (the palm's "
                         "deviation has six dimensions); use direct draws (--method direct)")
    return cov


class PalmJacobian:
    """The flange's body Jacobian of an arm of six or more joints (one kinematics, reused):
    ``description``'s (default: the default robot's; its flange: :func:`~kinegrasp_env.
    closing.hand_errors.flange_link`).

    Attributes:
        arm: the arm's joints.
    """

    def __init__(self, description: RobotDescription | None = None) -> None:
        from kinegrasp_env.closing.hand_errors import flange_link

        description = description or load_robot(DEFAULT_ROBOT)
        if description.arm_dof < 6:
            raise ValueError(f"re-weighting needs an arm of at least six joints (the "
                             f"palm's deviation has six dimensions); robot "
                             f"{description.name!r} has {description.arm_dof}")
        self.kin, self.flange = Kinematics(description.model), flange_link(description)
        self.arm = description.arm_dof

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """(n, 6, arm) d delta / d q_arm at configurations q (n, dof) or (dof,): rows 0-2 the
        flange origin's velocity, rows 3-5 its angular velocity, both in the flange frame."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        rot = self.kin.pose(q, self.flange)[:, :3, :3]
        jac = self.kin.jacobian(q, self.flange)[:, :, :self.arm]
        rt = np.swapaxes(rot, 1, 2)
        return np.concatenate([rt @ jac[:, :3], rt @ jac[:, 3:]], axis=1)

    def covariance(self, q: np.ndarray, sigma) -> np.ndarray:
        """(n, 6, 6) J_b S_q J_b^T at configurations q (n, dof) for joint noise ``sigma``
        (:func:`joint_covariance` of the arm's joints)."""
        jac = self(q)
        return jac @ joint_covariance(sigma, self.arm) @ np.swapaxes(jac, 1, 2)

    def gaussian(self, q: np.ndarray, joints, palm: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The Gaussian model of the palm's deviation at configurations q (n, dof): ((n, 6, 6)
        covariance, (n, 6) mean) under zero-mean Gaussian joint noise ``joints``
        (:func:`joint_covariance`'s forms) and a zero-mean palm error of covariance ``palm``
        (6, 6; metres, radians) in the flange's frame, added to it: J S_q J^T + S_palm to
        first order, and the joint noise's second-order mean (:meth:`mean`; the palm error's
        is 0)."""
        return self.deviation_covariance(q, joints, palm), self.mean(q, joints)

    def deviation_covariance(self, q: np.ndarray, joints, palm: np.ndarray | None = None
                             ) -> np.ndarray:
        """(n, 6, 6) :meth:`gaussian`'s covariance alone: J S_q J^T + S_palm."""
        cov = self.covariance(q, joints)
        return cov if palm is None else cov + palm

    def deviation(self, q0: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(n, 6) the exact deviation of the flange at configurations q (n, dof) from its
        pose at q0 (n, dof) or (dof,): F(q0)^-1 F(q) as (translation, metres; rotation
        vector, radians), the convention of the engines' palm error."""
        q0 = np.atleast_2d(np.asarray(q0, dtype=float))
        rel = rigid_inverse(self.kin.pose(q0, self.flange)) @ self.kin.pose(q, self.flange)
        return np.concatenate([rel[:, :3, 3], rotation_log(rel[:, :3, :3])], axis=1)

    def mean(self, q: np.ndarray, sigma, step: float = MEAN_STEP) -> np.ndarray:
        """(n, 6) the deviation's mean to second order at configurations q (n, dof) for
        joint noise ``sigma`` (:func:`joint_covariance`, S_q = sum_m l_m v_m v_m^T): with
        delta(e) the exact deviation of joint errors e, E[delta] = 1/2 sum_m l_m v_m^T H v_m
        + O(|S_q|^2), each v^T H v by the central second difference
        (delta(h v) + delta(-h v)) / h^2 (h = ``step``, radians). The first-order model's mean
        is 0; what the shift does to P(FC) is measured by ``benchmarks/bench_reweight.py``."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        arm = self.arm
        lam, vec = np.linalg.eigh(joint_covariance(sigma, arm))
        steps = np.concatenate([step * vec.T, -step * vec.T])  # (2 arm, arm): +h v_m, -h v_m
        moved = np.repeat(q, len(steps), axis=0)
        moved[:, :arm] += np.tile(steps, (len(q), 1))
        dev = self.deviation(np.repeat(q, len(steps), axis=0), moved)
        dev = dev.reshape(len(q), 2, arm, 6)
        return 0.5 * np.einsum("m,nmk->nk", lam, dev[:, 0] + dev[:, 1]) / step**2


def linear_draws(covariance: np.ndarray, n: int, seed, mean: np.ndarray | None = None
                 ) -> np.ndarray:
    """(n, 6) deltas drawn from N(mean (default 0), covariance (6, 6)) (the Gaussian model)."""
    centre = np.zeros(6) if mean is None else np.asarray(mean, dtype=float)
    return as_generator(seed).multivariate_normal(centre, covariance, size=n,
                                                  method="cholesky")


@dataclass
class PalmEstimate:
    """What one target distribution of delta gets from a batch.

    Attributes:
        p_fc: P(force closure) (its derivative along psi where asked for).
        q_mean, q_std, q_skew: Q's mean, standard deviation and skewness over the
            force-closure draws, weighted (NaN where no draw is in force closure; the
            skewness NaN where Q does not vary).
        outcome_shares: (len(OUTCOMES),) each outcome's weighted share of the draws.
        ess: the effective sample size of the target's weights (draws).
    """

    p_fc: WeightedEstimate
    q_mean: float
    q_std: float
    q_skew: float = float("nan")
    outcome_shares: np.ndarray | None = None

    @property
    def ess(self) -> float:
        return self.p_fc.ess


@dataclass
class PalmBatch:
    """Closings of one grasp at palm deviations drawn from a proposal.

    Attributes:
        q: (dof,) the configuration closed (its palm pose is the grasp's).
        deltas: (n, 6) the palm deviations (flange frame: metres, then radians).
        log_proposal: (n,) the proposal's log density at each delta.
        outcome: (n,) int8 outcome per draw; quality: (n,) Q (0 unless force closure).
    """

    q: np.ndarray
    deltas: np.ndarray
    log_proposal: np.ndarray
    outcome: np.ndarray
    quality: np.ndarray

    def __len__(self) -> int:
        return len(self.deltas)

    @property
    def fc(self) -> np.ndarray:
        """(n,) bool: force closure per draw."""
        return self.outcome == FORCE_CLOSURE

    def estimate(self, covariance: np.ndarray, derivative: np.ndarray | None = None, *,
                 mean: np.ndarray | None = None, mean_derivative: np.ndarray | None = None
                 ) -> PalmEstimate:
        """P(FC) and Q's moments for deltas ~ N(mean (6,) (default 0), covariance (6, 6));
        with ``derivative`` (6, 6) = d covariance / d psi (and ``mean_derivative`` (6,) =
        d mean / d psi), P(FC)'s derivative along psi too."""
        log_target = gaussian_logpdf(self.deltas, covariance, mean)
        score = None if derivative is None else gaussian_score(
            self.deltas, covariance, derivative, mean, mean_derivative)
        p = weighted_estimate(self.fc, log_target, self.log_proposal, score)
        weights = normalised_weights(log_target, self.log_proposal)
        shares = np.bincount(self.outcome, weights=weights, minlength=len(OUTCOMES))
        w = weights * self.fc
        if w.sum() <= 0.0:
            return PalmEstimate(p, float("nan"), float("nan"), outcome_shares=shares)
        w = w / w.sum()
        mean = float(w @ self.quality)
        std = float(np.sqrt(max(float(w @ (self.quality - mean) ** 2), 0.0)))
        skew = float(w @ ((self.quality - mean) / std) ** 3) if std > 0 else float("nan")
        return PalmEstimate(p, mean, std, skew, shares)


def close_deltas(q: np.ndarray, deltas: np.ndarray, object_name: str, *, engine: str = "fast",
                 friction: float = 0.5, progress=None,
                 robot: str = DEFAULT_ROBOT) -> tuple[np.ndarray, np.ndarray]:
    """((n,) outcome, (n,) Q) of closing the hand of catalog ``robot`` at configuration q
    (dof,) with the hand moved by each delta (n, 6) in the flange frame (its palm error:
    :mod:`~kinegrasp_env.closing.hand_errors`), by its engine ``engine``, in chunks of
    :data:`BATCH_CHUNK` (``progress(done, total)`` after each)."""
    from kinegrasp_env.montecarlo.engines import make_engine

    check_batch_engine(engine)
    check_batch_object(object_name)
    n = len(deltas)
    outcome, quality = np.empty(n, np.int8), np.empty(n)
    eng = make_engine(engine, robot, object_name, friction=friction)
    try:
        for start in range(0, n, BATCH_CHUNK):
            stop = min(n, start + BATCH_CHUNK)
            rows = np.tile(np.asarray(q, dtype=float), (stop - start, 1))
            out = eng.run(rows, palm=offset_transforms(deltas[start:stop]))
            outcome[start:stop], quality[start:stop] = out.outcome, out.quality
            if progress is not None:
                progress(stop, n)
    finally:
        eng.close()
    return outcome, quality


def close_batch(q: np.ndarray, object_name: str, covariances: np.ndarray, n: int, seed, *,
                engine: str = "fast", friction: float = 0.5, progress=None,
                robot: str = DEFAULT_ROBOT) -> PalmBatch:
    """A :class:`PalmBatch` of n closings of ``robot`` at configuration q (dof,), deltas
    drawn from the stratified mixture over ``covariances`` (K, 6, 6)
    (:class:`MixtureProposal`); ``seed`` an integer or a ``numpy.random.Generator``
    (:func:`batch_stream`)."""
    proposal = MixtureProposal.covering(covariances, n)
    deltas = proposal.sample(as_generator(seed))
    outcome, quality = close_deltas(q, deltas, object_name, engine=engine, friction=friction,
                                    robot=robot, progress=progress)
    return PalmBatch(np.asarray(q, dtype=float).copy(), deltas, proposal.logpdf(deltas),
                     outcome, quality)


#: The deviation's components, in the flange frame.
DELTA_NAMES = ("x", "y", "z", "rx", "ry", "rz")


@dataclass
class FragileDirections:
    """The palm directions in which a grasp loses force closure soonest.

    Under a reference distribution N(0, S) of delta (S = L L^T), with whitened deviations
    z = L^-1 delta, the failing draws' second moment M = E[z z^T | not force closure] is the
    identity where failure does not depend on the deviation; its eigenvectors with the largest
    eigenvalues are the directions along which the failures lie further out than the draws
    do: the fragile ones.

    Attributes:
        directions: (k, 6) unit vectors in the whitened space, most fragile first.
        spread: (k,) their eigenvalues (1: no more fragile than any direction).
        whitening: (6, 6) L.
    """

    directions: np.ndarray
    spread: np.ndarray
    whitening: np.ndarray

    def coordinates(self, deltas: np.ndarray) -> np.ndarray:
        """(n, k) deviations (n, 6) in the fragile directions (reference standard deviations)."""
        z = np.linalg.solve(self.whitening, np.atleast_2d(deltas).T).T
        return z @ self.directions.T

    def projected(self, covariance: np.ndarray) -> np.ndarray:
        """(k, k) a covariance (6, 6) of delta seen in the fragile directions."""
        inv = np.linalg.inv(self.whitening)
        return self.directions @ inv @ covariance @ inv.T @ self.directions.T

    def label(self, i: int) -> str:
        """Direction i in words: its largest components of delta, in reference s.d."""
        v = self.whitening @ self.directions[i]
        scale = np.sqrt(np.sum(self.whitening**2, axis=1))  # the reference s.d. per component
        share = (v / scale) ** 2
        share /= share.sum()
        top = np.argsort(-share)[:2]
        return " + ".join(f"{DELTA_NAMES[j]} {100 * share[j]:.0f}%" for j in top)


def fragile_directions(batch: PalmBatch, reference: np.ndarray, count: int = 2
                       ) -> FragileDirections:
    """The ``count`` most fragile directions of the batch's grasp under deltas ~ N(0,
    reference (6, 6)) (:class:`FragileDirections`).

    Raises:
        ValueError: no draw of the batch fails (nothing is fragile).
    """
    chol = np.linalg.cholesky(reference)
    w = normalised_weights(gaussian_logpdf(batch.deltas, reference), batch.log_proposal)
    w = w * ~batch.fc
    if w.sum() <= 0:
        raise ValueError("no draw of the batch loses force closure: no fragile direction")
    z = np.linalg.solve(chol, batch.deltas.T).T
    moment = (z * (w / w.sum())[:, None]).T @ z
    values, vectors = np.linalg.eigh(moment)
    order = np.argsort(values)[::-1][:count]
    return FragileDirections(vectors[:, order].T, values[order], chol)
