"""The holding test of a description robot in MuJoCo: the Panda's hand, and the xArm's linkage
gripper (written here from pybullet_data, as a user adds it).

Independent references: MuJoCo's own URDF reader and forward kinematics against the
project's URDF kinematics; the URDF's ``<limit>`` and ``<mimic>`` tags read here with
ElementTree; the cube's faces (30 mm from its centre, a hand derivation from its 60 mm
edge) for the contact points; the kinematic reference closing (pybullet closest points, no
dynamics) for the contact normals; MuJoCo's contact forces (``mj_contactForce``: what its
solver reports) for the jaws' efforts; pybullet's holding test for the verdicts.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pybullet_data
import pytest
import yaml

pytest.importorskip("mujoco")

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli.main import main
from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.physics.mujoco_robot_hold import (
    JawServos,
    MujocoRobotHold,
    description_hand,
)
from kinegrasp_env.physics.protocol import HELD, HoldProtocol
from kinegrasp_env.physics.robot_agreement import closing_agreement
from kinegrasp_env.physics.robot_hold import RobotHold
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.description import (
    RobotDescription,
    load_description,
    parse_description,
)
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import load_object

PANDA_URDF = asset_path("robots", "panda", "panda.urdf")
PANDA_YAML = asset_path("robots", "panda", "panda.yaml")
JAWS = ("panda_finger_joint1", "panda_finger_joint2")
XARM_URDF = Path(pybullet_data.getDataPath()) / "xarm" / "xarm6_with_gripper.urdf"
#: The cube's half edge, metres (its faces in its own frame).
HALF_EDGE = 0.03
#: A contact point's distance from the cube face it presses: MuJoCo's contacts penetrate by
#: 0.01 mm under the jaws' 20 N (measured); 0.05 mm held.
FACE_TOL = 5e-5
#: The contact normal against the kinematic closing's: measured 4e-6 degrees; 0.5 held.
ANGLE_TOL = np.radians(0.5)
#: MuJoCo collides the finger's hull, whose pad is two faces 2 degrees apart: the pad touches
#: the face at a corner of its hull, 11.1 mm from the kinematic closing's patch centre on
#: every cube grasp (measured); 12 mm held (the pad is 21 mm wide, 27 mm long).
POINT_TOL = 12e-3


def urdf_joints(urdf: Path) -> dict[str, ET.Element]:
    return {j.get("name"): j for j in ET.parse(urdf).getroot().findall("joint")}


@pytest.fixture(scope="module")
def panda_cube():
    description, obj = load_robot("panda"), load_object("cube")
    simulator = MujocoRobotHold(description, obj, 0.5, HoldProtocol())
    yield simulator
    simulator.close()


def test_mujoco_reads_the_cut_hand_as_the_urdf_has_it(panda_cube):
    """The hand's joints and limits as the URDF states them; each finger link where the
    project's forward kinematics puts it at a configuration (MuJoCo's kinematics of the
    same URDF, root at the palm pose)."""
    world = panda_cube.world
    joints = urdf_joints(PANDA_URDF)
    assert sorted(world.joint_names) == sorted(JAWS)
    for name in JAWS:
        limit = joints[name].find("limit")
        np.testing.assert_allclose(world.model.joint(name).range,
                                   [float(limit.get("lower")), float(limit.get("upper"))])
    description = panda_cube.description
    q = shipped_grasps("cube", "panda")[0].q0.copy()
    q[-1] = 0.013
    values = {k: v for k, v in description.model.expand(q).items() if k in world.qpos_adr}
    world.reset(panda_cube.palm_poses(q)[0], values)
    kinematics = Kinematics(description.model)
    for link in ("panda_leftfinger", "panda_rightfinger"):
        np.testing.assert_allclose(world.link_pose(link),
                                   kinematics.pose(q[None], link)[0], atol=1e-9)


def test_closing_contacts_lie_on_the_faces_the_kinematic_closing_finds(panda_cube):
    """Per shipped cube grasp: one contact per jaw, on the cube face it presses (30 mm from
    the centre along its normal), its normal the kinematic closing's, within the pad of its
    patch centre."""
    kinematic = RobotWorld(panda_cube.description, panda_cube.world.obj)
    try:
        for grasp in shipped_grasps("cube", "panda"):
            agreement = closing_agreement(panda_cube, kinematic, grasp.q0)
            assert agreement.start_collision == (False, False)
            assert not agreement.physics_only and not agreement.kinematic_only
            assert len(agreement.pairs) == 2, grasp.id
            assert agreement.max_angle <= ANGLE_TOL, (grasp.id, agreement)
            assert agreement.max_distance <= POINT_TOL, (grasp.id, agreement)
            closing, _ = panda_cube.close_hand(grasp.q0)
            for contact in closing.contacts:
                depth = abs(float(contact.point @ contact.normal))  # to the face plane
                assert abs(depth - HALF_EDGE) <= FACE_TOL, (grasp.id, contact)
    finally:
        kinematic.close()


def test_jaws_press_with_their_urdf_efforts(panda_cube):
    """Each jaw's normal force on the gripped cube, as MuJoCo's solver reports it, is its
    motor's effort limit read from the URDF."""
    _, result = panda_cube.run_draw(shipped_grasps("cube", "panda")[0].q0)
    joints = urdf_joints(PANDA_URDF)
    efforts = [float(joints[j].find("limit").get("effort")) for j in JAWS]
    np.testing.assert_allclose(result.forces_gripped, efforts, rtol=0.02)


@pytest.mark.parametrize("effort", [8.0, 35.0])
def test_description_efforts_reach_mujoco_too(effort):
    """The description's efforts, below and above the URDF's 20 N (MuJoCo's URDF reader
    caps a joint's force at its <limit effort> unless told otherwise), press the cube."""
    data = yaml.safe_load(PANDA_YAML.read_text())
    data["efforts"] = {"panda_finger_joint1": effort}
    description = parse_description(data, PANDA_YAML)
    simulator = MujocoRobotHold(description, load_object("cube"), 0.5, HoldProtocol())
    _, result = simulator.run_draw(shipped_grasps("cube", "panda")[0].q0)
    np.testing.assert_allclose(result.forces_gripped, [effort, effort], rtol=0.02)


@pytest.mark.parametrize(("obj", "grasp", "held"), [("cube", 0, True), ("cube", 1, True),
                                                     ("cube", 2, True), ("drill", 0, False),
                                                     ("spray_flask", 2, False)])
def test_verdicts_are_pybullets(obj, grasp, held):
    """The two simulators agree on grasps whose verdict pybullet gives clearly: cube grasps
    0-2 hold in both (measured: pybullet drops cube grasp 3 and MuJoCo holds it, left out),
    the Panda's drill and spray flask grasps drop in both."""
    description, target = load_robot("panda"), load_object(obj)
    q = shipped_grasps(obj, "panda")[grasp].q0
    verdicts = []
    for cls in (RobotHold, MujocoRobotHold):
        simulator = cls(description, target, 0.5, HoldProtocol())
        try:
            verdicts.append(simulator.run_draw(q)[1].outcome == HELD)
        finally:
            simulator.close()
    assert verdicts == [held, held]


def test_a_linkage_gripper_closes_its_followers_on_the_urdf_mimics(tmp_path):
    """The xArm's gripper in free space: half-way through its closing every mimic joint of
    the URDF is at its multiplier times its driver (the closing's follower rule as MuJoCo
    equalities; 1e-3 rad held), and closed to the stall no joint is beyond its URDF limit by
    more than 0.005 rad (MuJoCo's limits are soft; measured 0.0035)."""
    data = {"name": "xarm6", "urdf": str(XARM_URDF),
            "arm_joints": ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6"],
            "palm_link": "xarm_gripper_base_link", "hand_joints": ["drive_joint"],
            "close": {"drive_joint": 1}, "finger_links": ["left_finger", "right_finger"]}
    path = tmp_path / "xarm6.yaml"
    path.write_text(yaml.safe_dump(data))
    description = load_description(path)
    simulator = MujocoRobotHold(description, load_object("cube"), 0.5, HoldProtocol())
    world, q = simulator.world, np.zeros(7)  # the palm far above the cube
    joints = urdf_joints(XARM_URDF)

    def values() -> dict[str, float]:
        return dict(zip(world.joint_names, world.joint_states(world.joint_names)[0],
                        strict=True))

    world.reset(simulator.palm_poses(q)[0], {name: 0.0 for name in world.joint_names})
    JawServos(world, description, simulator.motors, simulator.holds)
    world.step(200)  # 0.2 s at the drive's 2 rad/s: half of its 0.85 rad
    value = values()
    assert 0.2 < value["drive_joint"] < 0.6
    leaders = {"drive_joint", "right_outer_knuckle_joint"}  # the fingers' first joints
    followers = [name for name in value
                 if joints[name].find("mimic") is not None and name not in leaders]
    assert len(followers) == 4
    for name in followers:
        mimic = joints[name].find("mimic")
        expected = float(mimic.get("multiplier", 1.0)) * value[mimic.get("joint")]
        assert abs(value[name] - expected) <= 1e-3, (name, value[name], expected)
    closing, _ = simulator.close_hand(q)
    assert not closing.contacts
    assert sorted(closing.joints) == sorted(m.joint for m in simulator.motors)  # every one
    for name, v in values().items():
        limit = joints[name].find("limit")
        assert float(limit.get("lower")) - 5e-3 <= v <= float(limit.get("upper")) + 5e-3, name


def test_validate_panda_in_mujoco(tmp_path, capsys):
    status = main(["validate", "--robot", "panda", "--object", "cube", "--sigma", "0",
                   "--samples", "1", "--simulator", "mujoco", "--json",
                   "--out", str(tmp_path / "out")])
    out, err = capsys.readouterr()
    assert status == 0, err
    summary = json.loads(out)
    assert summary["settings"]["simulator"] == "mujoco"
    assert [g["p_hold"] for g in summary["grasps"]][:3] == [1.0, 1.0, 1.0]


def panda_with_dae(tmp_path: Path, collision: bool) -> RobotDescription:
    """The Panda with its finger mesh named ``finger.dae`` (the OBJ's bytes) in the two
    fingers' visuals and, with ``collision``, in their collisions too."""
    import re

    text = PANDA_URDF.read_text()
    pattern = (r"(<{tag}>\s*(?:<origin[^>]*>\s*)?<geometry>\s*"
               r"<mesh filename=\"package://meshes/collision/)finger\.obj")
    for tag in ("visual", "collision") if collision else ("visual",):
        text, count = re.subn(pattern.format(tag=tag), r"\1finger.dae", text)
        assert count == 2, tag
    meshes = tmp_path / "meshes" / "collision"
    meshes.mkdir(parents=True)
    for mesh in (PANDA_URDF.parent / "meshes" / "collision").iterdir():
        (meshes / mesh.name).write_bytes(mesh.read_bytes())
    (meshes / "finger.dae").write_bytes((meshes / "finger.obj").read_bytes())
    (tmp_path / "panda.urdf").write_text(text)
    return parse_description(yaml.safe_load(PANDA_YAML.read_text()), tmp_path / "panda.yaml")


def test_a_collision_mesh_mujoco_cannot_read_is_refused_in_one_line(tmp_path):
    with pytest.raises(ValueError, match=r"MuJoCo reads STL and OBJ meshes, not finger\.dae"):
        description_hand(panda_with_dae(tmp_path, collision=True))


def test_a_visual_mesh_mujoco_cannot_read_is_dropped(tmp_path):
    """MuJoCo drops visuals: a DAE visual beside an OBJ collision mesh holds like the
    Panda."""
    simulator = MujocoRobotHold(panda_with_dae(tmp_path, collision=False), load_object("cube"),
                                0.5, HoldProtocol())
    assert simulator.run_draw(shipped_grasps("cube", "panda")[0].q0)[1].outcome == HELD
