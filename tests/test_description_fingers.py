"""Fingers derived from the URDF when a description names no ``finger_links``.

A linkage gripper (a Robotiq 2F-style four-bar per side: outer knuckle -> inner finger ->
pad, and an inner knuckle whose far end the URDF's tree leaves unattached) is two fingers,
its pads the tips: the inner knuckles are the four-bars' bars, leaves of the tree but no
fingertips. Written here as a URDF of its own (no file of the library's), plus the xArm
gripper as pybullet_data ships it. Given explicitly, ``finger_links`` keeps its rule (the
tips are the leaves of the links named), and the shipped robots keep their fingers.
"""

from __future__ import annotations

from pathlib import Path

import pybullet_data
import pytest
import yaml

from kinegrasp_env.robot.catalog import BUILTIN, load_robot
from kinegrasp_env.robot.description import load_description
from kinegrasp_env.robot.description_fields import RobotDescriptionError
from kinegrasp_env.robot.linkage import linkage_bars

BOX = '<collision><geometry><box size="0.01 0.02 {length}"/></geometry></collision>'


def link(name: str, length: float | None = 0.04) -> str:
    """A link, with a box of collision geometry unless ``length`` is None."""
    body = "" if length is None else BOX.format(length=length)
    return f'<link name="{name}">{body}</link>'


def joint(name: str, parent: str, child: str, *, xyz: str = "0 0 0.04", axis: str = "1 0 0",
          kind: str = "revolute", mimic: tuple[str, float] | None = None) -> str:
    follow = f'<mimic joint="{mimic[0]}" multiplier="{mimic[1]}"/>' if mimic else ""
    limit = '<limit lower="0" upper="0.8" effort="10" velocity="1"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
            f'{limit}{follow}</joint>')


def linkage_urdf(layout: str) -> str:
    """A wrist joint, the palm, then per side (left: y > 0, right: y < 0) a linkage cut open.

    ``layout="palm"`` (the Robotiq 2F and xArm layout): outer knuckle (left: the driving
    joint; right: its mimic) -> inner finger (a mimic, turning back) -> pad (fixed; a frame,
    without collision geometry: a finger touches with the links it moves), and the
    inner knuckle, a mimic hanging from the palm. ``layout="finger"``: a three-joint finger
    (outer knuckle -> middle -> inner finger -> pad), its bar a mimic hanging from the outer
    knuckle (a four-bar coupling the phalanges)."""
    parts = [link("base"), link("palm", 0.02),
             joint("wrist", "base", "palm", axis="0 0 1", xyz="0 0 0.1")]
    for side, sign, mult in (("left", 1, None), ("right", -1, ("drive", 1.0))):
        outer, finger, pad, knuckle, middle = (f"{side}_{n}" for n in (
            "outer_knuckle", "inner_finger", "pad", "inner_knuckle", "middle"))
        axis = f"{sign} 0 0"
        parts += [link(outer), link(finger), link(pad, None), link(knuckle, 0.03),
                  joint("drive" if side == "left" else f"{side}_outer_joint", "palm", outer,
                        xyz=f"0 {0.03 * sign} 0.05", axis=axis, mimic=mult),
                  joint(f"{side}_pad_joint", finger, pad, kind="fixed",
                        xyz=f"0 {-0.005 * sign} 0.03")]
        before_finger = outer
        if layout == "finger":
            parts += [link(middle), joint(f"{side}_middle_joint", outer, middle,
                                          axis=axis, mimic=("drive", 0.5))]
            before_finger = middle
        parts += [joint(f"{side}_finger_joint", before_finger, finger,
                        xyz=f"0 {0.03 * sign} 0.04", axis=f"{-sign} 0 0",
                        mimic=("drive", 1.0)),
                  joint(f"{side}_knuckle_joint", "palm" if layout == "palm" else outer,
                        knuckle, xyz=f"0 {0.015 * sign} 0.065", axis=axis,
                        mimic=("drive", 1.0))]
    return f'<?xml version="1.0"?><robot name="linkage">{"".join(parts)}</robot>'


def write(tmp_path: Path, urdf: str, **description) -> Path:
    (tmp_path / "linkage.urdf").write_text(urdf)
    data = {"name": "linkage", "urdf": "linkage.urdf", "arm_joints": ["wrist"],
            "palm_link": "palm", "hand_joints": ["drive"], "close": {"drive": 1},
            **description}
    path = tmp_path / "linkage.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


HAND_LINKS = ("left_outer_knuckle", "left_inner_finger", "left_pad", "left_inner_knuckle",
              "right_outer_knuckle", "right_inner_finger", "right_pad",
              "right_inner_knuckle")


@pytest.mark.parametrize("layout", ["palm", "finger"])
def test_a_linkage_gripper_is_two_fingers_ending_at_its_pads(tmp_path, layout):
    """No ``finger_links``: the inner knuckles (one joint off a longer chain that moves with
    the same actuator) are no fingertips; the pads (the distal links) are. The knuckles
    stay finger links: they move with the hand and may touch the object."""
    d = load_description(write(tmp_path, linkage_urdf(layout)))
    middle = {"palm": (), "finger": ("middle",)}[layout]
    assert d.fingertip_links == ("left_pad", "right_pad")
    assert [f.tip for f in d.fingers] == ["left_pad", "right_pad"]
    assert [f.joints for f in d.fingers] == [
        ("drive", *(f"left_{m}_joint" for m in middle), "left_finger_joint"),
        ("right_outer_joint", *(f"right_{m}_joint" for m in middle), "right_finger_joint")]
    assert [f.links for f in d.fingers] == [
        (f"{s}_outer_knuckle", *(f"{s}_{m}" for m in middle), f"{s}_inner_finger")
        for s in ("left", "right")]
    assert [f.directions for f in d.fingers] == [(1,) * (2 + len(middle))] * 2
    assert set(d.finger_links) == set(HAND_LINKS) | {f"{s}_{m}" for s in ("left", "right")
                                                     for m in middle}
    assert d.contact_model == "soft"  # the default of a two-finger hand


def test_finger_links_given_keep_the_leaves_as_tips(tmp_path):
    """``finger_links`` named: the tips are the leaves of the links named, as before (the
    knuckles too when named)."""
    urdf = linkage_urdf("palm")
    every = load_description(write(tmp_path, urdf, finger_links=list(HAND_LINKS)))
    assert every.fingertip_links == ("left_pad", "left_inner_knuckle", "right_pad",
                                     "right_inner_knuckle")
    assert len(every.fingers) == 4 and every.contact_model == "point"
    pads = load_description(write(tmp_path, urdf, finger_links=["left_pad", "right_pad"]))
    assert pads.fingertip_links == ("left_pad", "right_pad")
    assert pads.finger_links == ("left_pad", "right_pad")


def test_a_pad_with_collision_geometry_fixed_below_a_finger_link_is_refused(tmp_path):
    """A finger touches the object with the links its closing joints move: collision
    shapes on a link fixed below one of them would never touch, so the description read as
    it is is refused, naming the pad, its joint and the link to move its shapes to (which
    ``robots add`` does in its copy: test_flat_pads.py)."""
    urdf = linkage_urdf("palm").replace('<link name="left_pad"></link>',
                                        link("left_pad", 0.01))
    with pytest.raises(RobotDescriptionError, match=(
            "^linkage.yaml: urdf: link 'left_pad' has collision geometry and is fixed "
            r"\(joint 'left_pad_joint'\) to 'left_inner_finger', which a closing joint "
            "moves; .* give 'left_inner_finger' 'left_pad''s collision shapes in "
            r"linkage.urdf \(and drop them from 'left_pad'; `kinegrasp robots add` does so "
            r"in its copy\)$")):
        load_description(write(tmp_path, urdf))
    found = []
    load_description(write(tmp_path, urdf), fixed_pads=found)
    assert found == [("left_pad", "left_inner_finger")]


def test_a_urdf_of_primitives_alone_is_added_to_the_catalog(tmp_path, monkeypatch, capsys):
    """A URDF without a mesh (boxes only): ``robots add`` copies it into the entry's
    ``files/`` folder (which no mesh made) and the catalog loads it back."""
    from kinegrasp_env.cli.main import main

    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    assert main(["robots", "add", str(write(tmp_path, linkage_urdf("palm")))]) == 0, \
        capsys.readouterr().err
    assert load_robot("linkage").urdf == tmp_path / "home/robots/linkage/files/linkage.urdf"


#: The shipped robots' fingertips, as load_robot gave them before linkage bars were told
#: apart (and after): the URDFs' distal links, one per finger. The SDH-like hand's
#: ``f*_tip`` are frames fixed to the distal phalanges (no collision geometry: a tip is
#: not required to have any); the Panda's jaws are two one-joint fingers, one a mimic.
SHIPPED_TIPS = {
    "kuka_sdh": ("f1_tip", "f2_tip", "f3_tip"),
    "panda": ("panda_leftfinger", "panda_rightfinger"),
}
SHIPPED_JOINTS = {
    "kuka_sdh": (("f1_proximal", "f1_distal"), ("f2_proximal", "f2_distal"),
                 ("f3_proximal", "f3_distal")),
    "panda": (("panda_finger_joint1",), ("panda_finger_joint2",)),
}


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_shipped_robots_keep_their_fingers(name):
    """Every built-in robot (none names finger_links) keeps its fingertips and fingers."""
    assert set(SHIPPED_TIPS) == set(BUILTIN)
    d = load_robot(name)
    assert d.fingertip_links == SHIPPED_TIPS[name]
    assert tuple(f.tip for f in d.fingers) == SHIPPED_TIPS[name]
    assert tuple(f.joints for f in d.fingers) == SHIPPED_JOINTS[name]


def test_the_xarm_gripper_is_the_fingers_its_pads_name(tmp_path):
    """pybullet_data's xArm gripper (its inner knuckles hang from the gripper base, mimics of
    drive_joint): without finger_links, the fingers it has with its pads named."""
    urdf = Path(pybullet_data.getDataPath()) / "xarm" / "xarm6_with_gripper.urdf"
    data = {"name": "xarm6", "urdf": str(urdf),
            "arm_joints": ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6"],
            "palm_link": "xarm_gripper_base_link", "hand_joints": ["drive_joint"],
            "close": {"drive_joint": 1}}
    derived, named = tmp_path / "derived.yaml", tmp_path / "named.yaml"
    derived.write_text(yaml.safe_dump(data))
    named.write_text(yaml.safe_dump({**data, "finger_links": ["left_finger", "right_finger"]}))
    d, n = load_description(derived), load_description(named)
    assert d.fingertip_links == n.fingertip_links == ("left_finger", "right_finger")
    assert d.fingers == n.fingers
    assert {"left_inner_knuckle", "right_inner_knuckle"} <= set(d.finger_links)


def test_only_a_one_joint_bar_beside_a_longer_chain_of_its_actuators_is_dropped():
    """The rule alone: a coupled thumb of two joints, a leaf on an actuator of its own, an
    equally long coupled jaw and a leaf off a different chain all stay fingertips."""
    drive = {j: "a" for j in ("a", "b", "c", "t1", "t2", "k", "m")} | {"x": "x"}
    assert linkage_bars({"tip": ["a", "b", "c"], "thumb": ["t1", "t2"]}, drive) == set()
    assert linkage_bars({"tip": ["a", "b"], "own": ["x"]}, drive) == set()
    assert linkage_bars({"left": ["a"], "right": ["m"]}, drive) == set()
    assert linkage_bars({"tip": ["a", "b", "c"], "bar": ["k"]}, drive) == {"bar"}
    assert linkage_bars({"tip": ["a", "b", "c"], "bar": ["a", "k"]}, drive) == {"bar"}
    assert linkage_bars({"tip": ["a", "b", "c"], "off": ["m", "k"]}, drive) == set()


def test_box_shapes_are_drawn_at_their_urdf_size(tmp_path):
    """The drawn geometry (the report's 3-D scene, the hand frame) of a box is the box the
    URDF gives: the palm's box of 0.01 x 0.02 x 0.02 m (a collision box, which pybullet also
    shows as its visual) spans exactly that (pybullet reports a box's full extents; drawn as
    half extents, it spanned twice the size)."""
    import numpy as np

    from kinegrasp_env.robot.picture import robot_geometry

    description = load_description(write(tmp_path, linkage_urdf("palm")))
    shapes = [s for s in robot_geometry(description, []).shapes if s.link == "palm"]
    assert len(shapes) == 1
    np.testing.assert_allclose(np.ptp(shapes[0].vertices, axis=0), [0.01, 0.02, 0.02],
                               atol=1e-9)


@pytest.mark.parametrize("old, new, message", [
    ('<parent link="left_inner_finger"/><child link="left_pad"/>',
     '<parent link="left_inner_fingr"/><child link="left_pad"/>',
     "joint 'left_pad_joint' has parent link 'left_inner_fingr', which is not a link of the "
     "file"),
    ('<child link="left_pad"/>', '<child link="left_padd"/>',
     "joint 'left_pad_joint' has child link 'left_padd', which is not a link of the file"),
    ('<mimic joint="drive"', '<mimic joint="driev"',
     "joint '[a-z_]+' mimics 'driev', which is not a joint of the file"),
])
def test_a_urdf_typo_is_named(tmp_path, old, new, message):
    """A joint naming a link or a mimicked joint the URDF does not have is refused naming the
    joint and the name (it read "joints not connected to the root", "expected one root link",
    or asked to list the missing joint in hand_joints)."""
    urdf = linkage_urdf("palm")
    assert old in urdf
    with pytest.raises(RobotDescriptionError, match=message):
        load_description(write(tmp_path, urdf.replace(old, new, 1)))
