"""The reference closing of every robot (``closing.generic_reference.RobotWorld``), on the
default robot: its rounded links placed by the model's kinematics where pybullet's collision
frames are, pybullet queried per link as the whole robot's query says, the touches polished to
the exact gap's zero, the world left at the closed hand (joint values staged, then set in
pybullet)."""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.closing.close_rules import CONTACT_TOL, POLISH_TOL, QUERY_DISTANCE
from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.robot.default_robot import default_description
from kinegrasp_env.world.grasps import grasp_by_index
from kinegrasp_env.world.objects import load_object


def _matrix(bullet, quaternion) -> np.ndarray:
    return np.reshape(bullet.getMatrixFromQuaternion(quaternion), (3, 3))


def _bullet_frame(world: RobotWorld, link: str) -> np.ndarray:
    """(4, 4) a link's URDF frame from pybullet's own forward kinematics: the link's inertial
    frame (what its collision shapes hang from) and the inertial offset, composed in double
    precision (the link frame pybullet reports, entries 4 and 5, is single precision)."""
    bullet = world.bullet
    state = bullet.getLinkState(world.bodies["robot"], world.link_index[link],
                                computeForwardKinematics=True)
    inertial, offset = np.eye(4), np.eye(4)
    inertial[:3, :3], inertial[:3, 3] = _matrix(bullet, state[1]), state[0]
    offset[:3, :3], offset[:3, 3] = _matrix(bullet, state[3]), state[2]
    return inertial @ np.linalg.inv(offset)


def _random_configuration(world: RobotWorld, rng: np.random.Generator) -> np.ndarray:
    """(dof,) a configuration within the joint limits (finite ones; +-pi otherwise)."""
    lower, upper = world.model.lower, world.model.upper
    lower, upper = np.where(np.isfinite(lower), lower, -np.pi), np.where(
        np.isfinite(upper), upper, np.pi)
    return rng.uniform(lower, upper)


def test_rounded_link_frames_are_pybullets_collision_frames():
    """The frames the exact pairs use (the robot model's kinematics, double precision)
    against pybullet's forward kinematics of the same URDF, at random configurations."""
    rng = np.random.default_rng(21)
    with RobotWorld(default_description(), load_object("mug")) as world:
        assert len(world.rounded) == 6  # the SDH's six phalanxes
        worst = 0.0
        for _ in range(30):
            world.set_configuration(_random_configuration(world, rng))
            for link in world.rounded:
                worst = max(worst, float(np.abs(world.model_pose(link)
                                                - _bullet_frame(world, link)).max()))
    # measured 2.0e-11 (metres and rotation entries; pybullet's quaternions round-tripped)
    assert worst <= 1e-10, worst


def test_a_link_query_gives_the_whole_robot_querys_distances():
    """The closing asks pybullet about one link at a time: the same records' minimum as
    the whole robot's query restricted to that link, bit for bit."""
    grasp = grasp_by_index("drill", 0)
    rng = np.random.default_rng(3)
    with RobotWorld(default_description(), load_object("drill")) as world:
        compared = 0
        for _ in range(20):
            q = grasp.q0.copy()
            q[8:] += rng.uniform(0, 0.6, 6)
            world.set_configuration(q)
            whole: dict[int, float] = {}
            for rec in world.closest(QUERY_DISTANCE):
                whole[rec[3]] = min(rec[8], whole.get(rec[3], np.inf))
            for link, index in world.link_index.items():
                alone = min((rec[8] for rec in world.closest(QUERY_DISTANCE, link)),
                            default=None)
                assert alone == whole.get(index)
                compared += alone is not None
    assert compared > 20


@pytest.fixture(scope="module")
def closed():
    """100 noisy draws of the spray flask's grasp 2 (sigma 0.0133 rad) closed one by one:
    (configurations, per draw (result, pybullet's joint values after it, the exact gap of
    each contact's link then))."""
    grasp = grasp_by_index("spray_flask", 2)
    q = chunk_configurations(grasp.q0, 7, 0.0133, "gaussian", 102, 0, 100)
    out = []
    with RobotWorld(default_description(), load_object("spray_flask")) as world:
        fingers = world.description.fingers
        for row in q:
            result = world.auto_close(row)
            joints = {name: world.bullet.getJointState(world.bodies["robot"],
                                                       world.joint_index[name])[0]
                      for name in world.values}  # the movable joints
            # measured afresh from pybullet's state: a scene of the same robot and object
            gaps = [_fresh_gap(world, joints, fingers[c.finger].links[c.link])
                    for c in result.contacts]
            pairs = [world.rounded_pair(fingers[c.finger].links[c.link])[2]
                     for c in result.contacts]
            out.append((result, joints, gaps, pairs))
    return q, out


def _fresh_gap(world: RobotWorld, joints: dict[str, float], link: str) -> float:
    """The exact gap of a rounded link at the joint values ``joints`` (set anew)."""
    world.set_joint_values({name: value + 1.0 for name, value in joints.items()})
    world.set_joint_values(joints)
    return world.rounded_pair(link)[0]


def test_the_polish_reaches_the_exact_gaps_zero(closed):
    """Every contact's exact gap at the returned hand is within the contact tolerance, and
    the secant polish brings nearly all to POLISH_TOL (a second link of a finger may touch
    within CONTACT_TOL where the first one was polished); the contact point is the exact
    pair's point on the object."""
    _, out = closed
    gaps = np.abs([g for _, _, found, _ in out for g in found])
    assert gaps.size > 200
    assert gaps.max() <= CONTACT_TOL
    # measured: all 299 contacts of these draws
    assert np.mean(gaps <= POLISH_TOL) >= 0.99, (gaps.size, np.mean(gaps <= POLISH_TOL))
    for result, _, _, points in out:
        for contact, point in zip(result.contacts, points, strict=True):
            np.testing.assert_allclose(point, contact.point, atol=1e-9)


def test_the_world_is_left_at_the_closed_hand(closed):
    """After a closing, pybullet's joints are the closing's final values (and the pre-shape
    where the closing does not move a joint): the staged values were set."""
    q, out = closed
    spread = default_description().hand_joints[0]
    for row, (result, joints, _, _) in zip(q, out, strict=True):
        if result.start_collision:
            continue
        assert joints[spread] == row[7]
        for name, value in result.joints.items():
            assert joints[name] == value


@pytest.mark.pin
def test_outcomes_as_pinned(closed):
    """Regression pin: the reference engine's outcome counts (start collision, missed, no
    force closure, force closure) of the fixture's 100 draws (spray flask grasp 2, sigma
    0.0133 rad, seed 102, chunk 0), as this project's reference engine wrote them; it
    catches a change of the closing's outcomes, not an error (the outcomes are checked
    against pybullet's own queries in tests/test_agreement.py)."""
    q, _ = closed
    engine = make_engine("pybullet", DEFAULT_ROBOT, "spray_flask")
    try:
        draws = engine.run(q)
    finally:
        engine.close()
    assert np.bincount(draws.outcome, minlength=4).tolist() == [0, 1, 25, 74]
