"""The elbow from one batch: what it scores on fresh draws, how often its certificate is false
on outcome fields with a known truth, and its command-line refusals.

The certificate test replaces the closing by a half-space field over the palm's deviation,
f(delta) = [u . delta < c], whose P(FC) at each elbow is Phi((c - u . m(psi)) / sqrt(u^T
S(psi) u)) exactly, N(m(psi), S(psi)) the model of the real self-motion of a shipped grasp:
the claim "no evaluated angle beats the chosen one by more than B" is then checked against
the closed form, run after run.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, NO_FORCE_CLOSURE
from kinegrasp_env.montecarlo.palm_batch import PalmBatch
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.reweight import MixtureProposal, gaussian_logpdf
from kinegrasp_env.toolkit.elbow import reachable_configurations, with_configuration
from kinegrasp_env.toolkit.elbow_reweight import SelfMotionDeviation, batch_certificate
from kinegrasp_env.toolkit.elbow_reweight_search import optimize_robot_elbow_reweighted
from kinegrasp_env.world.grasps import shipped_grasps

SIGMA = 0.0233


@pytest.fixture(scope="module")
def grasp():
    return shipped_grasps("spray_flask")[4]


@pytest.fixture(scope="module")
def field(grasp):
    """(reach, motion, covariances, means, u, c, truth per angle) of a half-space field over
    delta."""
    reach = reachable_configurations(grasp)[::3]
    motion = SelfMotionDeviation(SIGMA)
    covs = motion.at(np.stack([q for _, q in reach]))
    # the direction whose spread changes most along the self-motion
    spread = np.array([np.diag(c) for c in covs])
    u = np.zeros(6)
    u[int(np.argmax(spread.max(axis=0) / spread.min(axis=0)))] = 1.0
    c = 0.6 * float(np.sqrt(np.median(spread @ u)))
    means = motion.gaussian(np.stack([q for _, q in reach]))[1]
    # the model's deviation N(m, S): P(u . delta < c) = Phi((c - u . m) / sqrt(u^T S u))
    truth = np.array([stats.norm.cdf((c - u @ m) / np.sqrt(u @ s @ u))
                      for s, m in zip(covs, means, strict=True)])
    return reach, motion, covs, means, u, c, truth


def synthetic_batch(covs, u, c, n, seed) -> PalmBatch:
    proposal = MixtureProposal.covering(covs, n)
    deltas = proposal.sample(np.random.default_rng(seed))
    outcome = np.where(deltas @ u < c, FORCE_CLOSURE, NO_FORCE_CLOSURE).astype(np.int8)
    return PalmBatch(np.zeros(14), deltas, proposal.logpdf(deltas), outcome, np.zeros(n))


def false_certificates(field, c: float, truth: np.ndarray, n: int, runs: int = 200) -> int:
    """Of ``runs`` runs on the half-space field at offset ``c`` (true P(FC) per angle
    ``truth``): the angle chosen on a selection batch of n closings, the certificate from a
    fresh one; how many certificates are false (a rival's true P(FC) exceeds the chosen
    one's by more than the bound)."""
    reach, motion, covs, means, u, _, _ = field
    false = 0
    for run in range(runs):
        selection = synthetic_batch(covs, u, c, n, 2 * run)
        values = [float(np.exp(gaussian_logpdf(selection.deltas, s, m)
                               - selection.log_proposal) @ selection.fc)
                  for s, m in zip(covs, means, strict=True)]
        b = int(np.argmax(values))
        rivals = [reach[j] for j in range(len(reach)) if j != b]
        fresh = synthetic_batch(covs, u, c, n, 2 * run + 1)
        cert = batch_certificate(reach[b], rivals, fresh, motion, 0.05, 0.05)
        gap = max(truth[j] - truth[b] for j in range(len(reach)) if j != b)
        false += gap > cert.bound
    return false


def test_certificate_is_false_at_most_at_its_level(field):
    """200 runs: the angle chosen on a selection batch, the certificate from a fresh one.
    The statement is false when a rival's true P(FC) exceeds the chosen one's by more than
    B; at delta 0.05, 200 runs with a true false rate <= 0.05 give more than 18 false ones
    with probability < 0.01."""
    *_, c, truth = field
    assert truth.max() - truth.min() > 0.02  # the angles differ: a real choice
    false = false_certificates(field, c, truth, 600)
    assert false <= 18, false


def test_a_batch_that_nearly_always_holds_still_bounds_the_rivals(field):
    """The half-space moved out to where P(FC) is 0.996-0.9999 at every angle: batches of
    300 closings mostly hold every time, and the normal bound of such a batch is 0 (no
    weighted variance) while a rival's true P(FC) may exceed the chosen one's. Over 200 runs
    at delta 0.05 the certificate is false in at most 18 (a true rate <= 0.05 gives more
    with probability < 0.01; measured: 0 with the Clopper-Pearson bound beside the normal
    one, 57 with the normal bound alone), and an all-held batch's interval at an angle is
    Wilson's at its ESS, lower end 1 / (1 + z^2 / ESS)."""
    reach, motion, covs, means, u, _, _ = field
    spread = np.sqrt(np.array([u @ s @ u for s in covs]))
    c = 2.6 * float(spread.max())
    truth = np.array([stats.norm.cdf((c - u @ m) / np.sqrt(u @ s @ u))
                      for s, m in zip(covs, means, strict=True)])
    assert truth.min() > 0.99 and truth.max() - truth.min() > 0.003
    false = false_certificates(field, c, truth, 300)
    assert false <= 18, false
    batch = synthetic_batch(covs, u, 1e3, 300, 0)  # every closing holds
    est = motion.estimate(batch, reach[0][1])
    z = stats.norm.ppf(0.975)
    assert est.value == pytest.approx(1.0, abs=1e-12) and est.se == 0.0
    assert est.interval[0] == pytest.approx(1.0 / (1.0 + z * z / est.ess), rel=1e-9)
    assert est.interval[1] == 1.0


def test_best_angle_scored_on_fresh_direct_draws(grasp):
    """The chosen angle's P(FC) is that of the configuration on the direct method's fresh
    draws (the 300 rows after the selection's: chunks 2 and 3 of the seed's 250-draw chunks),
    computed here independently: the rows drawn by hand from numpy's
    ``SeedSequence(3, spawn_key=(c,))`` streams (docs/conventions.md, "Random streams") and
    closed by the fast engine in one call."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.robot.catalog import DEFAULT_ROBOT

    noise = JointNoise(SIGMA)
    result, evidence = optimize_robot_elbow_reweighted(grasp, noise, 300, seed=3,
                                                       engine="fast")
    moved = with_configuration(grasp, result.best_q, result.best_psi)
    eps = np.concatenate([
        np.random.default_rng(np.random.SeedSequence(3, spawn_key=(c,))
                             ).standard_normal((rows, 7)) * SIGMA
        for c, rows in ((2, 250), (3, 50))])
    q = np.repeat(np.asarray(moved.q0, dtype=float)[None], 300, axis=0)
    q[:, :7] += eps
    with make_engine("fast", DEFAULT_ROBOT, grasp.object) as engine:
        outcome = engine.run(q).outcome
    assert result.best_p_fc == pytest.approx(np.mean(outcome == FORCE_CLOSURE), abs=1e-12)
    assert evidence.batch == 600 and len(evidence.curve) == len(result.curve)
    # the best angle is the curve's best or between its neighbours
    psis = [p.psi for p in result.curve]
    assert psis[0] <= result.best_psi <= psis[-1]


def test_cli_reweight_and_its_refusals(capsys, tmp_path, monkeypatch):
    from kinegrasp_env.cli import main
    from kinegrasp_env.toolkit import reweight_evidence

    args = ["elbow", "--object", "spray_flask", "--grasp", "4", "--sigma", str(SIGMA),
            "--samples", "200", "--method", "reweight"]
    assert main([*args, "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["reweight"]["batch"] == 400
    assert {"psi", "ess", "slope", "se"} <= set(payload["reweight"]["points"][0])
    assert "re-weighted" in payload["certificate"]["method"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "from one batch of 400 closings" in out and "effective sample size" in out
    page = tmp_path / "elbow.html"
    pictures = []  # the fragility picture is computed once for the plot and the page
    real = reweight_evidence.fragile_directions
    monkeypatch.setattr(reweight_evidence, "fragile_directions",
                        lambda *a: pictures.append(1) or real(*a))
    assert main([*args, "--report", str(page), "--plot", str(tmp_path / "elbow.png")]) == 0
    capsys.readouterr()
    text = page.read_text()
    assert "Why this elbow" in text and "--method reweight --batch 400" in text
    assert (tmp_path / "elbow.png").stat().st_size > 0 and len(pictures) == 1
    assert main([*args, "--noise", "uniform"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Gaussian joint noise" in err[0]
    # a batch smaller than its targets (one per reachable angle, and the defensive share)
    assert main([*args[:-3], "6", "--method", "reweight"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot cover" in err[0] and "give --batch" in err[0]
    assert "beside the defensive component's 10% share" in err[0]
    assert main([*args[:6], "0", *args[7:]]) == 2  # sigma 0: nothing to re-weight
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "re-weighting needs joint noise, and sigma is 0" in err[0], err
    assert main(["reproduce", "fig10", "--object", "cube", "--grasps", "10", "--samples",
                 "2", "--method", "reweight", "--engine", "fast", "--out",
                 str(tmp_path / "f10")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "give --samples" in err[0]


def test_an_angle_short_of_its_draws_is_topped_up_and_pooled():
    """Worked by hand: weights worth 400 draws at P 0.8 (se 0.02) and the 600 direct draws
    that make up 1,000 at P 0.6 pool to (400 x 0.8 + 600 x 0.6) / 1000 = 0.68 with standard
    error hypot(400 x 0.02, sqrt(600 x 0.68 x 0.32)) / 1000; the direct draws asked for are
    exactly the shortfall; an undefined ESS asks for all 1,000 and keeps them alone."""
    from kinegrasp_env.sampling.reweight import WeightedEstimate
    from kinegrasp_env.toolkit.elbow import ElbowPoint
    from kinegrasp_env.toolkit.elbow_reweight import topped_up

    asked = []

    def direct(psi, q, n):
        asked.append(n)
        fc = np.arange(n) < round(0.6 * n)
        return ElbowPoint(psi, q, float(fc.mean()), (0.0, 1.0), fc)

    q = np.zeros(14)
    point = topped_up(WeightedEstimate(0.8, 0.02, 400.0, 0.1, 0.05), direct, 0.3, q, 1000)
    se = np.hypot(400 * 0.02, np.sqrt(600 * 0.68 * 0.32)) / 1000
    assert asked == [600] and point.fallback and point.ess == 400.0
    assert point.point.p_fc == pytest.approx(0.68, abs=1e-12)
    assert point.se == pytest.approx(se, rel=1e-12) and point.slope == 0.1
    assert point.point.p_fc_ci == pytest.approx((0.68 - 1.959964 * se, 0.68 + 1.959964 * se))
    alone = topped_up(WeightedEstimate(float("nan"), float("nan"), float("nan")), direct, 0.3,
                      q, 1000)
    assert asked[-1] == 1000 and alone.point.p_fc == pytest.approx(0.6, abs=1e-12)


def test_the_rare_outcome_bound_is_a_difference_of_clopper_pearson_bounds():
    """Hand-computed with scipy's beta quantiles, uniform weights over 300 draws (ESS 300),
    each side at delta / 4: every draw held at both angles (the chosen angle's failures
    rare): 0 - lower(300 of 300) = 1 - (delta / 4)^(1/300); a rival with 3 successes of 300
    against a chosen angle at 150 (the rival's successes rare); -inf where no outcome is
    rare (the normal bound stands alone)."""
    from kinegrasp_env.toolkit.elbow_reweight import rare_outcome_bound

    w, delta = np.full(300, 1 / 300), 0.05
    held = rare_outcome_bound(1.0, w, 1.0, w, delta)
    assert held == pytest.approx(1.0 - (delta / 4) ** (1 / 300), rel=1e-9)
    rival = rare_outcome_bound(0.5, w, 0.01, w, delta)
    upper = stats.beta.ppf(1 - delta / 4, 3 + 1, 300 - 3)
    lower = stats.beta.ppf(delta / 4, 150, 300 - 150 + 1)
    assert rival == pytest.approx(upper - lower, rel=1e-9) and rival < 0
    assert rare_outcome_bound(0.6, w, 0.5, w, delta) == -np.inf


def test_a_batch_without_a_failing_closing_is_labelled_as_a_batch(tmp_path, capsys):
    """At sigma 0.0033 every closing of the cube grasp 2's batch holds, so there is no
    fragile direction to draw: the page still names its curve the re-weighted batch's (it
    said "selection draws") and says why the third chart is missing."""
    from kinegrasp_env.cli import main

    page = tmp_path / "e.html"
    assert main(["elbow", "--object", "cube", "--grasp", "2", "--sigma", "0.0033",
                 "--samples", "200", "--method", "reweight", "--report", str(page)]) == 0
    capsys.readouterr()
    text = page.read_text()
    assert "P(FC), one re-weighted batch" in text and "selection draws (common" not in text
    assert "No closing of the batch failed" in text
