"""A robot added as a user adds it plans, evaluates and ranks from the command line.

The stand-in user robot is the xArm 6 with its gripper from pybullet_data: a 6-joint arm (not
the 7 of the built-in robots) and a gripper whose two fingers are linkages of revolute joints
driven by one joint through mimic joints (not prismatic jaws), its meshes given as
``package://`` paths. Its description is written here at run time, in a data folder of this
test's own; the library knows none of its names.

Independent references: pybullet's own forward kinematics of the URDF (``getLinkState``) for
the palm pose a grasp records; the cube's mesh vertices (its support plane along each contact
normal) for the contacts; ``evaluate`` of each grasp alone for the numbers ``rank`` prints
(same seed: the same draws).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pybullet
import pybullet_data
import pytest
import yaml
from pybullet_utils.bullet_client import BulletClient

from kinegrasp_env.cli.main import main
from kinegrasp_env.world.objects import load_object

XARM_URDF = Path(pybullet_data.getDataPath()) / "xarm" / "xarm6_with_gripper.urdf"
ARM = ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6"]
PALM = "xarm_gripper_base_link"
FINGER_LINKS = ("left_finger", "right_finger")
#: The description a user writes for it (the schema of docs/guides/robot.md).
DESCRIPTION = {
    "name": "xarm6",
    "urdf": str(XARM_URDF),
    "arm_joints": ARM,
    "palm_link": PALM,
    "hand_joints": ["drive_joint"],
    "close": {"drive_joint": 1},
    "open": {"drive_joint": 0.0},
    "finger_links": list(FINGER_LINKS),
    "contact_model": "soft",
}
SIGMA = 0.0133
SAMPLES = 100


@pytest.fixture()
def workspace(tmp_path, monkeypatch):
    """A data folder of this test's own (the robot catalog lives in it), and the current
    folder (where the commands write) a scratch one."""
    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def run(capsys, *argv: str) -> str:
    """``kinegrasp ARGV`` in-process; its stdout (exit status 0 asserted)."""
    capsys.readouterr()
    status = main(list(argv))
    out, err = capsys.readouterr()
    assert status == 0, err
    return out


def bullet_palm_pose(arm: np.ndarray) -> np.ndarray:
    """(4, 4) world pose of the palm link at arm joints (6,): pybullet's own kinematics."""
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(str(XARM_URDF), useFixedBase=True)
        index = {}
        for j in range(client.getNumJoints(body)):
            info = client.getJointInfo(body, j)
            index[info[1].decode()] = j
            index[info[12].decode()] = j
        for name, value in zip(ARM, arm, strict=True):
            client.resetJointState(body, index[name], float(value))
        state = client.getLinkState(body, index[PALM], computeForwardKinematics=True)
        pose = np.eye(4)
        pose[:3, :3] = np.reshape(client.getMatrixFromQuaternion(state[5]), (3, 3))
        pose[:3, 3] = state[4]
    finally:
        client.disconnect()
    return pose


def test_the_xarm6_plans_evaluates_and_ranks(workspace, capsys):
    """``robots add`` of a description written here, then ``plan --robot``, ``evaluate``
    (P(FC) 1 at sigma 0, Q equal to the planned one) and ``rank`` (each candidate's numbers
    equal to ``evaluate`` of it alone, ordered by P(FC))."""
    path = workspace / "xarm6.yaml"
    path.write_text(yaml.safe_dump(DESCRIPTION))
    assert "xarm6: 6 arm joints" in run(capsys, "robots", "add", str(path))

    out = run(capsys, "plan", "--robot", "xarm6", "--object", "cube", "--count", "2",
              "--seed", "0", "--out", "g.json")
    assert "2 grasps of cube for robot xarm6 written to g.json" in out
    data = json.loads(Path("g.json").read_text())
    assert data["robot"] == "xarm6" and len(data["grasps"]) == 2

    cube = load_object("cube")
    vertices = np.asarray(cube.mesh.vertices)
    for g in data["grasps"]:
        q0 = np.array(g["q0"])
        assert q0.shape == (7,) and q0[6] == 0.0  # 6 arm joints, then the open gripper
        # measured difference to pybullet's kinematics 3.5e-8 (its link states are single
        # precision); margin: 1e-6
        assert np.allclose(g["palm_pose"], bullet_palm_pose(q0[:6]), atol=1e-6)
        contacts = g["contacts"]
        assert sorted(c["finger"] for c in contacts) == [0, 1]  # one contact per jaw
        normals = np.array([c["normal"] for c in contacts])
        points = np.array([c["point"] for c in contacts])
        assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
        assert normals[0] @ normals[1] < -0.999  # opposite faces: an antipodal grasp
        # on the face the inward normal pushes into: the mesh's support plane along -normal
        # (measured 0: a contact on a face is placed on its plane; margin: 1e-9 m)
        support = np.max(vertices @ -normals.T, axis=0)
        assert np.allclose(np.einsum("ij,ij->i", points, -normals), support, atol=1e-9)
        assert g["q_nominal"] > 0

    # the brief's form of the command: its printed P(FC)
    out = run(capsys, "evaluate", "--grasps", "g.json", "--grasp", "0", "--sigma", "0",
              "--samples", "5")
    assert "P(FC)   = 1.0000" in out and "force_closure 5" in out
    for i, g in enumerate(data["grasps"]):
        row = json.loads(run(capsys, "evaluate", "--grasps", "g.json", "--grasp", str(i),
                             "--sigma", "0", "--samples", "5", "--json"))
        assert row["p_fc"] == 1.0 and row["outcomes"]["force_closure"] == 5
        # the nominal closing again: the planner's contacts, to rounding
        assert row["q_mean"] == pytest.approx(g["q_nominal"], rel=1e-9)

    out = run(capsys, "rank", "g.json", "--sigma", str(SIGMA), "--samples", str(SAMPLES),
              "--out", "ranked.csv")
    assert "written to ranked.csv" in out
    rows = list(csv.DictReader(Path("ranked.csv").open()))
    assert sorted(r["id"] for r in rows) == ["0", "1"]
    p_fc = [float(r["p_fc"]) for r in rows]
    assert p_fc == sorted(p_fc, reverse=True)
    for r in rows:
        alone = json.loads(run(capsys, "evaluate", "--grasps", "g.json", "--grasp", r["id"],
                               "--sigma", str(SIGMA), "--samples", str(SAMPLES), "--json"))
        assert float(r["p_fc"]) == alone["p_fc"]
        # the CSV keeps 6 significant digits
        assert float(r["q_mean"]) == pytest.approx(alone["q_mean"], rel=1e-5)
        assert int(r["samples"]) == SAMPLES
        # regression pin (measured 0.74 and 0.78 at seed 0): noise of 0.0133 rad on six
        # joints costs a 6 cm cube grasp some but not most of its force closure
        assert 0.5 <= alone["p_fc"] < 1.0
