"""The most robust elbow from one batch of closings: P(FC) along the self-motion by weights.

:func:`~kinegrasp_env.toolkit.elbow_search.optimize_robot_elbow` closes fresh draws at every
angle. Here (:mod:`kinegrasp_env.montecarlo.palm_batch`) one batch of closings over the palm's
deviation answers every angle (any robot's:
:mod:`~kinegrasp_env.toolkit.elbow_reweight_search`), because the elbow angle psi changes only
the deviation's distribution, N(m(psi), J(psi) S_q J(psi)^T) (its covariance to first order,
its mean m to second):

1. **Curve** (the selection batch): every reachable angle of the fine grid re-weighted, with
   its standard error, effective sample size (ESS) and the slope dP/dpsi (the weights'
   derivative: the covariance's derivative along the self-motion, by central differences of
   the Jacobian at psi +- :data:`SLOPE_STEP`). An angle whose ESS falls below the draws asked
   for is topped up with direct draws for the shortfall, pooled with its weights' estimate,
   and marked so.
2. **Continuous optimum**: from the best grid angle, the zero of the slope between its
   neighbours (bisection on the slope's sign), so the choice is not tied to grid points.
3. **Scoring** (fresh direct draws): the chosen and the nominal angle on joint-noise draws the
   batch never saw, common to both: P(FC) with Wilson intervals, the paired gain with a
   t-interval. The re-weighted value at the chosen angle is checked against them (a
   disagreement beyond both sampling errors is reported: the linearisation does not hold).
4. **Certificate** (a second, fresh batch): for each evaluated rival, the re-weighted
   difference p_j - p_b on the fresh batch and its one-sided normal upper bound at level
   delta / 2 (the weights' delta-method standard error, halved level: a margin for the
   ratio estimators' finite-sample bias, measured), or, where an angle's rarer outcome
   weighs few effective draws (a batch that closed alike nearly every time), at least the
   difference of Clopper-Pearson bounds at the angles' effective sample sizes
   (:func:`rare_outcome_bound`); the claim "no evaluated angle beats the
   chosen one by more than B" fails only if the bound of the best true rival fails (the
   intersection-union argument of :mod:`~kinegrasp_env.toolkit.elbow_certificate`). Unlike
   the direct certificate's exact binomial bounds this one is asymptotic, and it bounds the
   Gaussian model's P(FC) (whose own bias is measured beside it): its coverage is measured
   in ``benchmarks/bench_reweight.py``.

The noise must be zero-mean Gaussian on the arm joints (a scalar or per-joint sigma, or a
covariance) and optionally on the palm (:func:`~kinegrasp_env.montecarlo.palm_batch.
gaussian_terms`); objects on a support table are refused (their arm links matter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.grasp_stats import Noise
from kinegrasp_env.montecarlo.palm_batch import (
    ARM,
    BATCH_FACTOR,
    PalmBatch,
    PalmJacobian,
    batch_stream,
    check_batch_object,
    gaussian_terms,
)
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.ik import ArmIK
from kinegrasp_env.sampling.reweight import (
    WeightedEstimate,
    gaussian_logpdf,
    normalised_weights,
)
from kinegrasp_env.sampling.stats import normal_quantile
from kinegrasp_env.toolkit.elbow import (
    FINE_STEP,
    ElbowPoint,
    ElbowResult,
    elbow_result,
)
from kinegrasp_env.toolkit.elbow_certificate import (
    Certificate,
    Rival,
    check_levels,
    clopper_pearson_lower,
    clopper_pearson_upper,
)
from kinegrasp_env.toolkit.reweight_evidence import CurvePoint, ReweightEvidence
from kinegrasp_env.world.grasps import Grasp

#: Half-step of the central difference of the covariance along psi (radians).
SLOPE_STEP = 1e-4
#: Bisection steps of the continuous optimum (the bracket shrinks 2^-steps).
BISECTION_STEPS = 10
#: The certificate's method, in words.
BATCH_METHOD = ("one-sided normal bounds at level delta/2 on each rival's re-weighted "
                "advantage (Clopper-Pearson ones at the effective sample sizes where an "
                "outcome is rare) under the Gaussian model of the palm's deviation, on a fresh "
                "batch")


class SelfMotionDeviation:
    """The palm deviation's Gaussian along one grasp's self-motion: its covariance (first
    order) and mean (second order: :meth:`~kinegrasp_env.montecarlo.palm_batch.PalmJacobian.
    mean`), and their derivatives along the elbow angle. A 6-joint arm has no self-motion:
    its configurations (IK branches) have their Gaussians, and no derivative joins them.

    Args:
        joints: the arm joints' noise (:func:`~kinegrasp_env.montecarlo.palm_batch.
            joint_covariance`: sigma, one sigma per arm joint or a covariance, radians).
        palm: (6, 6) covariance of a palm error added to the deviation (metres, radians).
        description: a description robot with a 7-joint arm with a self-motion, or a
            6-joint arm (default: the default robot).
    """

    def __init__(self, joints, palm: np.ndarray | None = None,
                 description: RobotDescription | None = None) -> None:
        self.jac = PalmJacobian(description)
        if description is None:
            self.ik = ArmIK(self.jac.kin)  # the palm held: the flange is rigid with it
        elif description.has_self_motion:
            from kinegrasp_env.robot.null_motion import ArmSelfMotion

            self.ik = ArmSelfMotion(description)
        else:
            self.ik = None  # IK branches: no motion between them
        self.joints = joints
        self.palm = np.zeros((6, 6)) if palm is None else np.asarray(palm, dtype=float)

    def gaussian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((n, 6, 6) covariance, (n, 6) mean) at configurations q (n, dof)
        (:meth:`~kinegrasp_env.montecarlo.palm_batch.PalmJacobian.gaussian`)."""
        return self.jac.gaussian(q, self.joints, self.palm)

    def at(self, q: np.ndarray) -> np.ndarray:
        """(n, 6, 6) covariance at configurations q (n, dof) (:meth:`gaussian`'s)."""
        return self.jac.deviation_covariance(q, self.joints, self.palm)

    def estimate(self, batch: PalmBatch, q: np.ndarray, psi: float | None = None
                 ) -> WeightedEstimate:
        """P(FC) of the batch at configuration q (14,); with ``psi`` (its elbow angle), its
        slope along psi too (NaN at a limit of the self-motion)."""
        moved = None if psi is None else self.derivative(q, psi)
        cov, mean = self.gaussian(q[None])
        return batch.estimate(cov[0], None if moved is None else moved[0], mean=mean[0],
                              mean_derivative=None if moved is None else moved[1]).p_fc

    def configuration(self, q: np.ndarray, psi: float) -> np.ndarray | None:
        """(dof,) q moved to elbow angle psi (radians), None where the path fails or the
        arm has no self-motion."""
        if self.ik is None:
            return None
        moved, ok = self.ik.set_elbow_angle(q, psi)
        return np.reshape(moved, -1) if np.all(ok) else None

    def derivative(self, q: np.ndarray, psi: float
                   ) -> tuple[np.ndarray, np.ndarray] | None:
        """((6, 6) d covariance / d psi, (6,) d mean / d psi) at configuration q (14,) of
        angle psi, by central differences; None at a limit of the self-motion."""
        plus = self.configuration(q, psi + SLOPE_STEP)
        minus = self.configuration(q, psi - SLOPE_STEP)
        if plus is None or minus is None:
            return None
        both = np.stack([plus, minus])
        cov, mean = self.gaussian(both)
        return (cov[0] - cov[1]) / (2 * SLOPE_STEP), (mean[0] - mean[1]) / (2 * SLOPE_STEP)


def batch_curve(reach: list[tuple[float, np.ndarray]], batch: PalmBatch,
                motion: SelfMotionDeviation, samples: int, direct) -> list[CurvePoint]:
    """Every reachable angle re-weighted; where the ESS falls short of ``samples``, topped up
    with direct draws (:func:`topped_up`; ``direct(psi, q, n)``: the angle's
    :class:`ElbowPoint` on n selection draws)."""
    out = []
    for psi, q in reach:
        est = motion.estimate(batch, q, psi)
        if not est.ess >= samples:  # a NaN effective sample size is topped up too
            out.append(topped_up(est, direct, psi, q, samples))
            continue
        point = ElbowPoint(psi, q, est.value, est.interval, np.zeros(0, bool))
        out.append(CurvePoint(point, est.se, est.ess, est.derivative, est.derivative_se,
                              False))
    return out


def topped_up(est: WeightedEstimate, direct, psi: float, q: np.ndarray, samples: int
              ) -> CurvePoint:
    """An angle whose weights are worth ``est.ess`` < ``samples`` draws: n = ``samples`` -
    floor(ESS) direct draws (``direct(psi, q, n)``), pooled with the weights' estimate in
    proportion to the ESS and n (two independent estimates of P(FC): the pool's standard
    error is theirs combined, its interval normal, clipped to [0, 1])."""
    ess = est.ess if math.isfinite(est.ess) and est.ess > 0 else 0.0
    n = samples - math.floor(ess)
    point = direct(psi, q, n)
    value = (ess * (est.value if ess else 0.0) + n * point.p_fc) / (ess + n)
    se = math.hypot(ess * (est.se if ess else 0.0),
                    math.sqrt(n * max(value * (1.0 - value), 0.0))) / (ess + n)
    z = normal_quantile(0.95)
    pooled = ElbowPoint(psi, q, value, (max(0.0, value - z * se), min(1.0, value + z * se)),
                        point.fc, point.outcome)
    return CurvePoint(pooled, se, ess, est.derivative, est.derivative_se, True)


def continuous_optimum(curve: list[CurvePoint], batch: PalmBatch,
                       motion: SelfMotionDeviation, step: float = FINE_STEP
                       ) -> tuple[float, np.ndarray, float]:
    """(psi, q (14,), P) of the batch's best angle: the best grid angle, moved to the zero
    of the slope between it and a neighbour one grid ``step`` (radians) away where the slope
    changes sign there."""
    usable = [c for c in curve if not c.fallback]
    if not usable:
        best = max(curve, key=lambda c: c.point.p_fc)
        return best.point.psi, best.point.q, best.point.p_fc
    best = max(usable, key=lambda c: c.point.p_fc)
    i = curve.index(best)
    psi, q, value = best.point.psi, best.point.q, best.point.p_fc
    lo = curve[i - 1] if i > 0 else None
    hi = curve[i + 1] if i + 1 < len(curve) else None
    # bracket [a, b] with slope > 0 at a and < 0 at b, between neighbours one grid step
    # apart (both reachable and clear of the object: the path between them is taken as clear)
    def adjacent(u: CurvePoint, v: CurvePoint) -> bool:
        return not (u.fallback or v.fallback) and abs(v.point.psi - u.point.psi) <= 1.01 * step

    if hi is not None and adjacent(best, hi) and best.slope > 0 > hi.slope:
        a, b = best, hi
    elif lo is not None and adjacent(lo, best) and lo.slope > 0 > best.slope:
        a, b = lo, best
    else:
        return psi, q, value
    pa, pb, qa = a.point.psi, b.point.psi, a.point.q
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (pa + pb)
        qm = motion.configuration(qa, mid)
        if qm is None:
            break
        if motion.estimate(batch, qm, mid).derivative > 0:
            pa, qa = mid, qm
        else:
            pb = mid
    mid = 0.5 * (pa + pb)
    qm = motion.configuration(qa, mid)
    if qm is None:
        return psi, q, value
    found = motion.estimate(batch, qm).value
    return (mid, qm, found) if found >= value else (psi, q, value)


#: The normal bound of a difference stands alone where each angle's rarer outcome weighs at
#: least this many effective draws (a textbook condition for the normal approximation of a
#: binomial count).
MIN_RARE_DRAWS = 10.0


def rare_outcome_bound(p_best: float, w_best: np.ndarray, p: float, w: np.ndarray,
                       delta: float) -> float:
    """A bound on p - p_best (a rival's P(FC) less the chosen angle's, weights w and w_best
    (n,)) that holds where the normal one may not: where either angle's rarer outcome weighs
    fewer than :data:`MIN_RARE_DRAWS` effective draws (its ESS 1 / sum(w^2) times p or
    1 - p), the batch may have missed where it happens, and the bound is the rival's
    Clopper-Pearson upper bound less the chosen angle's lower one, each at its ESS and level
    ``delta`` / 4 (the difference at ``delta`` / 2, the normal bound's level); -inf where no
    outcome is rare. The larger of this and the normal bound is false only when both are: a
    batch whose every closing ended alike gave a normal bound of 0 (no weighted variance),
    whatever the truth."""
    ess_best, ess = 1.0 / float(np.sum(w_best**2)), 1.0 / float(np.sum(w**2))
    rarest = min(ess_best * min(p_best, 1.0 - p_best), ess * min(p, 1.0 - p))
    if rarest >= MIN_RARE_DRAWS:
        return -math.inf
    return float(clopper_pearson_upper(p * ess, ess, delta / 4)
                 - clopper_pearson_lower(p_best * ess_best, ess_best, delta / 4))


def batch_certificate(chosen: tuple[float, np.ndarray], rivals: list[tuple[float, np.ndarray]],
                      fresh: PalmBatch, motion: SelfMotionDeviation, epsilon: float,
                      delta: float) -> Certificate:
    """The certificate of the chosen angle from a fresh batch (module docstring, step 4)."""
    # one-sided at level delta / 2: at delta itself the normal bound of two near angles
    # (strongly correlated weights, a difference of a few standard errors) can be false more
    # often than delta (the ratio estimators' finite-sample bias and skew); how often each
    # is false on a field with a known truth: benchmarks/bench_reweight.py's "certificate"
    z = normal_quantile(1.0 - delta)
    qs = np.stack([chosen[1]] + [q for _, q in rivals])
    weights = [normalised_weights(gaussian_logpdf(fresh.deltas, c, m), fresh.log_proposal)
               for c, m in zip(*motion.gaussian(qs), strict=True)]
    f = fresh.fc.astype(float)
    p_best = float(weights[0] @ f)
    out = []
    for (psi, _), w in zip(rivals, weights[1:], strict=True):
        p = float(w @ f)
        influence = w * (f - p) - weights[0] * (f - p_best)
        se = float(np.sqrt(np.sum(influence**2)))
        diff = p - p_best
        upper = max(diff + z * se, rare_outcome_bound(p_best, weights[0], p, w, delta))
        out.append(Rival(float(psi), p, None, None, diff, upper))
    if not out:
        return Certificate(float(chosen[0]), epsilon, delta, len(fresh), [], None, None, True,
                           method=BATCH_METHOD)
    worst = max(out, key=lambda r: r.upper)
    return Certificate(float(chosen[0]), epsilon, delta, len(fresh), out, worst.upper,
                       worst.psi, worst.upper <= epsilon, method=BATCH_METHOD)


def check_reweight(grasp: Grasp, noise, samples: int, epsilon: float, delta: float,
                   batch: int | None, dof: int = ARM) -> None:
    """Every input of a re-weighted search (:func:`~kinegrasp_env.toolkit.
    elbow_reweight_search.optimize_robot_elbow_reweighted`) that can be refused before any
    closing: the levels, the noise (:func:`~kinegrasp_env.montecarlo.palm_batch.
    gaussian_terms`, for an arm of ``dof`` joints), the object (no support table) and the
    batch (at least ``samples``: a smaller one sends every angle to direct draws).
    ValueError naming the bad one."""
    check_levels(epsilon, delta)
    gaussian_terms(noise, dof)
    check_batch_object(grasp.object)
    if batch is not None and batch < samples:
        raise ValueError(f"a batch of {batch} closings cannot stand for {samples} direct "
                         f"draws per angle: give a batch of at least as many (--batch >= "
                         f"--samples)")


@dataclass(frozen=True)
class ReweightRobot:
    """What the re-weighted search needs of a robot (a 7-joint arm's self-motion, a 6-joint
    arm's IK branches): the deviation's
    covariance at each configuration, the reachable ones, one batch of closings, and direct
    draws at one.

    Attributes:
        reach: (psi, q) along the grasp's self-motion, sorted by psi (the grasp's own q0
            included).
        nominal: the index of the grasp's own configuration in ``reach``.
        motion: the deviation's Gaussian along the self-motion.
        close: ``close(covariances (K, 6, 6), n, stream) ->`` :class:`PalmBatch` at the
            grasp's palm pose.
        direct: ``direct(psi, q, n) ->`` :class:`ElbowPoint` on n selection draws.
        fresh: ``fresh(q) ->`` (samples,) force closure on draws the selection never saw.
        engine: the engine's name.
    """

    reach: list
    nominal: int
    motion: SelfMotionDeviation
    close: object
    direct: object
    fresh: object
    engine: str


def reweighted_search(grasp: Grasp, noise: Noise, samples: int, seed: int,
                      robot: ReweightRobot, *, step: float, epsilon: float, delta: float,
                      batch: int | None, progress=None
                      ) -> tuple[ElbowResult, ReweightEvidence]:
    """The module's four steps for ``robot`` (:class:`ReweightRobot`; the inputs checked)."""
    report = progress or (lambda stage: None)
    n = int(batch or BATCH_FACTOR * samples)
    reach, motion = robot.reach, robot.motion
    covs = motion.at(np.stack([q for _, q in reach]))
    report("batch")
    selection = robot.close(covs, n, batch_stream(seed, 0))
    curve = batch_curve(reach, selection, motion, samples, robot.direct)
    psi, q, estimate = continuous_optimum(curve, selection, motion, step)
    report("fresh draws")
    nominal_psi, nominal_q = reach[robot.nominal]
    points = [c.point for c in curve]
    best = next((p for p in points if abs(p.psi - psi) < 1e-12), None)
    if best is None:  # between grid points: the continuous optimum joins the curve
        z = normal_quantile(0.95)
        se = motion.estimate(selection, q).se
        best = ElbowPoint(psi, q, estimate, (max(0.0, estimate - z * se),
                                             min(1.0, estimate + z * se)), np.zeros(0, bool))
        points = sorted([*points, best], key=lambda p: p.psi)
    nominal = next(p for p in points if p.q is nominal_q)
    best.fresh_fc = robot.fresh(q)
    nominal.fresh_fc = best.fresh_fc if nominal is best else robot.fresh(nominal_q)
    report("certificate")
    fresh = robot.close(covs, n, batch_stream(seed, 1))
    rivals = [(c.point.psi, c.point.q) for c in curve if abs(c.point.psi - psi) > 1e-9]
    certificate = batch_certificate((psi, q), rivals, fresh, motion, epsilon, delta)
    result = elbow_result(grasp, points, best, nominal, nominal_psi, noise,
                          samples, seed, robot.engine, step, epsilon, delta,
                          certificate=certificate)
    # the chosen angle's estimate against its fresh draws: both errors (the re-weighted
    # one's at that angle; the choice of the largest of many estimates biases it up, so a
    # disagreement is a hint, not a proof, that the linearisation fails there)
    p_fresh = float(best.fresh_fc.mean())
    se = math.hypot(math.sqrt(max(p_fresh * (1 - p_fresh), 1e-12) / samples),
                    motion.estimate(selection, q).se)
    agrees = abs(estimate - p_fresh) <= normal_quantile(0.95) * se
    return result, ReweightEvidence(n, curve, estimate, agrees, selection,
                                    motion.at(nominal_q[None])[0], motion.at(q[None])[0])
