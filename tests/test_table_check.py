"""The support table in the description robots' closings.

What each test proves:
- ``test_table_check_matches_pybullet``: the fast closing's table test (GJK on the links'
  collision geometry as the closing reads it) against pybullet's closest points between
  each link of the robot's own URDF and a box body (an independent distance code on the
  URDF's shapes), link by link, for the default robot and the Panda; links within a band of
  touching, where the two geometry readings may differ, are left out and counted.
- ``test_the_engines_mark_draws_in_the_table``: with a table, the fast engine and the
  reference (pybullet's queries) mark the same draws ``start_collision``; every other draw
  is what it is without the table.
- ``test_the_physics_engine_marks_draws_in_the_table``: the physics engine, whose simulation
  has no arm, marks the draws the fast engine's table test flags, and only those.
- ``test_the_default_robots_table_check_is_the_probes``: the default robot's fast engine's
  table test (the one its closing runs), the reference engine's (the description's
  :attr:`~kinegrasp_env.montecarlo.description_engine.RobotEngine.in_table`) and its bespoke
  pybullet probe flag the same draws.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.closing.link_geometry import robot_link_geometry
from kinegrasp_env.closing.table_check import TableCheck
from kinegrasp_env.montecarlo.draws import START_COLLISION
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.placement import place_object
from kinegrasp_env.world.sim import BulletWorld, pybullet
from kinegrasp_env.world.support import SupportTable
from kinegrasp_env.world.table_body import table_body

#: Links nearer than this to touching (pybullet's distance, metres) are not compared: the
#: closing reads a cylinder as its inscribed 16-sided prism, pybullet as a cylinder (1 mm of
#: a 5 cm radius apart at most), and a mesh as its hull alike.
BAND = 2e-3


@pytest.fixture(scope="module", autouse=True)
def own_catalog(tmp_path_factory):
    """The placed copy lives in a catalog of its own."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("KINEGRASP_HOME", str(tmp_path_factory.mktemp("table_home")))
        place_object("cube", as_name="cube_on_table", table=SupportTable(), force=True)
        yield


def _draws(robot: str, n: int, sigma: float, seed: int) -> np.ndarray:
    """(n, dof) configurations about the robot's shipped cube grasps."""
    grasps = shipped_grasps("cube", robot)
    rng = np.random.default_rng(seed)
    q = np.array([grasps[i % len(grasps)].q0 for i in range(n)], dtype=float)
    arm = load_robot(robot).arm_dof
    q[:, :arm] += rng.normal(0.0, sigma, (n, arm))
    return q


@pytest.mark.parametrize("robot", ["kuka_sdh", "panda"])
def test_table_check_matches_pybullet(robot):
    description = load_robot(robot)
    obj = load_object("cube_on_table")
    geometry = robot_link_geometry(description)
    check = TableCheck(geometry, obj)
    q = _draws(robot, 40, 0.08, 1)
    poses = Kinematics(description.model).forward(q, list(geometry))
    world = BulletWorld()
    bullet = world.bullet
    try:
        body = bullet.loadURDF(str(description.urdf), useFixedBase=True,
                               flags=pybullet.URDF_USE_IMPLICIT_CYLINDER)
        infos = [bullet.getJointInfo(body, j) for j in range(bullet.getNumJoints(body))]
        joint = {info[1].decode(): j for j, info in enumerate(infos)}
        index = {info[12].decode(): j for j, info in enumerate(infos)}
        index[description.model.base_link] = -1
        for link in index.values():
            bullet.changeDynamics(body, link, collisionMargin=0.0)
        table = table_body(bullet, obj)
        ours = {link: check.hits(link, obj.pose_inverse @ poses[link]) for link in geometry}
        agree = near = hits = 0
        for i in range(len(q)):
            for name, value in description.model.expand(q[i]).items():
                bullet.resetJointState(body, joint[name], float(value))
            for link in geometry:
                rows = bullet.getClosestPoints(body, table, BAND, linkIndexA=index[link])
                distance = min((row[8] for row in rows), default=np.inf)
                if abs(distance) < BAND:
                    near += 1
                    continue
                assert ours[link][i] == (distance < 0), (link, i, distance)
                agree += 1
                hits += int(ours[link][i])
    finally:
        world.close()
    # both verdicts occur, and the band leaves most links compared
    assert hits > 10 and agree - hits > 10 and near < 0.1 * (agree + near), (hits, agree, near)


@pytest.mark.parametrize("robot", ["kuka_sdh", "panda"])
def test_the_engines_mark_draws_in_the_table(robot):
    # near the grasps, and arms swung far (into the table: the Panda's jaws never reach it
    # near its cube grasps)
    q = np.vstack([_draws(robot, 16, 0.01, 2), _draws(robot, 16, 0.3, 3)])
    with make_engine("fast", robot, "cube_on_table") as fast, \
            make_engine("pybullet", robot, "cube_on_table") as reference, \
            make_engine("fast", robot, "cube") as free:
        a, b, c = fast.run(q), reference.run(q), free.run(q)
    np.testing.assert_array_equal(a.outcome, b.outcome)
    in_table = (a.outcome == START_COLLISION) & (c.outcome != START_COLLISION)
    assert in_table.any() and (~in_table).any()
    assert len(set(a.outcome[~in_table].tolist())) > 1
    np.testing.assert_array_equal(a.outcome[~in_table], c.outcome[~in_table])
    np.testing.assert_array_equal(a.quality[~in_table], c.quality[~in_table])


def test_the_physics_engine_marks_draws_in_the_table():
    """The physics engine (the hand alone simulated) takes the fast engine's table test:
    exactly the draws in the table are start collisions, the others are simulated."""
    q = _draws("panda", 12, 0.3, 3)
    with make_engine("fast", "panda", "cube_on_table") as fast:
        in_table = fast.hand.table_hits(q)
    rows = np.concatenate([np.flatnonzero(in_table)[:2], np.flatnonzero(~in_table)[:2]])
    assert rows.size == 4
    with make_engine("physics", "panda", "cube_on_table") as physics:
        draws = physics.run(q[rows])
    np.testing.assert_array_equal(draws.outcome == START_COLLISION, in_table[rows])


def test_the_default_robots_table_check_is_the_probes():
    """The fast and the reference engine's table tests of the default robot against
    pybullet's own closest points (``tests/table_probe_reference.TableProbe``:
    the robot's URDF and the table box in a world of their own)."""
    from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
    from tests.table_probe_reference import TableProbe

    q = _draws(DEFAULT_ROBOT, 60, 0.05, 3)
    fast = make_engine("fast", DEFAULT_ROBOT, "cube_on_table")
    reference = make_engine("pybullet", DEFAULT_ROBOT, "cube_on_table")
    probe = TableProbe(load_object("cube_on_table"))
    try:
        expected = probe.hits(q)
        assert 0 < expected.sum() < len(q)
        # the fast engine's own test (its closing's start check), then the engines' in_table
        np.testing.assert_array_equal(fast.hand.table_hits(q), expected)
        np.testing.assert_array_equal(reference.in_table(reference.check(q)), expected)
    finally:
        fast.close()
        reference.close()
        probe.close()
