"""The balanced grip of a description robot whose fingers are chains of revolute joints
(:mod:`kinegrasp_env.physics.balanced_grip`).

What it proves: the grip joints derived from a description (closing joints, the spread joints
below the palm, which links each joint moves, torque bounds, fingertips) are the ones the
default robot's own holding test writes out by hand (``GRIP_JOINTS``, ``SPREAD_FINGERS``,
the assumed torques), joint by joint in the same pybullet world; and with them the holding
test of the SDH run as a description holds the nominal cube and mug grasps about as often as
the SDH's own test, where pressing every motor at full effort (the jaws' rule) drops them.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.physics.balanced_grip import balances, grip_layout
from kinegrasp_env.robot.catalog import load_robot


def test_the_sdh_balances_and_the_panda_grips_as_jaws():
    assert balances(load_robot("kuka_sdh"))
    assert not balances(load_robot("panda"))  # prismatic jaws
    with pytest.raises(ValueError, match="it grips as jaws do"):
        grip_layout(load_robot("panda"))


def test_the_layout_is_the_sdh_holding_tests_own_grip_joints():
    """In one pybullet world of the SDH, at a closed pre-shape: axes (closing positive),
    points on them, fingers, first links carried, torque bounds and fingertips equal those of
    the SDH's holding test (its joint list and torques written by hand)."""
    from kinegrasp_env.physics.hold_runner import GRIP_JOINTS
    from kinegrasp_env.physics.pybullet_closing import MotorSettings
    from kinegrasp_env.physics.pybullet_hold import grip_joints_now
    from kinegrasp_env.physics.pybullet_world import PhysicsWorld
    from kinegrasp_env.robot.default_robot import hand_joint_values
    from kinegrasp_env.world.objects import load_object

    world = PhysicsWorld(load_object("mug"))
    try:
        world.reset(np.eye(4), hand_joint_values(np.array([0.6, 0.2, 0.5, 0.3, 0.6, 0.1, 0.4])))
        own = grip_joints_now(world, MotorSettings())
        layout = grip_layout(load_robot("kuka_sdh"))
        derived = layout.joints(*world.joint_frames(list(layout.names)),
                                np.array([world.link_pose(t)[:3, 3] for t in layout.tips]))
    finally:
        world.close()
    order = [layout.names.index(name) for name in GRIP_JOINTS]
    assert sorted(layout.names) == sorted(GRIP_JOINTS)
    for field in ("axes", "origins", "fingers", "first_links", "lower", "upper", "tips"):
        np.testing.assert_allclose(np.asarray(getattr(derived, field), dtype=float)[order],
                                   np.asarray(getattr(own, field), dtype=float),
                                   atol=1e-12, err_msg=field)


@pytest.mark.parametrize("simulator", ["pybullet", "mujoco"])
def test_the_sdh_as_a_description_holds_its_nominal_grasps(simulator):
    """The quick holding test of ``kuka_sdh`` through the description robots' holding test
    on the 24 nominal cube and mug grasps: measured 15 held in pybullet and 12 in MuJoCo
    with the balanced grip (the SDH's own test: 17 and 15; the jaws' rule: 1 and 3;
    ``python benchmarks/description_hold.py --sigmas 0 --samples 1``). At least 10 must
    hold."""
    if simulator == "mujoco":
        pytest.importorskip("mujoco")
    from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine
    from kinegrasp_env.physics.protocol import HELD, QUICK_PROTOCOL
    from kinegrasp_env.physics.robot_hold import QUICK_MOTORS
    from kinegrasp_env.world.grasps import shipped_grasps

    held = 0
    for obj in ("cube", "mug"):
        q = np.array([g.q0 for g in shipped_grasps(obj)])
        # the description robots' holding test (quick_hold_engine gives the SDH its own)
        with RobotHoldEngine("kuka_sdh", obj, protocol=QUICK_PROTOCOL, motors=QUICK_MOTORS,
                             simulator=simulator) as engine:
            held += int((engine.run_hold(q)[1].outcome == HELD).sum())
    assert held >= 10


def test_a_joint_that_closes_negative_gets_the_mirrored_spring():
    """The same hand state written with one joint's URDF axis flipped (its closing direction
    -1, its angle and axis negated) is the same physical grip: that joint's spring target and
    torque at every angle are the mirror of the original's, the others' unchanged."""
    import dataclasses

    from kinegrasp_env.physics.grip_forces import GripContact

    layout = grip_layout(load_robot("kuka_sdh"))
    j = layout.names.index("f2_proximal")
    rng = np.random.default_rng(0)
    # a tripod: three distal contacts on a ball of radius 0.04 m about the origin
    points = 0.04 * np.array([[1.0, 0.0, 0.0], [-0.5, 0.8, 0.0], [-0.5, -0.8, 0.0]])
    contacts = [GripContact(f, 1, points[f], -points[f] / 0.04) for f in range(3)]
    count = len(layout.names)
    # every joint 5 cm above its finger's contact, its axis horizontal: closing turns the
    # tip towards the centre
    origins = np.array([points[f] + [0.0, 0.0, 0.05] for f in layout.fingers])
    tips = np.array([points[f] for f in layout.fingers])
    axes = np.cross([0.0, 0.0, 1.0], tips / 0.04)
    stall = rng.uniform(-0.5, 0.5, count)
    pose = np.eye(4)
    args = (pose, np.zeros(3), 0.8, 0.0015)
    plain = layout.spring(contacts, axes, origins, tips, stall, *args)
    flip = np.ones(count)
    flip[j] = -1.0
    mirrored = dataclasses.replace(layout, directions=layout.directions * flip)
    other = mirrored.spring(contacts, axes * flip[:, None], origins, tips, stall * flip, *args)
    assert plain is not None and other is not None and plain.loaded[j]
    np.testing.assert_allclose(other.targets, plain.targets * flip, atol=1e-12)
    np.testing.assert_allclose(other.stall, stall * flip)
    angles = stall + rng.uniform(-0.01, 0.01, count)
    np.testing.assert_allclose(other.torques(angles * flip), plain.torques(angles) * flip,
                               atol=1e-12)


def test_a_tip_on_its_joints_axis_advances_by_the_farthest_contact():
    """``reach``: a joint whose fingertip (the tip link's frame) lies on its axis, or nearer
    it than half the lever of the farthest contact the joint carries, advances by that
    contact; a tip with a lever of its own is kept. Hand-built: two joints on finger 0, axis
    z through the origin, both carrying both contacts on links >= 0; the levers are read off
    the coordinates."""
    from kinegrasp_env.physics.balanced_grip import reach
    from kinegrasp_env.physics.grip_forces import GripContact, GripJoints

    joints = GripJoints(axes=np.array([[0.0, 0.0, 1.0]] * 2), origins=np.zeros((2, 3)),
                        fingers=np.zeros(2, dtype=int), first_links=np.zeros(2, dtype=int),
                        lower=np.zeros(2), upper=np.ones(2),
                        tips=np.array([[0.0, 0.0, 0.05], [0.04, 0.0, 0.0]]))
    contacts = [GripContact(0, k, np.array(point), np.array([1.0, 0.0, 0.0]))
                for k, point in enumerate(([0.03, 0.0, 0.01], [0.0, 0.06, 0.02]))]
    assert joints.carries(contacts).all()
    tips = reach(joints, contacts)
    np.testing.assert_allclose(tips[0], [0.0, 0.06, 0.02])  # on the axis: the farthest
    np.testing.assert_allclose(tips[1], [0.04, 0.0, 0.0])  # 0.04 >= 0.5 x 0.06: kept


def test_no_built_in_finger_is_an_independent_jaw():
    """The creep rule of fingers driven each on its own (``independent_jaws``) leaves the
    built-in hands as they were: the Panda's second finger mimics its first, and every SDH
    finger has two motors; a gripper of two knuckles with no mimic has two such fingers
    (tests/test_flat_pads.py builds one)."""
    from kinegrasp_env.physics.hand_motors import independent_jaws
    from kinegrasp_env.robot.catalog import load_robot

    assert independent_jaws(load_robot("panda")) == frozenset()
    assert independent_jaws(load_robot("kuka_sdh")) == frozenset()
