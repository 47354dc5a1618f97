"""The balanced grip of a description robot whose fingers are chains of revolute joints
(:mod:`kinegrasp_env.physics.balanced_grip`).

What it proves: the grip joints derived from a description (closing joints, the spread joints
below the palm, which links each joint moves, torque bounds, fingertips) are the SDH's as
written out by hand; and with them the holding test of the SDH holds most nominal cube and
mug grasps in both simulators.
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


def test_the_layout_is_the_sdh_hands_grip_joints_written_by_hand():
    """The grip joints derived from the description (closing joints, the spread joints below
    the palm, the first link each moves, torque bounds, fingertips) against the SDH's written
    out by hand: six flexion joints pressing within 2.1 / 1.4 N m (the description's
    efforts), the two spread joints (fingers 1 and 2) either way within the URDF's 10 N m,
    each carrying every link of its finger."""
    layout = grip_layout(load_robot("kuka_sdh"))
    expected = {  # joint: (finger, first link, lower, upper, tip)
        **{f"f{f + 1}_proximal": (f, 0, 0.0, 2.1, f"f{f + 1}_tip") for f in range(3)},
        **{f"f{f + 1}_distal": (f, 1, 0.0, 1.4, f"f{f + 1}_tip") for f in range(3)},
        **{f"f{f + 1}_spread": (f, 0, -10.0, 10.0, f"f{f + 1}_tip") for f in range(2)},
    }
    assert sorted(layout.names) == sorted(expected)
    for j, name in enumerate(layout.names):
        finger, first, lower, upper, tip = expected[name]
        assert (layout.fingers[j], layout.first_links[j], layout.tips[j]) == (finger, first, tip)
        assert (layout.lower[j], layout.upper[j]) == pytest.approx((lower, upper), abs=1e-12)
    assert np.all(layout.directions == 1.0)


@pytest.mark.parametrize("simulator", ["pybullet", "mujoco"])
def test_the_sdh_as_a_description_holds_its_nominal_grasps(simulator):
    """The quick holding test of ``kuka_sdh`` on the 24 nominal cube and mug grasps: measured
    17 held in pybullet and 18 in MuJoCo with the balanced grip. At least 12 must hold."""
    if simulator == "mujoco":
        pytest.importorskip("mujoco")
    from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine
    from kinegrasp_env.physics.protocol import HELD, QUICK_PROTOCOL
    from kinegrasp_env.physics.robot_hold import QUICK_MOTORS
    from kinegrasp_env.world.grasps import shipped_grasps

    held = 0
    for obj in ("cube", "mug"):
        q = np.array([g.q0 for g in shipped_grasps(obj)])
        with RobotHoldEngine("kuka_sdh", obj, protocol=QUICK_PROTOCOL, motors=QUICK_MOTORS,
                             simulator=simulator) as engine:
            held += int((engine.run_hold(q)[1].outcome == HELD).sum())
    assert held >= 12


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
