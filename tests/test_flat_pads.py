"""A flat pad pressed on a face whose closest point lands on the face's edge is on that face.

Two flat faces in contact touch over a region, and a closest-point query returns an arbitrary
point of it; where that point falls on the face's border (the edge to the next face), the face
test alone finds two planes and took the contact for an edge contact, at the edge point, while
the other engine, whose query returned an inner point, scored it on the face at its patch
centre. The face a pad lies flat on is the one whose plane its collision geometry does not
cross (:func:`~kinegrasp_env.closing.contact_patch.flat_face`), decided by both engines on the
same geometry.

Independent references: the cube's faces and a box pad placed by hand (which face a pad lies
on is read off the construction); a user's gripper of two box jaws written here on the KUKA iiwa
of pybullet_data, whose reference engine takes its closest points from pybullet.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pybullet_data
import pytest
import yaml
from cli_helpers import run_in_process as run

from kinegrasp_env.closing.contact_patch import PATCH_DEPTH, flat_face
from kinegrasp_env.world.objects import load_object

HALF = 0.03  # the built-in cube's half size, metres
TOL = 5e-5


def box_pad(centre, size, turn=0.0) -> np.ndarray:
    """(1, 8, 3) the corners of a box pad (object frame) of full ``size`` about ``centre``,
    turned by ``turn`` radians about the y axis through the centre."""
    half = np.asarray(size) / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    c, s = np.cos(turn), np.sin(turn)
    turned = (corners * half) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T
    return (turned + np.asarray(centre))[None]


def test_a_pad_flat_on_a_face_at_its_edge_is_on_that_face():
    """The cube (its faces x = +-0.03 about its centre): a pad of 2 x 1 x 8 cm pressed flat on
    the +x face, reaching above the top edge, touches at a point of that edge: the +x face
    (the pad crosses the top face's plane, not the +x one); tilted by 1e-3 rad it dips 0.04
    mm past the edge, less than the 1 mm a pad is pressed in: the +x face still. Tilted by
    0.1 rad it dips 2 mm: no face. Flat on the top face, at its edge with +x: the top face."""
    cube = load_object("cube")
    centre_z = cube.center_of_mass[2]
    edge = np.array([[HALF, 0.0, centre_z + HALF]])
    flat = box_pad([HALF + 0.01, 0.0, centre_z + HALF - 0.02], [0.02, 0.01, 0.08])
    part, plane = flat_face(cube, edge, flat, TOL)
    assert part[0] == 0 and np.allclose(plane[0], [1, 0, 0, -HALF], atol=1e-9), plane
    for turn, face in ((1e-3, 0), (0.1, -1)):  # a corner of the pad turns about y past x
        pad = box_pad([HALF + 0.01, 0.0, centre_z + HALF - 0.02], [0.02, 0.01, 0.08], turn)
        dip = HALF - pad[0, :, 0].min()  # how far past the +x plane, by construction
        assert (dip < PATCH_DEPTH) == (face == 0), dip
        assert flat_face(cube, edge, pad, TOL)[0][0] == face, turn
    # tilted by 0.3 rad, its lowest end's edge on the cube's edge and the pad leaning out
    # above it: it crosses the top face's plane only, but no face of it lies on the +x face
    # (two of its corners touch): no face
    c, s = np.cos(0.3), np.sin(0.3)
    end = box_pad([HALF + 0.04 * s + 0.01 * c, 0.0, centre_z + HALF + 0.04 * c - 0.01 * s],
                  [0.02, 0.01, 0.08], turn=0.3)
    touching = np.abs(end[0, :, 0] - HALF) < 1e-12
    assert touching.sum() == 2 and np.allclose(end[0, touching, 2], centre_z + HALF)
    assert end[0, :, 0].min() >= HALF - 1e-12
    assert flat_face(cube, edge, end, TOL)[0][0] == -1
    on_top = box_pad([HALF - 0.02, 0.0, centre_z + HALF + 0.005], [0.08, 0.01, 0.01])
    part, plane = flat_face(cube, edge, on_top, TOL)
    assert part[0] == 0 and np.allclose(plane[0], [0, 0, 1, -(centre_z + HALF)], atol=1e-9)
    away = np.array([[HALF + 0.01, 0.0, centre_z]])  # off the surface: no plane near it
    assert flat_face(cube, away, flat, TOL)[0][0] == -1


IIWA = Path(pybullet_data.getDataPath()) / "kuka_iiwa" / "model.urdf"


def jaw(side: str, sign: int, mimic: str = "") -> str:
    """URDF text of one box jaw on a prismatic joint of the palm, at ``sign`` x 6 cm along
    y and closing towards the palm's centre; ``mimic``: the joint it follows, if any."""
    return f"""
  <joint name="finger_{side}_joint" type="prismatic">
    <parent link="gripper_palm"/><child link="finger_{side}"/>
    <origin xyz="0 0 0.04" rpy="0 0 0"/><axis xyz="0 {-sign} 0"/>
    <limit lower="0" upper="0.05" effort="50" velocity="0.2"/>{mimic}
  </joint>
  <link name="finger_{side}">
    <inertial><mass value="0.05"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0"
      izz="1e-5"/></inertial>
    <collision><origin xyz="0 {0.06 * sign} 0.04"/><geometry><box size="0.02 0.01 0.08"/>
    </geometry></collision>
  </link>"""


#: Two box jaws on one prismatic joint, the second a mimic, on a palm at the iiwa's flange.
JAWS = """
  <joint name="flange_joint" type="fixed">
    <parent link="lbr_iiwa_link_7"/><child link="gripper_palm"/>
    <origin xyz="0 0 0.045" rpy="0 0 0"/>
  </joint>
  <link name="gripper_palm">
    <inertial><mass value="0.5"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0"
      izz="0.001"/></inertial>
    <collision><origin xyz="0 0 0.02"/><geometry><box size="0.04 0.14 0.04"/></geometry>
    </collision>
  </link>""" + jaw("left", 1) + jaw(
    "right", -1, '\n    <mimic joint="finger_left_joint" multiplier="1" offset="0"/>') + """
</robot>
"""


@pytest.fixture()
def jaw_robot(tmp_path, monkeypatch, capsys):
    """The iiwa with two box jaws, added to a catalog of this test's own."""
    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    meshes = IIWA.parent / "meshes"
    text = IIWA.read_text().replace('filename="meshes/', f'filename="{meshes}/')
    (tmp_path / "jaws.urdf").write_text(re.sub(r"</robot>\s*$", JAWS, text))
    description = {"name": "iiwa_jaws", "urdf": "jaws.urdf",
                   "arm_joints": [f"lbr_iiwa_joint_{i}" for i in range(1, 8)],
                   "palm_link": "gripper_palm", "hand_joints": ["finger_left_joint"],
                   "close": {"finger_left_joint": 1}, "open": {"finger_left_joint": 0}}
    (tmp_path / "jaws.yaml").write_text(yaml.safe_dump(description))
    run(capsys, "robots", "add", str(tmp_path / "jaws.yaml"))
    return tmp_path


def test_box_jaws_score_alike_in_both_engines(jaw_robot, capsys):
    """Two planned cube grasps of the box-jaw gripper at sigma 0: both engines give the same
    outcome and Q (to 1e-6 relative). The second jaw's pad lies flat on a cube face past its
    top edge, where the fast engine's closest point fell on that edge: it scored Q 0.016
    against the reference's 0.059 at the planned pose of grasp 0 (and pybullet's own
    closest point, inside the face, agrees with the reference)."""
    run(capsys, "plan", "--robot", "iiwa_jaws", "--object", "cube", "--count", "2", "--seed",
        "0", "--out", "g.json")
    q = {}
    for engine in ("pybullet", "fast"):
        for grasp in ("0", "1"):
            payload = json.loads(run(capsys, "evaluate", "--grasps", "g.json", "--grasp", grasp,
                                     "--sigma", "0", "--samples", "1", "--engine", engine,
                                     "--json"))
            assert payload["p_fc"] == 1.0
            q[engine, grasp] = payload["q_nominal"]
    for grasp in ("0", "1"):
        assert q["fast", grasp] == pytest.approx(q["pybullet", grasp], rel=1e-6), q


def test_spanning_a_face_is_the_second_singular_value_of_the_points():
    """The batched test (a covariance's eigenvalues) against NumPy's SVD of each set of
    centred points, on random point sets with random subsets flagged; and the two hand
    cases: four corners of a 1 cm square span a face, four points on a line do not."""
    from kinegrasp_env.closing.contact_patch import spans_a_face

    rng = np.random.default_rng(0)
    points, on = rng.normal(size=(200, 8, 3)), rng.random((200, 8)) < 0.5
    svd = [on[i].sum() >= 3 and np.linalg.svd(points[i][on[i]] - points[i][on[i]].mean(axis=0),
                                              compute_uv=False)[1] > 0.3 for i in range(200)]
    batched = spans_a_face(points, on, 0.3)
    assert batched.tolist() == svd and 0 < batched.sum() < 200
    square = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [0.01, 0.01, 0]], dtype=float)
    line = np.array([[t, 0, 0] for t in (0, 0.01, 0.02, 0.03)], dtype=float)
    flags = np.ones((2, 4), dtype=bool)
    assert spans_a_face(np.stack([square, line]), flags, PATCH_DEPTH).tolist() == [True, False]


def test_a_finger_without_a_closing_joint_is_named(tmp_path, monkeypatch):
    """Two jaws on joints of their own, the description giving a close direction to one:
    the other finger has no closing joint, and the refusal says which joint wants one (it
    said the finger had no collision geometry on "( in jaws.urdf)": an empty list)."""
    from kinegrasp_env.robot.description import RobotDescriptionError, load_description

    meshes = IIWA.parent / "meshes"
    text = IIWA.read_text().replace('filename="meshes/', f'filename="{meshes}/')
    free = re.sub(r"\n\s*<mimic [^>]*/>", "", JAWS)
    (tmp_path / "jaws.urdf").write_text(re.sub(r"</robot>\s*$", free, text))
    description = {"name": "two_jaws", "urdf": "jaws.urdf",
                   "arm_joints": [f"lbr_iiwa_joint_{i}" for i in range(1, 8)],
                   "palm_link": "gripper_palm",
                   "hand_joints": ["finger_left_joint", "finger_right_joint"],
                   "close": {"finger_left_joint": 1}}
    (tmp_path / "jaws.yaml").write_text(yaml.safe_dump(description))
    with pytest.raises(RobotDescriptionError) as info:
        load_description(tmp_path / "jaws.yaml")
    assert str(info.value) == ("jaws.yaml: close: the finger ending at 'finger_right' has no "
                               "closing joint: give 'finger_right_joint' a close direction")
