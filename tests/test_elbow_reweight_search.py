"""The re-weighted elbow search for a description robot (the Panda).

What each test proves:

* the flange's body Jacobian of the Panda is the derivative of its forward kinematics
  (central differences of the flange pose, an independent computation, to 1e-6);
* a batch closing with a zero palm deviation is the engine's nominal closing; a palm
  deviation moves the hand as the arm's own joint 7 does (a turn about the flange's z axis);
* the re-weighted P(FC) along the Panda's self-motion agrees with direct draws at the same
  angles within 3 combined standard errors at every angle compared (the weights' delta-method
  error and the binomial one; 0.9 of them at most measured), and the command prints the
  batch's evidence.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.closing.hand_errors import flange_link
from kinegrasp_env.montecarlo.evaluate import make_engine
from kinegrasp_env.montecarlo.palm_batch import PalmJacobian, close_deltas
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.kinematics import Kinematics, rotation_log
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.elbow_reweight_search import optimize_robot_elbow_reweighted
from kinegrasp_env.toolkit.elbow_search import optimize_robot_elbow
from kinegrasp_env.world.grasps import shipped_grasps


def test_the_panda_flange_jacobian_is_its_kinematics_derivative():
    description = load_robot("panda")
    kin, flange = Kinematics(description.model), flange_link(description)
    q = np.asarray(shipped_grasps("cube", "panda")[0].q0, dtype=float)
    jac = PalmJacobian(description)(q)[0]
    base = kin.pose(q[None], flange)[0]
    h = 1e-6
    for j in range(7):
        step = np.zeros_like(q)
        step[j] = h
        plus, minus = kin.pose((q + step)[None], flange)[0], kin.pose((q - step)[None], flange)[0]
        rel = np.linalg.inv(base) @ plus, np.linalg.inv(base) @ minus
        twist = np.concatenate([(rel[0][:3, 3] - rel[1][:3, 3]) / (2 * h),
                                (rotation_log(rel[0][:3, :3]) - rotation_log(rel[1][:3, :3]))
                                / (2 * h)])
        np.testing.assert_allclose(jac[:, j], twist, atol=1e-6)


def test_a_batch_closing_is_the_engine_closing_with_a_palm_error():
    grasp = shipped_grasps("cube", "panda")[0]
    q = np.asarray(grasp.q0, dtype=float)
    turns = np.array([[0, 0, 0, 0, 0, 0.0], [0, 0, 0, 0, 0, 0.04]])
    outcome, quality = close_deltas(q, turns, "cube", robot="panda")
    moved = np.repeat(q[None], 2, axis=0)
    moved[1, load_robot("panda").arm_joints.index("panda_joint7")] += 0.04
    with make_engine("fast", "panda", "cube") as engine:
        direct = engine.run(moved)
    np.testing.assert_array_equal(outcome, direct.outcome)
    np.testing.assert_allclose(quality, direct.quality, rtol=1e-9, atol=1e-12)


def test_reweighted_curve_of_the_panda_agrees_with_direct_draws(capsys):
    grasp = shipped_grasps("cube", "panda")[1]
    noise, samples = JointNoise(0.0133), 500
    result, evidence = optimize_robot_elbow_reweighted(grasp, noise, samples, 0,
                                                       engine="fast", batch=1000)
    direct = optimize_robot_elbow(grasp, noise, samples, 0, evaluate_with="fast")
    by_psi = {round(p.psi, 6): p for p in direct.curve}
    compared = 0
    for c in evidence.curve:
        p = by_psi.get(round(c.point.psi, 6))
        if p is None or c.fallback:
            continue
        se = np.hypot(c.se, np.sqrt(p.p_fc * (1 - p.p_fc) / samples))
        assert abs(c.point.p_fc - p.p_fc) <= 3 * se, (c.point.psi, c.point.p_fc, p.p_fc)
        compared += 1
    assert compared >= 10 and result.engine == "fast"
    capsys.readouterr()
    assert main(["elbow", "--robot", "panda", "--object", "cube", "--grasp", "1", "--samples",
                 "100", "--method", "reweight", "--engine", "fast", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["robot"] == "panda" and shown["reweight"]["batch"] == 200
    assert main(["elbow", "--robot", "panda", "--object", "cube", "--batch", "50"]) == 2
    assert "--method direct takes none" in capsys.readouterr().err


@pytest.mark.parametrize("sigma", ["0.0133"])
def test_non_gaussian_noise_is_refused_before_any_closing(capsys, sigma):
    assert main(["elbow", "--robot", "panda", "--object", "cube", "--sigma", sigma,
                 "--noise", "uniform", "--method", "reweight"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Gaussian" in err[0]


def _searches():
    from kinegrasp_env.toolkit.elbow_reweight_search import optimize_robot_branches_reweighted
    from kinegrasp_env.toolkit.elbow_search import optimize_robot_branches

    return {"elbow": optimize_robot_elbow, "branches": optimize_robot_branches,
            "elbow_reweighted": optimize_robot_elbow_reweighted,
            "branches_reweighted": optimize_robot_branches_reweighted}


@pytest.mark.parametrize("search", ["elbow", "branches", "elbow_reweighted",
                                    "branches_reweighted"])
@pytest.mark.parametrize("change, message", [
    ({"seed": -1}, "seed must be an integer >= 0 (the run's rows), got -1"),
    ({"samples": 0}, "samples must be an integer >= 1, got 0"),
    ({"noise": 0.01}, "noise must be a JointNoise (e.g. JointNoise(0.0133)) or a NoiseModel, "
                      "got float 0.01"),
    ({"grasp": None}, "grasp must be a Grasp (kinegrasp_env.world.grasps), got NoneType"),
])
def test_every_search_refuses_bad_inputs_alike_before_any_closing(monkeypatch, search, change,
                                                                  message):
    """The direct and re-weighted elbow and IK-branch searches check their inputs by one
    rule (``check_search``), in the same words and before any engine is built (an engine
    built here fails the test)."""
    from kinegrasp_env.montecarlo.reference_engine import RobotReferenceEngine

    def no_engine(*args, **kwargs):
        raise AssertionError("an engine was built before the inputs were checked")

    monkeypatch.setattr(RobotReferenceEngine, "__init__", no_engine)
    run = {"grasp": shipped_grasps("cube")[1], "noise": JointNoise(0.01), "samples": 50,
           "seed": 0, **change}
    with pytest.raises(ValueError) as info:
        _searches()[search](run["grasp"], run["noise"], run["samples"], run["seed"])
    assert str(info.value) == message


def test_the_searches_refuse_a_wrong_engine_and_arm_in_one_line():
    """A direct search takes a reference engine of the grasp's robot and object (a name, or
    another robot's engine, is refused); a re-weighted one an engine that closes a hand
    moved by a palm error (not physics); the IK-branch searches a 6-joint arm (the
    7-joint KUKA moves along its self-motion instead)."""
    from kinegrasp_env.montecarlo.reference_engine import RobotReferenceEngine

    grasp, noise = shipped_grasps("cube")[1], JointNoise(0.01)
    searches = _searches()
    with pytest.raises(ValueError, match=r"^engine must be a RobotReferenceEngine of the "
                                         r"grasp's robot and object, or None, got str$"):
        searches["elbow"](grasp, noise, 50, engine="fast")
    with RobotReferenceEngine("panda", "cube") as panda, pytest.raises(
            ValueError, match=r"^grasp '1' is a grasp of robot 'kuka_sdh', not of 'panda'"):
        searches["elbow"](grasp, noise, 50, engine=panda)
    for name in ("elbow_reweighted", "branches_reweighted"):
        with pytest.raises(ValueError, match=r"^a batch of palm deviations is closed by an "
                                             r"engine that takes palm errors \(pybullet or "
                                             r"fast\), got engine 'physics'$"):
            searches[name](grasp, noise, 50, engine="physics")
    for name in ("branches", "branches_reweighted"):
        with pytest.raises(ValueError, match=r"^robot 'kuka_sdh' has 7 arm joints; IK "
                                             r"branches are a 6-joint arm's"):
            searches[name](grasp, noise, 50)
