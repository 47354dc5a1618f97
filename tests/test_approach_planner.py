"""The approach planner: grasps of a hand that is not a parallel jaw (the SDH, planned as a
description robot with its reference closing), checked with the fast engine's closing of the
same configurations (its distances from the object's distance grid and GJK bounds, not
pybullet's)."""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.hand_frame import hand_frame
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.toolkit.approach_planner import aligned
from kinegrasp_env.toolkit.grasp_planner import plan_grasps


def test_aligned_is_a_rotation_taking_a_to_b():
    """On random unit pairs, parallel and opposite ones included: orthonormal, det +1, a to
    b (to 1e-12)."""
    rng = np.random.default_rng(0)
    vectors = rng.normal(size=(40, 2, 3))
    vectors /= np.linalg.norm(vectors, axis=2, keepdims=True)
    pairs = [*vectors, (vectors[0, 0], vectors[0, 0]), (vectors[1, 0], -vectors[1, 0])]
    for a, b in pairs:
        rot = aligned(a, b)
        assert np.allclose(rot @ rot.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-12)
        assert np.allclose(rot @ a, b, atol=1e-12)


@pytest.mark.parametrize("obj", ["cube", "drill"])
def test_the_sdh_is_planned_as_a_description(obj):
    """Grasps of the three-finger SDH through the description pipeline: each in force
    closure by the fast engine too, with the same Q (3.1e-8 relative measured; 1e-6 held),
    its palm approaching along the drawn direction (the hand frame's
    approach axis in the world, to the IK's 1e-7)."""
    description = load_robot("kuka_sdh")
    grasps = plan_grasps(description, obj, count=2, seed=0)
    assert len(grasps) == 2
    fast = make_engine("fast", description, obj)
    draws = fast.run(np.array([g.q0 for g in grasps]))
    fast.close()
    assert list(draws.outcome) == [FORCE_CLOSURE] * 2
    assert np.allclose(draws.quality, [g.q_nominal for g in grasps], rtol=1e-6, atol=0.0)
    frame, kin = hand_frame(description), Kinematics(description.model)
    for grasp in grasps:
        assert grasp.robot == "kuka_sdh" and grasp.meta["planner"] == "approach"
        palm = kin.pose(grasp.q0, description.palm_link)[0]
        assert np.allclose(palm @ np.append(frame.approach, 0.0),
                           np.append(grasp.meta["direction"], 0.0), atol=1e-6)
