"""`kinegrasp ee --robot NAME` and `kinegrasp elbow --robot NAME`: a catalog robot's palm
noise and its grasps' most robust elbow, checked against pybullet's own kinematics."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine, evaluate_grasp
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import shipped_grasps

SIGMA = 0.0133


class BulletArm:
    """pybullet's forward kinematics of a description robot's URDF (its own client, the
    base fixed at the origin): the independent reference of these tests."""

    def __init__(self, robot: str) -> None:
        import pybullet
        from pybullet_utils.bullet_client import BulletClient

        self.description = load_robot(robot)
        self.bullet = BulletClient(connection_mode=pybullet.DIRECT)
        self.body = self.bullet.loadURDF(str(self.description.urdf), useFixedBase=True)
        info = [self.bullet.getJointInfo(self.body, j)
                for j in range(self.bullet.getNumJoints(self.body))]
        joints = {i[1].decode(): i for i in info}
        links = {i[12].decode(): i[0] for i in info}
        self.arm = [joints[name][0] for name in self.description.arm_joints]
        self.limits = np.array([joints[name][8:10] for name in self.description.arm_joints])
        self.palm = links[self.description.palm_link]
        self.links = links

    def pose(self, q_arm: np.ndarray, link: str | None = None) -> np.ndarray:
        """(4, 4) URDF frame of ``link`` (default the palm) at arm joints q_arm (7,)."""
        for j, v in zip(self.arm, q_arm, strict=True):
            self.bullet.resetJointState(self.body, j, float(v))
        index = self.palm if link is None else self.links[link]
        state = self.bullet.getLinkState(self.body, index, computeForwardKinematics=True)
        out = np.eye(4)
        out[:3, :3] = np.reshape(self.bullet.getMatrixFromQuaternion(state[5]), (3, 3))
        out[:3, 3] = state[4]
        return out

    def positions(self, q_arm: np.ndarray) -> np.ndarray:
        return np.array([self.pose(q)[:3, 3] for q in np.atleast_2d(q_arm)])


@pytest.fixture(scope="module")
def panda_arm():
    arm = BulletArm("panda")
    yield arm
    arm.bullet.disconnect()


def run_json(capsys, *args: str) -> dict:
    assert main(list(args)) == 0
    return json.loads(capsys.readouterr().out)


def test_ee_of_the_panda_against_pybullet(capsys, panda_arm):
    """The same draws (seed 5) through pybullet, whose link frames agree with ours to ~5e-8 m
    (its single-precision offsets): sampled mean (measured 1.3e-9 m; bound 2e-7) and
    covariance (measured 1.2e-11 m^2, 1e-7 of its largest entry; bound 1e-6 relative); p(q0)
    (measured 5e-8 m; bound 2e-7); J Sigma J^T against pybullet's central differences with
    step 3e-3 rad (measured 1.1e-5 relative; bound 1e-4); the default q0 is the middle of the
    URDF's limits."""
    n, seed = 3000, 5
    out = run_json(capsys, "ee", "--robot", "panda", "--samples", str(n), "--seed", str(seed),
                   "--json")
    q0 = np.asarray(out["q0"])
    assert np.allclose(q0, panda_arm.limits.mean(axis=1), atol=1e-12)
    eps = JointNoise(SIGMA).sample(n, 7, np.random.default_rng(seed))
    ee = panda_arm.positions(q0 + eps)
    assert np.abs(np.asarray(out["mean"]) - ee.mean(axis=0)).max() < 2e-7
    cov = np.cov(ee.T)
    assert np.abs(np.asarray(out["cov"]) - cov).max() < 1e-6 * np.abs(cov).max()
    # first order: p(q0) and J Sigma J^T with J by central differences of pybullet's FK
    assert np.abs(np.asarray(out["first_order_mean"]) - panda_arm.positions(q0)[0]).max() < 2e-7
    h = 3e-3
    jac = np.stack([(panda_arm.positions(q0 + h * e)[0] - panda_arm.positions(q0 - h * e)[0])
                    / (2 * h) for e in np.eye(7)], axis=1)
    linear = SIGMA**2 * jac @ jac.T
    first = np.asarray(out["first_order_cov"])
    assert np.abs(first - linear).max() < 1e-4 * np.abs(linear).max()
    # sampled against first order: sampling error ~ sqrt(var_i var_j / n), plus 3% for the
    # linearization (measured 2.2 se at most)
    se = np.sqrt(np.outer(linear.diagonal(), linear.diagonal()) / n)
    assert np.all(np.abs(np.asarray(out["cov"]) - first) < 5 * se + 0.03 * np.abs(first))


#: The arm configuration the pins below were made at (radians): elbow bent, wrist turned back.
PIN_Q0 = "0,0.6,0,-1.2,0,0.8,0"
#: Regression pin: the default robot's palm-position moments as the KUKA's own command printed
#: them before `ee` existed (`kinegrasp kuka-ee --q0 PIN_Q0 --json`, commit c443c2e); `ee`
#: draws the same noise through the description's model (which agrees with that command's
#: to float precision: measured 1e-16), so its numbers compare to a few ulps.
KUKA_EE_PIN = {
    "mean": [0.7353164099714355, -0.00011131720917207549, 0.4351308797387478],
    "cov": [[1.947563870547703e-05, -6.917912568485009e-07, 1.7429969451658404e-05],
            [-6.917912568485009e-07, 0.00015752286866695743, 9.509528426743483e-08],
            [1.7429969451658404e-05, 9.509528426743483e-08, 0.00014276355440916781]],
    "skew": [-0.016250005925463842, -0.008629794906081885, 0.010284923626902339],
    "samples": 10000, "sigma": 0.0133, "noise": "gaussian", "seed": 0}
#: Regression pin: the same with `--samples 500 --seed 3 --noise uniform`, as printed (7
#: significant digits; commit c443c2e).
KUKA_EE_TEXT_PIN = """KUKA palm position (500 draws)
  mean: [ 7.353625e-01 -5.543865e-04  4.352423e-01]
  cov:
[[ 2.108052e-05  6.794307e-07  1.821276e-05]
 [ 6.794307e-07  1.657720e-04 -4.631080e-06]
 [ 1.821276e-05 -4.631080e-06  1.412960e-04]]
  skew: [-0.072017 -0.025773 -0.019237]
"""


def test_ee_of_the_default_robot_keeps_the_pinned_palm_moments(capsys):
    out = run_json(capsys, "ee", "--q0", PIN_Q0, "--json")
    assert out["robot"] == "kuka_sdh" and out["q0"] == [0.0, 0.6, 0.0, -1.2, 0.0, 0.8, 0.0]
    for key, value in KUKA_EE_PIN.items():
        if key in ("mean", "cov", "skew"):
            np.testing.assert_allclose(out[key], value, rtol=1e-9, atol=1e-15)
        else:
            assert out[key] == value
    out = run_json(capsys, "ee", "--q0", PIN_Q0, "--samples", "500", "--seed", "3",
                   "--noise", "uniform", "--json")
    pinned = [float(x) for x in re.findall(r"-?\d\.\d+e[-+]\d+|-?\d\.\d{6}",
                                           KUKA_EE_TEXT_PIN)]
    shown = np.concatenate([np.ravel(out[key]) for key in ("mean", "cov", "skew")])
    assert len(pinned) == len(shown) == 15
    # printed to 7 significant digits (mean, cov) and to 6 decimals (skew)
    np.testing.assert_allclose(shown[:12], pinned[:12], rtol=1e-6, atol=0)
    np.testing.assert_allclose(shown[12:], pinned[12:], rtol=0, atol=5e-7)
    assert main(["ee", "--q0", "0,1,2"]) == 2
    assert capsys.readouterr().err.strip().endswith(
        "--q0: the arm of robot 'kuka_sdh' needs 7 joint angles, got 3")
    # without --q0 it starts at the description's home, the IK's start
    home = run_json(capsys, "ee", "--json")
    assert home["q0"] == load_robot("kuka_sdh").home_arm().tolist()


@pytest.mark.parametrize("args, message", [
    (["--q0", "0,0,0"], "--q0: the arm of robot 'panda' needs 7 joint angles, got 3"),
    (["--q0", "0,0,0,0.5,0,1.5,0"], "--q0: joint 4 angle 0.5 outside its limits"),
    (["--q0", "0,0,0,-1,0,nan,0"], "--q0"),
    (["--robot", "no_such_robot"], "unknown robot 'no_such_robot'"),
])
def test_ee_refuses_bad_input_in_one_line(capsys, args, message):
    argv = ["ee", *args] if args[0] == "--robot" else ["ee", "--robot", "panda", *args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


@pytest.fixture(scope="module")
def panda_elbow():
    """A small elbow run of the Panda's first cube grasp (0.25 rad grid, 30 draws)."""
    from kinegrasp_env.toolkit.elbow_search import (
        optimize_robot_elbow,
        robot_reachable_configurations,
    )

    grasp = shipped_grasps("cube", "panda")[0]
    with RobotReferenceEngine("panda", "cube") as engine:
        reach = robot_reachable_configurations(grasp, engine, step=0.25)
        result = optimize_robot_elbow(grasp, JointNoise(SIGMA), 30, 7, engine=engine,
                                      evaluate_with="pybullet",
                                      step=0.25, reach=reach)
        yield grasp, reach, result, engine


def test_panda_self_motion_keeps_the_palm_pose(panda_elbow, panda_arm):
    """Every configuration of the curve, by pybullet's FK: the grasp's palm pose (pose
    matrix entries, metres and rotation; measured 2.4e-8, pybullet's single precision;
    bound 2e-7), within the URDF's limits, the elbow moved (link4, the elbow of
    arm_angle_links, travels > 10 cm over the curve)."""
    grasp, reach, result, _ = panda_elbow
    assert len(reach) >= 5 and len(result.curve) >= 5
    elbows = []
    for point in result.curve:
        q = point.q[:7]
        deviation = np.abs(panda_arm.pose(q) - grasp.palm_pose).max()
        assert deviation < 2e-7, (point.psi, deviation)
        assert np.all((q >= panda_arm.limits[:, 0]) & (q <= panda_arm.limits[:, 1]))
        assert point.q[7:] == pytest.approx(grasp.q0[7:])
        elbows.append(panda_arm.pose(q, "panda_link4")[:3, 3])
    elbows = np.array(elbows)
    assert np.linalg.norm(elbows.max(axis=0) - elbows.min(axis=0)) > 0.1
    assert any(np.array_equal(p.q, grasp.q0) for p in result.curve)  # the nominal itself


def test_panda_best_angle_is_reported_on_fresh_draws(panda_elbow):
    """The best angle is the selection's argmax; its reported P(FC) is that of an
    independent evaluation on the fresh draws (the run's rows after the selection's, the
    default robot's report chunks: 250 .. 279 for 30 draws), the nominal's too, and the
    certificate bounds every rival's observed fresh advantage."""
    from dataclasses import replace

    grasp, _, result, engine = panda_elbow
    best = max(result.curve, key=lambda p: p.p_fc)
    assert result.best_psi == best.psi and result.engine == "pybullet"
    again = evaluate_grasp(replace(grasp, q0=best.q), sigma=SIGMA, n=30, seed=7,
                           offset=250, engine=engine)
    assert result.best_p_fc == again.p_fc
    assert np.array_equal(best.fresh_fc, again.draws.outcome == FORCE_CLOSURE)
    selection = evaluate_grasp(replace(grasp, q0=best.q), sigma=SIGMA, n=30, seed=7,
                               engine=engine)
    assert best.p_fc == selection.p_fc
    assert np.array_equal(best.fc, selection.draws.outcome == FORCE_CLOSURE)
    # the two streams differ draw by draw at every angle (measured: 6 to 15 of 30 draws)
    assert all((p.fc != p.fresh_fc).sum() >= 2 for p in result.curve)
    nominal = evaluate_grasp(grasp, sigma=SIGMA, n=30, seed=7, offset=250,
                             engine=engine)
    assert result.nominal_p_fc == nominal.p_fc
    cert = result.certificate.to_json()
    assert cert["chosen_psi"] == result.best_psi and cert["fresh_draws"] == 30
    best_fresh = again.draws.outcome == FORCE_CLOSURE
    for rival in cert["rivals"]:
        point = next(p for p in result.curve if p.psi == rival["psi"])
        observed = point.fresh_fc.mean() - best_fresh.mean()
        assert rival["difference"] == pytest.approx(observed)
        assert observed <= rival["upper"] <= cert["bound"] + 1e-12


def test_elbow_cli_for_the_panda(capsys):
    out = run_json(capsys, "elbow", "--robot", "panda", "--object", "cube", "--grasp", "1",
                   "--samples", "4", "--json")
    # the fast engine by default, as for the default robot
    assert out["robot"] == "panda" and out["engine"] == "fast" and out["samples"] == 4
    assert out["certificate"]["fresh_draws"] == 4 and len(out["curve"]) >= 3
    # the fast engine on two worker processes: the same draws as in this process
    fast = [run_json(capsys, "elbow", "--robot", "panda", "--object", "cube", "--grasp", "1",
                     "--samples", "20", "--engine", "fast", "--json", *extra)
            for extra in ([], ["--processes", "2"])]
    assert fast[0]["engine"] == "fast" and fast[0]["curve"] == fast[1]["curve"]
    assert fast[0]["certificate"] == fast[1]["certificate"]
    for args, message in [(["--grasp", "99"], "--grasp: grasp index 99 out of range"),
                          (["--object", "mug"], "no shipped grasps of 'mug'")]:
        assert main(["elbow", "--robot", "panda", "--object", "cube", *args]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and "\n" not in err, err


def test_the_default_robots_elbow_search_against_its_analytic_ik_and_own_draws():
    """The elbow search on kuka_sdh (Newton continuation on its description, draws by rows
    of the run's streams) walks every angle, and only those, that the default robot's arm
    reaches along its analytic self-motion (``toolkit.elbow.ArmWalk``, another solver:
    configurations within 1.1e-8 rad measured, 1e-7 allowed), and scores each on the
    draws of the run's rows closed by the default fast engine directly (rows of the seed's
    streams, ``chunk_configurations``): selection rows 0.., fresh rows 250.. of the seed. A
    draw within 1e-7 rad of a force-closure boundary may differ: at most one per angle
    allowed, none measured."""
    from kinegrasp_env.montecarlo.chunks import CHUNK, chunk_configurations
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.toolkit.elbow import reachable_configurations
    from kinegrasp_env.toolkit.elbow_search import (
        optimize_robot_elbow,
        robot_reachable_configurations,
    )

    grasp = shipped_grasps("cube")[2]
    noise = JointNoise(SIGMA)
    analytic = reachable_configurations(grasp)
    with RobotReferenceEngine("kuka_sdh", "cube") as engine:
        walked = robot_reachable_configurations(grasp, engine)
    assert len(walked) == len(analytic) >= 10
    for (psi, q), (psi_analytic, q_analytic) in zip(walked, analytic, strict=True):
        assert psi == pytest.approx(psi_analytic, abs=1e-9)
        assert np.abs(q - q_analytic).max() < 1e-7
    result = optimize_robot_elbow(grasp, noise, 60, seed=3, evaluate_with="fast",
                                  reach=walked)
    analytic = dict(analytic)
    engine = make_engine("fast", "kuka_sdh", "cube")
    for point in result.curve:
        q = analytic[min(analytic, key=lambda psi: abs(psi - point.psi))]
        assert np.abs(point.q - q).max() < 1e-7
        fc = [engine.run(chunk_configurations(q, 7, SIGMA, "gaussian", 3, chunk * CHUNK,
                                              60)).outcome == FORCE_CLOSURE
              for chunk in (0, 1)]
        assert (point.fc != fc[0]).sum() <= 1 and (point.fresh_fc != fc[1]).sum() <= 1
        assert (fc[0] != fc[1]).any()  # the fresh draws are other draws
