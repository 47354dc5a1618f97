"""Re-weighted P(FC) against direct draws: calibration, the Gaussian model's bias, timings.

For grasps of the default robot (``--grasps`` per object, the first ones of each shipped
set, fixed before any run), at ``--angles`` elbow angles spread over each grasp's reachable
self-motion and the paper's four noise levels:

* **calibration**: ``--replicates`` independent batches of ``--batch`` closings over the
  palm's deviation (each a mixture over all angle x sigma targets), each re-weighted to every
  case, against a direct evaluation of ``--direct`` joint-noise draws per case (each case its
  own draws): a judgement agrees when the difference lies within the 95% interval of both
  sampling errors (the re-weighted one's from its weights' effective sample size, the direct
  one's binomial). One batch serves all of a grasp's cases, so its error is shared by them
  all: the replicates turn a grasp's 72 correlated judgements into five independent sets, and
  their spread checks the weights' standard error directly;
* **the Gaussian model's bias**: ``--direct`` deltas drawn from the model N(m, J S_q J^T)
  (first-order covariance, second-order mean: what the weights target; the JSON's
  ``linear``) per case, closed directly, against the direct joint-noise draws (what the
  model gets wrong, sampling error aside: its interval is printed with it, and
  the mean over a grasp's angles with a t-interval, the cases' draws being independent);
* **timings** (warm, alone on the machine): ``elbow`` by both methods at ``--samples`` draws per
  angle; Table I's four noise levels at the nominal configuration from one batch against
  four direct runs of ``--levels-samples`` draws, with each method's standard errors beside,
  and the least closings one batch with direct top-ups needs for the direct runs' accuracy
  (:func:`levels_floor`: known from the weights alone, before any closing);
  fig10's ``--variants`` arm configurations of each object's first grasp on the reference
  engine (``reproduce fig10 --method reweight``) against a run per configuration.

Writes ``benchmarks/results/bench_reweight.json`` and the table in docs/guides/elbow.md.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from marked_section import write_between
from results_file import add_options, plain, publish, settings

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import GraspEvaluation, evaluate_grasp
from kinegrasp_env.montecarlo.palm_batch import (
    PalmJacobian,
    close_batch,
    close_deltas,
    linear_draws,
)
from kinegrasp_env.robot.endeffector import PAPER_SIGMAS
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.reweight import MixtureProposal, gaussian_logpdf, weighted_estimate
from kinegrasp_env.sampling.stats import Z95
from kinegrasp_env.toolkit.elbow import reachable_configurations, with_configuration
from kinegrasp_env.toolkit.elbow_reweight_search import optimize_robot_elbow_reweighted
from kinegrasp_env.toolkit.elbow_search import optimize_robot_elbow
from kinegrasp_env.world.grasps import shipped_grasps

DOC = Path(__file__).resolve().parents[1] / "docs" / "guides" / "elbow.md"
START, END = "<!-- reweight-calibration:start -->", "<!-- reweight-calibration:end -->"


#: The options that the calibration's figures depend on.
CALIBRATION_SETTINGS = ("objects", "grasps", "angles", "sigmas", "batch", "direct",
                        "replicates")


def evaluate_fast(grasp, noise: JointNoise | NoiseModel, n: int,
                  seed: int) -> GraspEvaluation:
    """``evaluate_grasp`` on the fast engine under joint noise or a noise model."""
    if isinstance(noise, NoiseModel):
        return evaluate_grasp(grasp, noise_model=noise, n=n, seed=seed,
                              engine="fast")
    return evaluate_grasp(grasp, sigma=noise.sigma, noise=noise.kind, n=n, seed=seed,
                          engine="fast")


def binomial_se(p: float, n: int) -> float:
    return math.sqrt(max(p * (1 - p), 0.0) / n)


def spread_angles(reach: list, count: int) -> list:
    """``count`` configurations evenly spread over the reachable self-motion (all if fewer)."""
    idx = np.unique(np.linspace(0, len(reach) - 1, count).round().astype(int))
    return [reach[i] for i in idx]


def pooled_half_width(p: float, ess: float, q: float, n: int) -> float:
    """The 95% half-width of the difference of two proportions, p worth ``ess`` draws and q
    of n, with the pooled proportion's variance (the two-proportion test's: it stays honest
    where one estimate is 0 or 1)."""
    pooled = (p * ess + q * n) / (ess + n)
    return Z95 * math.sqrt(max(pooled * (1 - pooled), 0.0) * (1 / ess + 1 / n))


def judged(case: dict, n: int) -> dict:
    """The case with its verdicts. ``agrees``: the difference within
    :func:`pooled_half_width` of the effective sample size and the n direct draws.
    ``agrees_delta``: within the interval of the weights' delta-method standard error and
    the binomial one (which understates the error of a rare outcome seen in few draws). The
    Gaussian model's bias: its 95% interval from both binomial errors."""
    p_rw, p_d, ess = case["reweighted"], case["direct"], case["ess"]
    half = pooled_half_width(p_rw, ess, p_d, n)
    half_delta = Z95 * math.hypot(case["reweighted_se"], binomial_se(p_d, n))
    diff = p_rw - p_d
    p_l = case["linear"]
    first = {}
    if "first_order" in case:  # the first-order model's estimate, judged alike
        p_f = case["first_order"]
        first = {"first_order_agrees": abs(p_f - p_d)
                 <= pooled_half_width(p_f, case["first_order_ess"], p_d, n)}
    return {**case, **first, "weights_difference": p_rw - p_l,
            "agrees_with_linear": abs(p_rw - p_l) <= pooled_half_width(p_rw, ess, p_l, n),
            "difference": diff, "half_width": half, "agrees": abs(diff) <= half,
            "half_width_delta": half_delta, "agrees_delta": abs(diff) <= half_delta,
            "linear_bias": case["linear"] - p_d,
            "linear_bias_half_width": Z95 * math.hypot(binomial_se(case["linear"], n),
                                                       binomial_se(p_d, n))}


def case_seeds(seed: int) -> dict:
    """The random streams of one grasp's calibration run with ``seed``: ``direct(k)`` and
    ``linear(k)`` the seeds of case k's direct and model draws (each case its own,
    so that the cases' sampling errors are independent), ``batch(r)`` replicate r's batch."""
    base = 1000 * seed
    return {"direct": lambda k: base + 1 + k, "linear": lambda k: base + 500 + k,
            "batch": lambda r: base + 900 + r}


def calibration(grasp, args, seed: int) -> list[dict]:
    """One record per (angle, sigma) case and batch replicate of one grasp."""
    angles = spread_angles(reachable_configurations(grasp), args.angles)
    jac = PalmJacobian()
    qs = np.stack([q for _, q in angles])
    covs = np.concatenate([jac.covariance(qs, s) for s in args.sigmas])
    means = np.concatenate([jac.mean(qs, s) for s in args.sigmas])
    seeds = case_seeds(seed)
    batches = [close_batch(angles[0][1], grasp.object, covs, args.batch, seeds["batch"](r))
               for r in range(args.replicates)]

    def direct(psi, q, sigma, k) -> float:
        return evaluate_fast(with_configuration(grasp, q, psi), JointNoise(sigma),
                             args.direct, seeds["direct"](k)).p_fc

    def linear(q, cov, mean, k) -> np.ndarray:
        return close_deltas(q, linear_draws(cov, args.direct, seeds["linear"](k), mean),
                            grasp.object)[0]

    return judged_cases({"object": grasp.object, "grasp": int(grasp.id)}, angles, covs,
                        means, batches, direct, linear, args)


def judged_cases(record: dict, angles: list, covs: np.ndarray, means: np.ndarray,
                 batches: list, direct, linear, args) -> list[dict]:
    """One judged record per (sigma, angle) case of one grasp and batch replicate
    (``record``: its fields): each batch of ``batches`` re-weighted to each case's Gaussian
    (``covs`` and ``means``, sigma-major; beside it, the first-order model's: the same
    covariance, mean 0), ``direct(psi, q, sigma, k)`` case k's direct P(FC),
    ``linear(q, cov, mean, k)`` the outcomes of its model deltas (both drawn once per case,
    shared by the replicates)."""
    cases, k = [], 0
    for sigma in args.sigmas:
        for psi, q in angles:
            common = {**record, "psi": psi, "sigma": sigma, "direct": direct(psi, q, sigma, k),
                      "linear": float(np.mean(linear(q, covs[k], means[k], k)
                                              == FORCE_CLOSURE))}
            for r, batch in enumerate(batches):
                est = batch.estimate(covs[k], mean=means[k]).p_fc
                first = batch.estimate(covs[k]).p_fc
                cases.append(judged({**common, "replicate": r, "reweighted": est.value,
                                     "reweighted_se": est.se, "ess": est.ess,
                                     "first_order": first.value,
                                     "first_order_ess": first.ess}, args.direct))
            k += 1
        recent = cases[-len(angles) * len(batches):]
        print(f"  {record['object']} grasp {record['grasp']} sigma {sigma:g}: "
              f"{sum(c['agrees'] for c in recent)}/{len(recent)} agree "
              f"({sum(c['first_order_agrees'] for c in recent)} at first order)",
              file=sys.stderr)
    return cases


def elbow_timing(grasp, args) -> dict:
    """Both elbow methods on one grasp, warm, at 0.0133 rad."""
    noise = JointNoise(0.0133)
    reach = reachable_configurations(grasp)
    t0 = time.perf_counter()
    direct = optimize_robot_elbow(grasp, noise, args.samples, 0, reach=reach)
    t1 = time.perf_counter()
    batch, evidence = optimize_robot_elbow_reweighted(grasp, noise, args.samples, 0,
                                                      reach=reach)
    t2 = time.perf_counter()
    return {"object": grasp.object, "grasp": int(grasp.id), "direct_s": t1 - t0,
            "reweight_s": t2 - t1, "ratio": (t2 - t1) / (t1 - t0),
            "direct_angles": len(direct.curve), "reweight_angles": len(batch.curve),
            "direct_best_psi": direct.best_psi, "reweight_best_psi": batch.best_psi,
            "direct_best_fresh": direct.best_p_fc, "reweight_best_fresh": batch.best_p_fc,
            "min_ess": min(c.ess for c in evidence.curve),
            "fallback_angles": sum(c.fallback for c in evidence.curve),
            "reweight_certified": batch.certificate.certified,
            "direct_certified": direct.certificate.certified}


def levels_timing(grasp, args) -> dict:
    """Table I's noise levels at the nominal configuration: one batch against direct runs."""
    q = np.asarray(grasp.q0, dtype=float)
    covs = np.concatenate([PalmJacobian().covariance(q, s) for s in args.sigmas])
    t0 = time.perf_counter()
    direct = [evaluate_fast(grasp, JointNoise(s), args.levels_samples, 0)
              for s in args.sigmas]
    t1 = time.perf_counter()
    batch = close_batch(q, grasp.object, covs, args.levels_batch, 0)
    est = [batch.estimate(c).p_fc for c in covs]
    t2 = time.perf_counter()
    return {"object": grasp.object, "grasp": int(grasp.id), "direct_s": t1 - t0,
            "reweight_s": t2 - t1, "ratio": (t2 - t1) / (t1 - t0),
            "direct_se": [binomial_se(d.p_fc, args.levels_samples) for d in direct],
            "reweight_se": [e.se for e in est], "ess": [e.ess for e in est],
            "direct_p_fc": [d.p_fc for d in direct], "reweight_p_fc": [e.value for e in est]}


def levels_floor(sigmas: list[float], samples: int, n: int = 20000, seed: int = 0) -> dict:
    """What one batch can give Table I's noise levels at the direct runs' accuracy, known
    before any closing (the weights need no outcome): each level's effective sample size
    as a share of a batch drawn from the stratified mixture of the levels' Gaussians, and
    the least closings (the batch, plus direct draws topping each level up to ``samples``
    effective ones) over four direct runs of ``samples``. The levels' covariances are
    sigma^2 multiples of one matrix, so the shares are those of the sigma ladder in six
    dimensions, the same for every grasp (the spray flask's grasp 0 stands for all)."""
    q = np.asarray(shipped_grasps("spray_flask")[0].q0, dtype=float)
    covs = np.concatenate([PalmJacobian().covariance(q, s) for s in sigmas])
    proposal = MixtureProposal.covering(covs, n)
    deltas = proposal.sample(np.random.default_rng(seed))
    log_proposal = proposal.logpdf(deltas)
    shares = np.array([weighted_estimate(np.zeros(n), gaussian_logpdf(deltas, c),
                                         log_proposal).ess / n for c in covs])
    sizes = np.arange(0, math.ceil(samples / shares.min()) + 1, max(samples // 200, 1))
    cost = sizes + np.maximum(samples - np.outer(sizes, shares), 0.0).sum(axis=1)
    best = int(np.argmin(cost))
    return {"ess_shares": shares.tolist(), "least_batch": int(sizes[best]),
            "least_closings": float(cost[best]),
            "least_ratio": float(cost[best] / (len(sigmas) * samples))}


def variants_timing(obj: str, args) -> dict:
    """fig10's arm configurations of one object's first grasp (:func:`~kinegrasp_env.toolkit.
    arm_variants.find_variants`): one batch against one run per configuration, on the
    reference engine (``reproduce``'s protocol with ``--engine pybullet``)."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit.arm_variants import find_variants
    from kinegrasp_env.toolkit.batch_stats import variant_stats

    robot = load_robot("kuka_sdh")
    grasps = find_variants(robot, obj, shipped_grasps(obj)[0], args.variants)

    def run(g):
        return evaluate_grasp(g, sigma=0.0033, n=args.samples, seed=0, engine="pybullet")

    t0 = time.perf_counter()
    direct = [run(g) for g in grasps]
    t1 = time.perf_counter()
    batch = variant_stats(grasps, 0.0033, args.samples, 0, engine="pybullet", robot=robot,
                          direct=run)
    t2 = time.perf_counter()
    return {"object": obj, "variants": len(grasps), "direct_s": t1 - t0,
            "reweight_s": t2 - t1, "ratio": (t2 - t1) / (t1 - t0),
            "direct_p_fc": [d.p_fc for d in direct], "reweight_p_fc": [b.p_fc for b in batch],
            "effective_samples": [getattr(b, "samples", args.samples) for b in batch]}


def env_timing(args) -> dict:
    """KineGrasp-v0 steps per second with the draws' reward and with the batch reward on the
    spray flask's grasps (the batches built in a first pass of ``--env-episodes`` episodes,
    then as many timed), and each reward's error against 4,000 direct draws at 16 states."""
    from kinegrasp_env.envs.kinegrasp import KineGraspEnv

    def episodes(env, first: int, rng, check: bool = False) -> tuple[int, list[float]]:
        steps, errors = 0, []
        for ep in range(args.env_episodes if not check else 8):
            env.reset(seed=first + ep)
            for _ in range(10 if not check else 2):
                _, _, _, _, info = env.step(np.array([rng.uniform(-1, 1), -1.0], np.float32))
                steps += 1
                if check:
                    direct = evaluate_fast(with_configuration(env.grasp, env.q, 0.0),
                                           env.noise, 4000, 9)
                    errors.append(info["p_fc"] - direct.p_fc)
        return steps, errors

    out = {}
    for reward in ("draws", "batch"):
        env = KineGraspEnv(objects=("spray_flask",), reward=reward)
        episodes(env, 0, np.random.default_rng(0))  # builds the batches
        start = time.perf_counter()
        steps, _ = episodes(env, 10**5, np.random.default_rng(1))
        elapsed = time.perf_counter() - start
        _, errors = episodes(env, 2 * 10**5, np.random.default_rng(2), check=True)
        out[reward] = {"steps_per_s": steps / elapsed,
                       "p_fc_rms_error": float(np.sqrt(np.mean(np.square(errors))))}
    out["ratio"] = out["batch"]["steps_per_s"] / out["draws"]["steps_per_s"]
    print(f"env: draws {out['draws']['steps_per_s']:.0f} steps/s, batch "
          f"{out['batch']['steps_per_s']:.0f} steps/s ({out['ratio']:.1f}x); P(FC) rms error "
          f"against 4,000 draws {out['draws']['p_fc_rms_error']:.4f} / "
          f"{out['batch']['p_fc_rms_error']:.4f}", file=sys.stderr)
    return out


def certificate_coverage(args) -> list[dict]:
    """How often the batch certificate's statement is false on a field with a known truth:
    force closure where u . delta < c (u the deviation's component whose spread changes most
    along spray flask grasp 4's self-motion, c 0.6 of its median spread), whose P(FC) at
    every angle is Phi((c - u . m(psi)) / sqrt(u^T S(psi) u)) under the model N(m, S); the
    angle chosen on one batch, the certificate from another, ``--coverage-runs`` runs per
    batch size. The statement is false
    when a rival's true P(FC) beats the chosen one's by more than the bound. The same bounds
    at level delta each (batch_certificate at 2 delta) are counted beside, judged at delta."""
    from scipy import stats as sps

    from kinegrasp_env.montecarlo.draws import NO_FORCE_CLOSURE
    from kinegrasp_env.montecarlo.palm_batch import PalmBatch
    from kinegrasp_env.sampling.reweight import MixtureProposal, gaussian_logpdf
    from kinegrasp_env.toolkit.elbow_reweight import SelfMotionDeviation, batch_certificate

    grasp = shipped_grasps("spray_flask")[4]
    reach = reachable_configurations(grasp)[::3]
    motion = SelfMotionDeviation(0.0233)
    covs, means = motion.gaussian(np.stack([q for _, q in reach]))
    spread = np.array([np.diag(c) for c in covs])
    u = np.zeros(6)
    u[int(np.argmax(spread.max(axis=0) / spread.min(axis=0)))] = 1.0
    c = 0.6 * float(np.sqrt(np.median(spread @ u)))
    truth = np.array([sps.norm.cdf((c - u @ m) / np.sqrt(u @ s @ u))
                      for s, m in zip(covs, means, strict=True)])

    def batch(n: int, seed: int) -> PalmBatch:
        proposal = MixtureProposal.covering(covs, n)
        deltas = proposal.sample(np.random.default_rng(seed))
        outcome = np.where(deltas @ u < c, FORCE_CLOSURE, NO_FORCE_CLOSURE).astype(np.int8)
        return PalmBatch(np.zeros(14), deltas, proposal.logpdf(deltas), outcome, np.zeros(n))

    out = []
    for n in args.coverage_batches:
        false = {0.05: 0, 0.1: 0}
        for run in range(args.coverage_runs):
            selection = batch(n, 10**6 + 2 * run)
            values = [float(np.exp(gaussian_logpdf(selection.deltas, s, m)
                                   - selection.log_proposal) @ selection.fc)
                      for s, m in zip(covs, means, strict=True)]
            b = int(np.argmax(values))
            rivals = [reach[j] for j in range(len(reach)) if j != b]
            gap = max(truth[j] - truth[b] for j in range(len(reach)) if j != b)
            fresh = batch(n, 10**6 + 2 * run + 1)
            for level in false:
                cert = batch_certificate(reach[b], rivals, fresh, motion, 0.05, level)
                false[level] += gap > cert.bound
        out.append({"batch": n, "runs": args.coverage_runs, "delta": 0.05,
                    "false_at_half_delta_bounds": false[0.05],
                    "false_at_delta_bounds": false[0.1]})
        print(f"certificate, batches of {n}: false {false[0.05]}/{args.coverage_runs} "
              f"(bounds at delta/2, as used), {false[0.1]}/{args.coverage_runs} (bounds at "
              f"delta)", file=sys.stderr)
    return out


def case_key(case: dict) -> tuple:
    return (case.get("robot"), case["object"], case["grasp"], case["sigma"], case["psi"])


def bias_groups(cases: list[dict]) -> list[dict]:
    """Per (object, grasp, sigma): the Gaussian model's mean bias over the angles with its
    95% t-interval (the cases' draws independent, so their errors are too)."""
    from scipy import stats as sps

    groups: dict = {}
    for c in cases:
        groups.setdefault(case_key(c)[:4], []).append(c["linear_bias"])
    out = []
    for (robot, obj, grasp, sigma), bias in groups.items():
        b = np.asarray(bias)
        half = (float(sps.t.ppf(0.975, len(b) - 1) * b.std(ddof=1) / math.sqrt(len(b)))
                if len(b) > 1 else math.inf)
        out.append({"robot": robot, "object": obj, "grasp": grasp, "sigma": sigma,
                    "mean": float(b.mean()), "half_width": half})
    return out


def batch_spread(cases: list[dict]) -> float:
    """sqrt(mean over cases of the replicates' variance / mean squared standard error): 1
    where the weights' standard error is right, NaN with one replicate."""
    groups: dict = {}
    for c in cases:
        groups.setdefault(case_key(c), []).append((c["reweighted"], c["reweighted_se"]))
    groups = {k: np.asarray(v) for k, v in groups.items() if len(v) > 1}
    if not groups:
        return math.nan
    var = np.mean([v[:, 0].var(ddof=1) for v in groups.values()])
    return float(math.sqrt(var / np.mean([np.mean(v[:, 1] ** 2) for v in groups.values()])))


def replicate_interval(cases: list[dict], replicates: list[int]) -> list[float] | None:
    """The 95% t-interval of the share of agreeing judgements over the batch replicates
    (each replicate's share one observation: its judgements share a batch), None with one."""
    from scipy import stats as sps

    if len(replicates) < 2:
        return None
    shares = np.array([np.mean([c["agrees"] for c in cases if c.get("replicate", 0) == r])
                       for r in replicates])
    half = float(sps.t.ppf(0.975, len(shares) - 1) * shares.std(ddof=1)
                 / math.sqrt(len(shares)))
    return [float(shares.mean() - half), float(shares.mean() + half)]


def summary(cases: list[dict], elbows: list[dict], levels: list[dict],
            variants: list[dict] | None = None) -> dict:
    """The figures of the calibration (every replicate's judgements; the Gaussian model's
    bias once per case) and the timings."""
    replicates = sorted({c.get("replicate", 0) for c in cases})
    first = [c for c in cases if c.get("replicate", 0) == replicates[0]]
    agree = sum(c["agrees"] for c in cases)
    # each difference in units of its standard error (N(0, 1) if both errors are right)
    z = np.array([c["difference"] / (c["half_width"] / Z95) for c in cases
                  if c["half_width"] > 0])
    bias = np.array([c["linear_bias"] for c in first])
    beyond = [c for c in first if abs(c["linear_bias"]) > 0.01
              and abs(c["linear_bias"]) - c["linear_bias_half_width"] > 0.01]
    groups = bias_groups(first)
    worst = max(groups, key=lambda g: abs(g["mean"]))
    return {"cases": len(first), "replicates": len(replicates), "judgements": len(cases),
            "agree": agree, "agree_share": agree / len(cases),
            "agree_by_replicate": [float(np.mean([c["agrees"] for c in cases
                                                  if c.get("replicate", 0) == r]))
                                   for r in replicates],
            "agree_share_interval": replicate_interval(cases, replicates),
            "agree_delta": sum(c["agrees_delta"] for c in cases),
            "agree_first_order": sum(c.get("first_order_agrees", False) for c in cases),
            "agree_with_linear": sum(c["agrees_with_linear"] for c in cases),
            "z_mean": float(np.mean(z)), "z_sd": float(np.std(z, ddof=1)),
            "batch_spread_over_se": batch_spread(cases),
            "max_abs_linear_bias": float(np.abs(bias).max()),
            "mean_abs_linear_bias": float(np.abs(bias).mean()),
            "linear_bias_surely_above_0.01": len(beyond),
            "bias_groups": groups,
            "largest_group_bias": worst["mean"],
            "largest_group_bias_half_width": worst["half_width"],
            "groups_bias_surely_above_0.01": sum(abs(g["mean"]) - g["half_width"] > 0.01
                                                 for g in groups),
            "min_ess": float(min(c["ess"] for c in cases)),
            "elbow_ratio_mean": (float(np.mean([e["ratio"] for e in elbows]))
                                 if elbows else None),
            "levels_ratio_mean": (float(np.mean([v["ratio"] for v in levels]))
                                  if levels else None),
            "variants_ratio_mean": (float(np.mean([v["ratio"] for v in variants]))
                                    if variants else None)}


def calibration_rows(result: dict) -> list[str]:
    """The Markdown rows of the calibration figures (both calibration scripts)."""
    s, run = result["summary"], result["settings"]
    n = run["direct"]
    shares = ", ".join(f"{100 * a:.1f}%" for a in s.get("agree_by_replicate", []))
    return [
        f"| judgements within the 95% interval of their difference (ESS and draws, pooled) | "
        f"{s['agree']} / {s['judgements']} ({100 * s['agree_share']:.1f}%) |",
        f"| the same, each batch replicate's share | {shares}"
        + (" (95% t-interval of the share {:.1f}%-{:.1f}%)".format(
            *(100 * x for x in s["agree_share_interval"]))
           if s.get("agree_share_interval") else "") + " |",
        f"| the same with the first-order model (mean 0, the same batches) | "
        f"{s['agree_first_order']} / {s['judgements']} "
        f"({100 * s['agree_first_order'] / s['judgements']:.1f}%) |",
        f"| the same with the weights' delta-method standard error | {s['agree_delta']} / "
        f"{s['judgements']} |",
        f"| the weights alone: re-weighted against {n:,} deviations drawn from the model, "
        f"within the same interval | {s['agree_with_linear']} / {s['judgements']} |",
        f"| differences in standard errors: mean, s.d. (0 and 1 if the errors are right) | "
        f"{s['z_mean']:+.2f}, {s['z_sd']:.2f} |",
        f"| the replicates' spread over the weights' standard error (1 if it is right) | "
        f"{s['batch_spread_over_se']:.2f} |",
        f"| smallest effective sample size | {s['min_ess']:.0f} |",
        f"| the Gaussian model's bias per case, largest / mean absolute (each +- "
        f"{Z95 * math.sqrt(0.5 / n):.4f} of sampling error at most) | "
        f"{s['max_abs_linear_bias']:.4f} / {s['mean_abs_linear_bias']:.4f} |",
        f"| the model's bias, the largest mean over a grasp's angles at one noise level "
        f"[95% t-interval] | {s['largest_group_bias']:+.4f} "
        f"[{s['largest_group_bias'] - s['largest_group_bias_half_width']:+.4f}, "
        f"{s['largest_group_bias'] + s['largest_group_bias_half_width']:+.4f}] |",
        f"| grasp and noise levels whose mean bias is above 0.01 beyond its interval | "
        f"{s['groups_bias_surely_above_0.01']} |"]


def calibration_table(result: dict) -> list[str]:
    """Per object and noise level: judgements agreeing, the weights alone, the largest
    difference, the Gaussian model's mean bias over the angles [95% t-interval]."""
    lines = ["| object | sigma | judgements agreeing | weights alone agreeing | largest abs. "
             "difference | the model's mean bias [95%] | largest abs. bias |",
             "|---|---|---|---|---|---|---|"]
    groups = {(g["object"], g["sigma"]): g for g in result["summary"]["bias_groups"]}
    for obj in dict.fromkeys(c["object"] for c in result["cases"]):
        for sigma in result["settings"]["sigmas"]:
            rows = [c for c in result["cases"] if c["object"] == obj and c["sigma"] == sigma]
            g = groups[(obj, sigma)]
            lines.append(
                f"| {obj} | {sigma:g} | {sum(c['agrees'] for c in rows)} / {len(rows)} | "
                f"{sum(c['agrees_with_linear'] for c in rows)} / {len(rows)} | "
                f"{max(abs(c['difference']) for c in rows):.4f} | "
                f"{g['mean']:+.4f} [{g['mean'] - g['half_width']:+.4f}, "
                f"{g['mean'] + g['half_width']:+.4f}] | "
                f"{max(abs(c['linear_bias']) for c in rows):.4f} |")
    return lines


def levels_floor_row(floor: dict, run: dict) -> str:
    """The Markdown row of :func:`levels_floor`'s figures (``floor``)."""
    shares = ", ".join(f"{x:.2f}" for x in floor["ess_shares"])
    return (f"| four noise levels at the direct runs' accuracy, least closings / four direct "
            f"runs (a batch of {floor['least_batch']:,}, each level topped up to "
            f"{run['levels_samples']:,} effective draws; its effective sizes {shares} of the "
            f"batch, for any grasp) | {floor['least_ratio']:.2f} |")


def markdown(result: dict) -> str:
    s = result["summary"]
    run = result["settings"]
    lines = [
        f"Re-weighted P(FC) against {run['direct']:,} direct draws per case "
        f"({s['cases']} cases: {run['angles']} elbow angles x {len(run['sigmas'])} noise "
        f"levels x {len(run['objects'])} grasps, each case's draws its own; "
        f"{s['replicates']} independent batches of {run['batch']:,} closings per grasp, each "
        "judged on every case). Written by `python benchmarks/bench_reweight.py`.", "",
        "| figure | value |", "|---|---|",
        *calibration_rows(result),
        f"| elbow time, re-weighted / direct (mean) | {s['elbow_ratio_mean']:.2f} |",
        f"| four noise levels, one batch / four direct runs (mean) | "
        f"{s['levels_ratio_mean']:.2f} |",
        *([levels_floor_row(result["levels_floor"], run)] if result.get("levels_floor")
          else []),
        *([f"| fig10's variants (reference engine), one batch / a run per variant (mean) | "
           f"{s['variants_ratio_mean']:.2f} |"] if s.get("variants_ratio_mean") else []),
        *([f"| KineGrasp-v0 steps/s, batch reward / draws' reward (grasps' batches built) "
           f"| {result['env']['ratio']:.1f} ({result['env']['batch']['steps_per_s']:.0f} / "
           f"{result['env']['draws']['steps_per_s']:.0f}); P(FC) rms error against 4,000 "
           f"draws {result['env']['batch']['p_fc_rms_error']:.3f} / "
           f"{result['env']['draws']['p_fc_rms_error']:.3f} |"] if result.get("env") else []),
        *[f"| batch certificate at delta 0.05 false (half-space field, batches of "
          f"{c['batch']}) | {c['false_at_half_delta_bounds']} / {c['runs']} (its bounds at "
          f"delta/2); {c['false_at_delta_bounds']} / {c['runs']} with bounds at delta |"
          for c in result.get("certificate", [])], "",
        *calibration_table(result)]
    return "\n".join(lines)


def render_again(args) -> None:
    """Re-judge a written result's cases (``--render-only``) and rewrite it and the table."""
    import json

    result = json.loads(Path(args.json_out).read_text())
    n = result["settings"]["direct"]
    result["cases"] = [judged(c, n) for c in result["cases"]]
    result["summary"] = summary(result["cases"], result["elbow"], result["levels"],
                                result.get("variants"))
    result["levels_floor"] = levels_floor(result["settings"]["sigmas"],
                                          result["settings"]["levels_samples"])
    print(markdown(result))
    # the measuring run's date and machine stay: only the verdicts are recomputed
    Path(args.json_out).write_text(json.dumps(plain(result), indent=1) + "\n")
    write_between(DOC, START, END, markdown(result))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "spray_flask", "drill", "mug"])
    parser.add_argument("--grasps", type=int, default=1, help="first N shipped grasps each")
    parser.add_argument("--angles", type=int, default=18)
    parser.add_argument("--sigmas", type=float, nargs="+", default=list(PAPER_SIGMAS))
    parser.add_argument("--batch", type=int, default=40000)
    parser.add_argument("--direct", type=int, default=20000)
    parser.add_argument("--replicates", type=int, default=5,
                        help="independent batches per grasp, each judged on every case")
    parser.add_argument("--samples", type=int, default=1000, help="elbow draws per angle")
    parser.add_argument("--levels-samples", type=int, default=10000)
    parser.add_argument("--levels-batch", type=int, default=20000)
    parser.add_argument("--variants", type=int, default=10, help="fig10 variants timed")
    parser.add_argument("--coverage-runs", type=int, default=1000)
    parser.add_argument("--env-episodes", type=int, default=40)
    parser.add_argument("--coverage-batches", type=int, nargs="+", default=[600, 2000])
    parser.add_argument("--no-calibration", action="store_true",
                        help="time only; with a written result, replace its timings and keep "
                        "its calibration cases")
    parser.add_argument("--no-timing", action="store_true",
                        help="calibrate only; keep the written result's timings")
    parser.add_argument("--render-only", action="store_true",
                        help="judge the cases of the JSON result again and rewrite it and "
                        "the docs table (no closing)")
    add_options(parser, __file__)
    args = parser.parse_args()
    if args.render_only:
        render_again(args)
        return
    grasps = [g for obj in args.objects for g in shipped_grasps(obj)[:args.grasps]]
    if args.no_timing:
        import json

        old = json.loads(Path(args.json_out).read_text())
        timings = {k: old.get(k) for k in ("elbow", "levels", "variants", "certificate",
                                           "env")}
        kept = {**old["settings"], **{k: v for k, v in settings(args).items()
                                      if k in CALIBRATION_SETTINGS}}
    else:
        timings = timing_figures(grasps, args)
    if args.no_calibration:
        import json

        if args.no_json or not Path(args.json_out).exists():
            return
        old = json.loads(Path(args.json_out).read_text())
        cases, kept = old["cases"], old["settings"]
        kept.update({k: v for k, v in settings(args).items()
                     if k not in CALIBRATION_SETTINGS})
    else:
        cases = [c for i, g in enumerate(grasps) for c in calibration(g, args, seed=10 * i)]
        if not args.no_timing:
            kept = settings(args)
    result = {"summary": summary(cases, timings["elbow"], timings["levels"],
                                 timings["variants"]),
              "levels_floor": levels_floor(kept["sigmas"], kept["levels_samples"]),
              **timings, "cases": cases, "settings": kept}
    publish(__file__, result, args, markdown(result), DOC, (START, END))


def timing_figures(grasps: list, args) -> dict:
    """The elbow, noise-level, fig10, certificate and env figures (warm, printed)."""
    # warm the compiled kernels once, outside every timing
    optimize_robot_elbow_reweighted(grasps[0], JointNoise(0.0133), 200, 0)
    optimize_robot_elbow(grasps[0], JointNoise(0.0133), 200, 0)
    elbows = [elbow_timing(g, args) for g in grasps]
    levels = [levels_timing(g, args) for g in grasps]
    variants = [variants_timing(obj, args) for obj in args.objects]
    for e in elbows:
        print(f"elbow {e['object']} {e['grasp']}: direct {e['direct_s']:.2f} s, re-weighted "
              f"{e['reweight_s']:.2f} s ({e['ratio']:.2f}); best {e['direct_best_psi']:+.3f} "
              f"/ {e['reweight_best_psi']:+.3f} rad, fresh P(FC) {e['direct_best_fresh']:.3f} "
              f"/ {e['reweight_best_fresh']:.3f}")
    for v in levels:
        print(f"levels {v['object']} {v['grasp']}: direct {v['direct_s']:.2f} s, one batch "
              f"{v['reweight_s']:.2f} s ({v['ratio']:.2f}); ESS "
              f"{', '.join(f'{e:.0f}' for e in v['ess'])}")
    for v in variants:
        print(f"fig10 {v['object']}: {v['variants']} variants, direct {v['direct_s']:.2f} s, "
              f"one batch {v['reweight_s']:.2f} s ({v['ratio']:.2f})")
    return {"elbow": elbows, "levels": levels, "variants": variants,
            "certificate": certificate_coverage(args), "env": env_timing(args)}


if __name__ == "__main__":
    main()
