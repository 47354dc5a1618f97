"""The elbow optimizer: what it promises (same palm pose, independent scoring draws, valid
intervals), each checked against an independent computation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats as sps

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.model import PALM_LINK, kuka_sdh
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.elbow import (
    ElbowPoint,
    configuration_at,
    miss_probability,
    optimize_elbow,
    paired_interval,
    reachable_configurations,
)
from kinegrasp_env.world.grasps import shipped_grasps


def test_paired_interval_is_the_t_interval():
    """Against scipy's own t-interval of the same data (an independent implementation)."""
    d = np.random.default_rng(3).normal(0.05, 0.3, 40)
    mean, lo, hi = paired_interval(d)
    ref = sps.t.interval(0.95, d.size - 1, loc=d.mean(), scale=sps.sem(d))
    assert mean == pytest.approx(d.mean())
    assert (lo, hi) == pytest.approx(ref, rel=1e-12)


def test_miss_probability_by_hand():
    """One rival with paired differences of known mean and standard error: the bound is
    Phi(mean / se), computed here by hand; a dominated rival adds 0."""
    best_fc = np.array([1, 1, 1, 0, 0, 1, 0, 1] * 10, bool)
    rival_fc = best_fc.copy()
    rival_fc[[3, 4]] = True      # rival wins two draws ...
    rival_fc[[0]] = False        # ... and loses one
    dominated = best_fc & False
    best = ElbowPoint(0.0, np.zeros(14), best_fc.mean(), (0, 1), best_fc)
    rival = ElbowPoint(0.1, np.zeros(14), rival_fc.mean(), (0, 1), rival_fc)
    low = ElbowPoint(0.2, np.zeros(14), 0.0, (0, 1), dominated)
    d = rival_fc.astype(float) - best_fc.astype(float)
    expected = 0.5 * (1 + math.erf(d.mean() / (d.std(ddof=1) / math.sqrt(d.size)) / math.sqrt(2)))
    low_d = dominated.astype(float) - best_fc.astype(float)
    expected += 0.5 * (1 + math.erf(low_d.mean() / (low_d.std(ddof=1) / math.sqrt(80))
                                    / math.sqrt(2)))
    assert miss_probability([best, rival, low], best) == pytest.approx(expected, rel=1e-12)


def test_self_motion_keeps_the_palm_pose_and_out_of_reach_is_an_error():
    """Every configuration the optimizer may choose reaches the grasp's palm pose (forward
    kinematics, independent of the IK that produced it); an unreachable angle is an error."""
    grasp = shipped_grasps("spray_flask")[0]
    reach = reachable_configurations(grasp, step=np.deg2rad(15))
    kin = Kinematics(kuka_sdh())
    palm = kin.pose(np.array([q for _, q in reach]), PALM_LINK)
    nominal = kin.pose(grasp.q0[None], PALM_LINK)[0]
    assert len(reach) >= 3
    assert np.abs(palm - nominal).max() < 1e-6
    psis = [psi for psi, _ in reach]
    assert psis == sorted(psis)
    with pytest.raises(ValueError, match="out of reach"):
        configuration_at(grasp, reach[-1][0] + 1.5 if reach[-1][0] < 1.5 else -3.1)


@pytest.mark.expensive
def test_optimizer_scores_on_independent_draws_and_reports_the_curve(tmp_path):
    """The best angle's P(FC) comes from draws the selection never saw (chunks K..2K-1), equal
    to evaluating that configuration on those chunks directly; the gain interval is the paired
    t-interval of those draws; the curve holds the nominal angle."""
    grasp = shipped_grasps("spray_flask")[1]
    noise = JointNoise(0.0266)
    result = optimize_elbow(grasp, noise, 200, seed=4, engine="fast", chunk=100)
    assert any(abs(p.psi - result.nominal_psi) < 1e-12 for p in result.curve)
    best = max(result.curve, key=lambda p: p.p_fc)
    assert result.best_psi == best.psi
    # independent scoring draws: chunks 2, 3 of seed 4 (selection used chunks 0, 1)
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.montecarlo.evaluate import draw_chunk

    engine = make_engine("fast", grasp.object)
    fc_best = np.concatenate([draw_chunk(engine, result.best_q, noise, 4, c, 100).outcome
                              for c in (2, 3)]) == FORCE_CLOSURE
    fc_nominal = np.concatenate([draw_chunk(engine, grasp.q0, noise, 4, c, 100).outcome
                                 for c in (2, 3)]) == FORCE_CLOSURE
    assert result.best_p_fc == fc_best.mean()
    assert result.nominal_p_fc == fc_nominal.mean()
    d = fc_best.astype(float) - fc_nominal.astype(float)
    ref = sps.t.interval(0.95, d.size - 1, loc=d.mean(), scale=sps.sem(d))
    assert result.gain_ci == pytest.approx(ref, rel=1e-9)
    # the selection draws are chunks 0, 1: the curve's nominal P(FC) equals evaluate_grasp
    nominal_point = next(p for p in result.curve if abs(p.psi - result.nominal_psi) < 1e-12)
    direct = evaluate_grasp(grasp, noise, 200, seed=4, engine="fast", chunk=100)
    assert nominal_point.p_fc == direct.p_fc
    payload = json.loads(json.dumps(result.to_json()))
    for key in ("best_psi", "best_p_fc", "best_p_fc_ci", "nominal_psi", "nominal_p_fc",
                "gain_ci", "curve"):
        assert key in payload
    assert {"psi", "p_fc", "p_fc_ci"} <= set(payload["curve"][0])


def test_evaluate_elbow_option(capsys):
    """`evaluate --elbow PSI` evaluates the configuration the optimizer's own move gives (same
    draws, same numbers); an unreachable angle is one line naming the reachable range."""
    from kinegrasp_env.cli import main
    from kinegrasp_env.toolkit.elbow import with_configuration

    grasp = shipped_grasps("spray_flask")[4]
    psi = 1.0
    args = ["evaluate", "--object", "spray_flask", "--grasp", "4", "--sigma", "0.0233",
            "--samples", "60", "--engine", "fast", "--json"]
    assert main([*args, "--elbow", str(psi)]) == 0
    shown = json.loads(capsys.readouterr().out)
    moved = with_configuration(grasp, configuration_at(grasp, psi), psi)
    direct = evaluate_grasp(moved, JointNoise(0.0233), 60, seed=0, engine="fast")
    assert shown["p_fc"] == direct.p_fc and shown["outcomes"] == direct.outcomes
    assert main([*args, "--elbow", "3.0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "out of reach" in err[0] and "reachable" in err[0]


@pytest.mark.expensive
def test_rank_best_elbow_ranks_the_optimizers_choice(tmp_path):
    """`rank --best-elbow N` ranks each candidate at the elbow the optimizer picks on seed + 1,
    scored on the ranking's own draws (seed): equal to optimizing and evaluating directly."""
    from kinegrasp_env.cli import main
    from kinegrasp_env.toolkit.elbow import with_configuration
    from kinegrasp_env.world.grasps import save_grasps

    grasp = shipped_grasps("cube")[0]
    save_grasps([grasp], tmp_path / "one.json")
    out = tmp_path / "r.csv"
    assert main(["rank", str(tmp_path / "one.json"), "--sigma", "0.02", "--samples", "80",
                 "--engine", "fast", "--best-elbow", "60", "--out", str(out)]) == 0
    row = out.read_text().splitlines()[1].split(",")
    best = optimize_elbow(grasp, JointNoise(0.02), 60, seed=1, engine="fast")
    direct = evaluate_grasp(with_configuration(grasp, best.best_q, best.best_psi),
                            JointNoise(0.02), 80, seed=0, engine="fast", chunk=80)
    assert row[0] == f"{grasp.id}e"
    assert float(row[1]) == pytest.approx(direct.p_fc, abs=1e-12)
