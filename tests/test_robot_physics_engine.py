"""The physics engine of a description robot (the Panda on the cube) against the reference
engine (pybullet closest points, no dynamics) on the same draws: P(FC) and contacts of the
shipped grasps at sigma 0, outcomes at a small sigma, and ``evaluate --engine physics``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kinegrasp_env.cli.main import main
from kinegrasp_env.montecarlo.evaluate import ENGINES, evaluate_grasp, make_engine
from kinegrasp_env.montecarlo.physics_engine import RobotPhysicsEngine
from kinegrasp_env.world.grasps import shipped_grasps
from tests.test_robot_physics import POINT_TOL

SIGMA, DRAWS, SEED = 0.0133, 40, 0
#: Draws with the same outcome on both engines at SIGMA (DRAWS draws of each of the 4 shipped
#: cube grasps, seed SEED): 159 of 160 measured with the jaws coupled (158 with each jaw on
#: its own motor; the disagreements: a draw of cube grasp 3 where one jaw's dynamic closing
#: misses what the kinematic closing touches); at least 152 of 160 held.
SAME_OUTCOME = 152 / 160


@pytest.fixture(scope="module")
def engines():
    physics, reference = make_engine("physics", "panda", "cube"), make_engine("pybullet",
                                                                               "panda", "cube")
    yield physics, reference
    physics.close()
    reference.close()


def test_the_engine_by_name():
    assert "physics" in ENGINES
    with make_engine("physics", "panda", "cube") as engine:
        assert isinstance(engine, RobotPhysicsEngine) and engine.name == "physics"


def test_sigma_zero_force_closure_and_contacts(engines):
    physics, reference = engines
    for g in shipped_grasps("cube", "panda"):
        a = evaluate_grasp(g, sigma=0.0, n=1, engine=physics)
        b = evaluate_grasp(g, sigma=0.0, n=1, engine=reference)
        assert a.p_fc == b.p_fc == 1.0, g.id
        assert physics.hold.world.pin is None  # the object was free while the hand closed
        assert np.array_equal(a.draws.finger, b.draws.finger)
        assert np.array_equal(a.draws.link, b.draws.link)
        distance = np.linalg.norm(a.draws.points - b.draws.points, axis=-1)
        assert np.all(distance <= POINT_TOL), (g.id, distance)
        # the dynamic closing's own result: the jaws' final joint values
        result = physics.close_one(g.q0)
        assert set(result.joints) == {"panda_finger_joint1", "panda_finger_joint2"}


def test_outcomes_agree_on_the_same_draws(engines):
    same = total = 0
    for g in shipped_grasps("cube", "panda"):
        a, b = (evaluate_grasp(g, sigma=SIGMA, n=DRAWS, seed=SEED, engine=e)
                for e in engines)
        same += int((a.draws.outcome == b.draws.outcome).sum())
        total += DRAWS
    assert same >= SAME_OUTCOME * total, (same, total)


def test_cli_evaluate_takes_the_physics_engine(capsys):
    g = shipped_grasps("cube", "panda")[0]
    assert main(["evaluate", "--robot", "panda", "--object", "cube", "--grasp", "0",
                 "--sigma", str(SIGMA), "--samples", "10", "--engine", "physics",
                 "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    expected = evaluate_grasp(g, sigma=SIGMA, n=10, seed=0, engine="physics")
    assert result["robot"] == "panda" and result["samples"] == 10
    assert result["p_fc"] == expected.p_fc and result["outcomes"] == expected.counts


def test_the_default_robots_physics_is_every_robots():
    """The default robot's physics engine by name is every robot's
    (``RobotPhysicsEngine``: its description's motors), and at sigma 0 every draw is the
    nominal closing (the same Q as the evaluation's nominal Q)."""
    grasp = shipped_grasps("spray_flask")[4]
    with make_engine("physics", "kuka_sdh", "spray_flask") as engine:
        assert isinstance(engine, RobotPhysicsEngine)
    still = evaluate_grasp(grasp, sigma=0.0, n=2, seed=SEED, engine="physics")
    assert still.q_mean == still.q_nominal  # at sigma 0 every draw is the nominal closing
