"""A flat pad pressed on a face whose closest point lands on the face's edge is on that face.

Two flat faces in contact touch over a region, and a closest-point query returns an arbitrary
point of it; where that point falls on the face's border (the edge to the next face), the face
test alone finds two planes and took the contact for an edge contact, at the edge point, while
the other engine, whose query returned an inner point, scored it on the face at its patch
centre. The face a pad lies flat on is the one whose plane its collision geometry does not
cross (:func:`~kinegrasp_env.closing.pad_faces.flat_face`), decided by both engines on the
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

from kinegrasp_env.closing.contact_patch import PATCH_DEPTH
from kinegrasp_env.closing.pad_faces import flat_face
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


def test_a_pad_edge_across_a_face_is_on_that_face():
    """A 1 x 0.5 x 4 cm pad upright beside the cube's +x face, turned about z by t so that
    one of its vertical edges alone touches the face, running from 2 cm below the cube's top
    edge to 2 cm above it; its closest point given at the top edge: the +x face (a line
    contact reaching into the face), at t = 0.3 and 0.05 rad, and flat (t = 0). Turned 45
    degrees about y instead, its own edge lying along the cube's top edge: no face (it touches
    the edge, not a face), nor where that pad is longer than the cube's edge."""
    cube = load_object("cube")
    top = cube.center_of_mass[2] + HALF
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    for t in (0.3, 0.05, 0.0):
        c, s = np.cos(t), np.sin(t)
        pad = (corners * [0.005, 0.0025, 0.02]) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T
        pad += [HALF - pad[:, 0].min(), 0.0, top]
        edge_y = pad[np.argmin(pad[:, 0]), 1]
        part, plane = flat_face(cube, np.array([[HALF, edge_y, top]]), pad[None], TOL)
        assert part[0] == 0 and np.allclose(plane[0], [1, 0, 0, -HALF], atol=1e-9), (t, plane)
    for length in (0.005, 0.05):  # shorter than the cube's edge, and longer
        c = s = np.sqrt(0.5)
        pad = (corners * [0.005, length, 0.02]) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T
        low = pad[np.argmin(pad[:, 0] + pad[:, 2])]
        pad += np.array([HALF, 0.0, top]) - [low[0], 0.0, low[2]]
        assert flat_face(cube, np.array([[HALF, 0.0, top]]), pad[None], TOL)[0][0] == -1, length


def test_spanning_a_face_is_the_second_singular_value_of_the_points():
    """The batched test (a covariance's eigenvalues) against NumPy's SVD of each set of
    centred points, on random point sets with random subsets flagged; and the two hand
    cases: four corners of a 1 cm square span a face, four points on a line do not."""
    from kinegrasp_env.closing.pad_faces import spans_a_face

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


def knuckle(side: str, sign: int) -> str:
    """URDF text of one box finger (3 x 1.2 x 10 cm) on a revolute knuckle of the palm,
    5.5 cm out along y, turning about x towards the palm's axis."""
    lower, upper = (-0.2, 1.2) if sign > 0 else (-1.2, 0.2)
    box = '<origin xyz="0 0 0.05"/><geometry><box size="0.03 0.012 0.1"/></geometry>'
    return f"""
  <joint name="{side}_knuckle" type="revolute">
    <parent link="gripper_palm"/><child link="{side}_finger"/>
    <origin xyz="0 {0.055 * sign} 0.04"/><axis xyz="1 0 0"/>
    <limit lower="{lower}" upper="{upper}" effort="20" velocity="2"/>
  </joint>
  <link name="{side}_finger">
    <inertial><mass value="0.05"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0"
      izz="1e-5"/></inertial>
    <collision>{box}</collision>
  </link>"""


@pytest.fixture(scope="module")
def knuckles(tmp_path_factory):
    """The iiwa with two box fingers on knuckles of their own (no mimic: each driven on its
    own), added to a catalog of this module's own, and three planned cube grasps (g.json)."""
    from cli_helpers import run_cli

    folder = tmp_path_factory.mktemp("knuckles")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("KINEGRASP_HOME", str(folder / "home"))
        mp.chdir(folder)
        meshes = IIWA.parent / "meshes"
        text = IIWA.read_text().replace('filename="meshes/', f'filename="{meshes}/')
        hand = re.sub(r'\s*<joint name="finger_left_joint".*', "", JAWS, flags=re.S)
        hand += knuckle("left", 1) + knuckle("right", -1) + "\n</robot>\n"
        (folder / "knuckles.urdf").write_text(re.sub(r"</robot>\s*$", hand, text))
        description = {"name": "iiwa_knuckles", "urdf": "knuckles.urdf",
                       "arm_joints": [f"lbr_iiwa_joint_{i}" for i in range(1, 8)],
                       "palm_link": "gripper_palm",
                       "hand_joints": ["left_knuckle", "right_knuckle"],
                       "close": {"left_knuckle": 1, "right_knuckle": -1},
                       "open": {"left_knuckle": 0.0, "right_knuckle": 0.0}}
        (folder / "knuckles.yaml").write_text(yaml.safe_dump(description))
        ball = '<collision><origin xyz="0 0 0.1"/><geometry><sphere radius="0.01"/></geometry>'
        balled = (folder / "knuckles.urdf").read_text().replace(
            '<link name="left_finger">', '<link name="left_finger">\n    ' + ball +
            "</collision>", 1)
        (folder / "balled.urdf").write_text(balled)
        (folder / "balled.yaml").write_text(yaml.safe_dump(
            {**description, "name": "iiwa_balled", "urdf": "balled.urdf"}))
        for args in (("robots", "add", "knuckles.yaml"), ("robots", "add", "balled.yaml"),
                     ("plan", "--robot", "iiwa_knuckles", "--object", "cube", "--count", "3",
                      "--seed", "0", "--out", "g.json")):
            assert run_cli(*args).returncode == 0, args
        yield folder


@pytest.fixture()
def in_knuckles(knuckles, monkeypatch):
    monkeypatch.setenv("KINEGRASP_HOME", str(knuckles / "home"))
    monkeypatch.chdir(knuckles)
    return knuckles


def polytope_distance(a: np.ndarray, b: np.ndarray) -> float:
    """The distance (metres) between conv(a) and conv(b) (points (n, 3), (m, 3)): the least
    |a^T x - b^T y| over simplex weights x, y, by SciPy's SLSQP (independent of pybullet's GJK
    and of the package's own convex distance)."""
    from scipy.optimize import minimize

    n, m = len(a), len(b)

    def gap(z):
        d = a.T @ z[:n] - b.T @ z[n:]
        return d @ d

    cons = [{"type": "eq", "fun": lambda z: z[:n].sum() - 1.0},
            {"type": "eq", "fun": lambda z: z[n:].sum() - 1.0}]
    z0 = np.concatenate([np.full(n, 1.0 / n), np.full(m, 1.0 / m)])
    best = minimize(gap, z0, bounds=[(0.0, 1.0)] * (n + m), constraints=cons, method="SLSQP",
                    options={"ftol": 1e-16, "maxiter": 500})
    return float(np.sqrt(max(best.fun, 0.0)))


def box_corners(size) -> np.ndarray:
    """(8, 3) the corners of a box of ``size`` (3,) centred at the origin."""
    half = np.asarray(size) / 2.0
    return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half


def test_the_reference_measures_a_tilted_box_edge_exactly(in_knuckles):
    """pybullet keeps the URDF importer's 1 mm margin on a box (shrunk by 1 mm, rounded by
    1 mm at its edges), so the distance of a box finger turned towards the cube, its tip's
    edge nearest, came out up to 1 mm x (cos t + sin t - 1) too far. The reference scene
    measures such a link on margin-free hulls: its gap equals the polytope distance of the
    posed box and the cube (SLSQP) to 1e-7 m at several knuckle angles. A link that also has
    a ball keeps pybullet's own shapes: its gap is the least of the box's and the ball's
    exact distances (the ball's: its centre's distance to the cube less its radius)."""
    from kinegrasp_env.closing.scene import RobotScene
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.world.grasps import load_grasps

    cube = load_object("cube")
    cube_corners = box_corners([2 * HALF] * 3) @ cube.pose[:3, :3].T + cube.pose[:3, 3]
    pad = box_corners([0.03, 0.012, 0.1]) + np.array([0.0, 0.0, 0.05])
    q = np.asarray(load_grasps(in_knuckles / "g.json")[0].q0, dtype=float)
    for name in ("iiwa_knuckles", "iiwa_balled"):
        scene = RobotScene(load_robot(name), cube)
        try:
            for angle in (0.12, 0.16, 0.18):
                scene.set_configuration(np.concatenate([q[:7], [angle, -angle]]))
                pose = scene.model_pose("left_finger")
                placed = pad @ pose[:3, :3].T + pose[:3, 3]
                exact = polytope_distance(placed, cube_corners)
                if name == "iiwa_balled":
                    centre = pose[:3, :3] @ [0.0, 0.0, 0.1] + pose[:3, 3]
                    local = np.abs(cube.pose[:3, :3].T @ (centre - cube.pose[:3, 3]))
                    exact = min(exact, np.linalg.norm(np.maximum(local - HALF, 0.0)) - 0.01)
                assert scene.bullet_gap("left_finger") == pytest.approx(exact, abs=1e-7), \
                    (name, angle)
        finally:
            scene.close()


def test_a_link_edge_through_the_object_is_an_overlap(in_knuckles):
    """A finger's box (3 x 1.2 x 10 cm) posed by hand across the cube's vertical edge at x =
    0.03, y = -0.03 as a thin strip cutting the corner: its long axis along (1, 1, 0) / sqrt 2,
    its centre 9 mm in from the edge along the diagonal, so that the strip spans 3-15 mm in
    from the edge and 1.5 cm up and down. No corner of either body is inside the other and no
    edge of the cube meets the box (checked here), yet they overlap: the fast closing's exact
    distance read only the link's vertices and the object's edges and called it apart; its
    signed distance is now the depth of the box's deepest edge point, the middle of its inner
    long edge, 15 mm in from the cube's edge: 15 / sqrt 2 mm from either face."""
    from kinegrasp_env.closing.link_distances import LinkDistances
    from kinegrasp_env.closing.link_geometry import robot_link_geometry
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.world.sdf import grid_of

    cube = load_object("cube")
    a, b = np.array([1.0, 1.0, 0.0]) / np.sqrt(2), np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    edge = np.array([HALF, -HALF, cube.center_of_mass[2]])
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([[0.0, 0.0, 1.0], b, a])  # link x, y, z in the object frame
    pose[:3, 3] = edge - 0.009 * b - 0.05 * a  # the box's centre (link (0, 0, 0.05)) 9 mm in
    box = (box_corners([0.03, 0.012, 0.1]) + np.array([0.0, 0.0, 0.05])) @ pose[:3, :3].T
    box += pose[:3, 3]
    local = box - [0.0, 0.0, cube.center_of_mass[2]]
    assert not np.any(np.all(np.abs(local) < HALF, axis=1))  # no box corner in the cube
    inward = (edge - box.mean(axis=0)) @ b  # the cube's edge beyond the strip's outer face
    assert inward > 0.006
    geometry = robot_link_geometry(load_robot("iiwa_knuckles"))
    distances = LinkDistances({"left_finger": geometry["left_finger"]}, cube, grid_of(cube))
    d = distances.polytopes(pose[None], "left_finger")[0][0]
    assert d == pytest.approx(-0.015 / np.sqrt(2), abs=1e-6), d


@pytest.mark.expensive
def test_tilted_box_pads_close_alike_in_both_engines(in_knuckles):
    """Two box fingers on knuckles of their own: a turning pad meets a face with its tip's
    edge. pybullet keeps a 1 mm margin on a URDF box (shrunk by 1 mm, its edges rounded by
    1 mm), so an edge contact measured 1 mm x (cos t + sin t - 1) too far and the reference's
    fingers stopped 1.7e-3 rad late; and the fast engine's closest point on a pad edge lying
    across a face fell at either end of it, the face's edge or inside (the two fingers of one
    symmetric grasp differed), so one scored a face contact at its patch centre and the other
    an edge contact 1 cm away (Q 0.033 against the reference's 0.053). The reference engine
    (pybullet's closest points) and the fast one (the package's own convex distance) now close
    alike: the same contacts to 1e-6 m and Q to 1e-6 relative at the planned poses, and the
    same contacts to 1e-6 m on all but a few noisy draws (a finger starting within the start
    tolerance inside the cube, where pybullet's penetration depth is its own)."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.world.grasps import load_grasps

    grasps = load_grasps(in_knuckles / "g.json")
    robot = load_robot("iiwa_knuckles")
    rng = np.random.default_rng(0)
    q = np.concatenate([np.array([g.q0 for g in grasps]),
                        np.repeat([g.q0 for g in grasps], 40, axis=0)])
    q[len(grasps):, :7] += rng.normal(0.0, 0.0133, (len(q) - len(grasps), 7))
    runs = {}
    for name in ("pybullet", "fast"):
        with make_engine(name, robot, "cube") as engine:
            runs[name] = engine.run(q)
    ref, fast = runs["pybullet"], runs["fast"]
    np.testing.assert_array_equal(ref.outcome, fast.outcome)
    gap = np.nan_to_num(np.abs(ref.points - fast.points)).max(axis=(1, 2))
    nominal = slice(0, len(grasps))
    assert gap[nominal].max() < 1e-6, gap[nominal]
    np.testing.assert_allclose(fast.quality[nominal], ref.quality[nominal], rtol=1e-6)
    assert np.mean(gap > 1e-6) <= 0.02, np.sort(gap)[-5:]


@pytest.mark.expensive
def test_fingers_driven_each_on_its_own_stop_where_they_touch_in_physics(in_knuckles):
    """The physics closing (pybullet, the object free) of the two independently driven
    fingers stops each finger where it touches, as the kinematic closing (a geometric model,
    the object fixed) does: within 0.01 rad at the planned poses, and within 0.035 rad (the
    median over 15 noisy draws, at sigma 0.0133, of the larger of the two fingers'
    differences) where the free object gives way a little. Their motors stayed at full speed
    and effort after the touch and pushed the cube between them until the two efforts
    balanced, both fingers near +-0.19 rad whatever the draw (a median difference of 0.06
    rad; the user's gripper of this kind: P(FC) 0.33 against 0.89)."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.physics.hand_motors import independent_jaws
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.world.grasps import load_grasps

    assert independent_jaws(load_robot("iiwa_knuckles")) == {"left_knuckle", "right_knuckle"}
    q0 = np.array([g.q0 for g in load_grasps(in_knuckles / "g.json")])
    q = np.concatenate([q0, np.repeat(q0, 5, axis=0)])
    q[len(q0):, :7] += np.random.default_rng(0).normal(0.0, 0.0133, (len(q) - len(q0), 7))
    robot = load_robot("iiwa_knuckles")
    runs = {}
    for name in ("fast", "physics"):
        with make_engine(name, robot, "cube") as engine:
            runs[name] = engine.run(q)
    gap = np.abs(runs["physics"].hand - runs["fast"].hand).max(axis=1)
    assert gap[:len(q0)].max() < 0.01, gap[:len(q0)]
    noisy = gap[len(q0):]
    assert np.median(noisy[np.isfinite(noisy)]) < 0.035, np.round(noisy, 3)


@pytest.mark.expensive
def test_a_knuckle_grip_holds_the_object_where_it_closed(in_knuckles, capsys):
    """The holding test's balanced grip of the independently driven knuckles (their pads'
    frames, the fingertips, on the joints' axes): each spring is sized from the contact its
    joint carries farthest from the axis, so the grip keeps the object within 2 mm of where
    the closing left it (a spring sized from the tip on the axis was a constant torque that
    held no position: a 12.7 mm shift)."""
    import csv

    from kinegrasp_env.cli.main import main

    assert main(["validate", "--grasps", "g.json", "--grasp", "1", "--sigma", "0",
                 "--samples", "1", "--out", "val"]) == 0
    capsys.readouterr()
    with (in_knuckles / "val" / "draws.csv").open() as handle:
        shift = [float(row["grip_shift_mm"]) for row in csv.DictReader(handle)]
    assert len(shift) == 1 and shift[0] < 2.0, shift


def test_spanning_a_segment_is_the_largest_singular_value_of_the_points():
    """The batched test against NumPy's SVD of each set of flagged, centred points, and two
    hand cases: two points 1 cm apart span a segment, two 0.1 mm apart (under the 1 mm
    depth) do not, nor does one point."""
    from kinegrasp_env.closing.pad_faces import spans_a_segment

    rng = np.random.default_rng(1)
    points, on = rng.normal(size=(200, 8, 3)) * 1e-3, rng.random((200, 8)) < 0.4
    expected = []
    for p, m in zip(points, on, strict=True):
        kept = p[m] - p[m].mean(axis=0) if m.sum() else np.zeros((1, 3))
        expected.append(m.sum() >= 2 and np.linalg.svd(kept, compute_uv=False)[0] > PATCH_DEPTH)
    np.testing.assert_array_equal(spans_a_segment(points, on, PATCH_DEPTH), expected)
    two = np.zeros((3, 2, 3))
    two[0, 1, 0], two[1, 1, 0] = 0.01, 1e-4
    flags = np.array([[True, True], [True, True], [True, False]])
    np.testing.assert_array_equal(spans_a_segment(two, flags, PATCH_DEPTH),
                                  [True, False, False])


def test_a_pad_overhanging_an_edge_presses_the_face_it_lies_on():
    """A box pad lying on the cube's top face, 5 cm of it on the face and 3 cm past the
    edge x = 0.03, tilted about that edge by 0.016 rad (its inner end 0.8 mm above the face,
    its outer end 0.48 mm below the plane, in the air past the edge): the pad is pressed
    over the part of it on the face, whose centre is (0.005, 0, 0.03) by construction. The
    pressed depth was counted from the lowest vertex, the one hanging below the plane past
    the edge, so the footprint was the overhang alone, the clip to the face empty, and the
    contact stayed at the edge."""
    from kinegrasp_env.closing.contact_patch import patch_centre

    tilt = 0.016
    bottom = [(x, y, HALF - (x - HALF) * tilt) for x in (-0.02, 0.06) for y in (-0.01, 0.01)]
    pad = np.array(bottom + [(x, y, z + 0.01) for x, y, z in bottom])
    face = np.array([(x, y, HALF) for x in (-HALF, HALF) for y in (-HALF, HALF)])
    centre = patch_centre(pad, face, np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, HALF]))
    assert centre is not None
    np.testing.assert_allclose(centre, [0.005, 0.0, HALF], atol=1e-9)


def test_jaws_on_a_cylinders_edges_score_as_on_its_faces(jaw_robot, capsys):
    """A cylinder's mesh of 48 facets (radius 2.5 cm, 10 cm tall), turned so that two edges
    face the jaws, and turned by half a facet more, so that two faces do: a grasp from above
    closes the jaws on the edges of one, on the faces of the other. Both engines, both meshes,
    at sigma 0: in force closure, and the same Q to 2% (the faces lie 0.2% nearer the axis
    than the edges; the Q of jaws on the edges was 0, their contacts at the two ends of the
    pad's overlap with the edges, 5 cm apart in height, where the faces' were at its centre)."""
    import trimesh

    for name, turn in (("can_edges", 0.0), ("can_faces", np.pi / 48)):
        mesh = trimesh.creation.cylinder(radius=0.025, height=0.1, sections=48)
        mesh.apply_transform(trimesh.transformations.rotation_matrix(turn, [0, 0, 1]))
        mesh.export(jaw_robot / f"{name}.stl")
        run(capsys, "objects", "add", str(jaw_robot / f"{name}.stl"), "--name", name)
    q = {}
    for name in ("can_edges", "can_faces"):
        (jaw_robot / f"{name}.json").write_text(json.dumps({
            "object": name, "robot": "iiwa_jaws",
            "candidates": [{"id": "top", "position": [0, 0, 0.16],
                            "quaternion": [0, 1, 0, 0]}]}))
        for engine in ("pybullet", "fast"):
            payload = json.loads(run(capsys, "evaluate", "--grasps", f"{name}.json", "--grasp",
                                     "top", "--sigma", "0", "--samples", "1", "--engine",
                                     engine, "--json"))
            assert payload["p_fc"] == 1.0, (name, engine)
            q[name, engine] = payload["q_nominal"]
    for name in ("can_edges", "can_faces"):
        assert q[name, "fast"] == pytest.approx(q[name, "pybullet"], rel=1e-6), q
    assert q["can_edges", "fast"] == pytest.approx(q["can_faces", "fast"], rel=0.02), q


def test_a_pad_over_coplanar_parts_presses_all_of_them():
    """A 4 x 2 cm pad lying on the top of a box split at x = 0 into two convex halves (their
    top faces in one plane, z = 0.03), its centre at x = 0.01: the patch is the whole pad,
    its centre (0.01, 0, 0.03) and its corners the pad's four, by construction, whichever
    half the contact's face is named on. A block sitting on the top (its bottom face in the
    same plane, the object on its other side) is no face of the top and adds nothing. One
    half alone put the centre at (0.005, ...) or (0.015, ...). The second half raised by
    3 um (less than ``COPLANAR_TOL``) is still in the plane."""
    from kinegrasp_env.closing.contact_patch import PatchGeometry

    def box(low, high):
        return np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                         for z in (low[2], high[2])], dtype=float)

    halves = (box([-HALF, -HALF, -HALF], [0, HALF, HALF]), box([0, -HALF, -HALF], [HALF] * 3))
    block = box([0.01, 0.0, HALF], [0.03, 0.01, HALF + 0.01])
    patch = PatchGeometry((*halves, block))
    pad = box([-0.01, -0.01, HALF], [0.03, 0.01, HALF + 0.01])
    top = np.array([0.0, 0.0, 1.0, -HALF])
    for part, point in ((0, [-0.005, 0.0, HALF]), (1, [0.02, 0.0, HALF])):
        centre, found, corners, count = patch.patches(
            pad, np.eye(4)[None], np.array([part]), top[None], np.array([point]))
        assert found[0] and count[0] == 4
        np.testing.assert_allclose(centre[0], [0.01, 0.0, HALF], atol=1e-12)
        expected = {(x, y) for x in (-0.01, 0.03) for y in (-0.01, 0.01)}
        got = {(round(x, 12), round(y, 12)) for x, y in corners[0, :, :2]}
        assert got == expected and np.allclose(corners[0, :, 2], HALF)
    # a decomposition's parts of one flat side lie a few micrometres apart (3.4 um on a
    # user's open box): the second half's top raised by 3 um is still in the plane
    raised = PatchGeometry((halves[0], halves[1] + [0.0, 0.0, 3e-6], block))
    centre, found, _, _ = raised.patches(pad, np.eye(4)[None], np.array([0]), top[None],
                                         np.array([[-0.005, 0.0, HALF]]))
    np.testing.assert_allclose(centre[0], [0.01, 0.0, HALF], atol=1e-12)


def open_box(path: Path) -> None:
    """An open box (6 x 5 x 8 cm outside, 4 mm walls, open at the top), written to path."""
    import trimesh

    pytest.importorskip("manifold3d")
    outer = trimesh.creation.box([0.06, 0.05, 0.08])
    outer.apply_translation([0, 0, 0.04])
    inner = trimesh.creation.box([0.052, 0.042, 0.08])
    inner.apply_translation([0, 0, 0.08])
    trimesh.boolean.difference([outer, inner], engine="manifold").export(path)


def test_jaws_on_a_wall_of_several_parts_press_it_where_they_lie(jaw_robot, capsys):
    """The box jaws pinching an open box's 5 cm across its y walls, the palm at x = 0.011
    above it: each 2 x 8 cm pad lies on a wall over x 0.001 .. 0.021 and z 0.01 .. 0.09,
    past the rim at z = 0.08, so the patch is x 0.001 .. 0.021, z 0.01 .. 0.08, its centre
    (0.011, +-0.025, 0.045) by construction (to the IK's pose error, 2e-6 m here). The
    import splits each wall into several convex parts (checked here); both engines put the
    contacts there and give the same Q (to 1e-6 relative). With the patch clipped to one
    part's face the two engines took different parts: Q 0.044 against force closure lost."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.toolkit.candidates import load_candidates, solve_all

    open_box(jaw_robot / "open_box.stl")
    run(capsys, "objects", "add", str(jaw_robot / "open_box.stl"))
    obj = load_object("open_box")
    under = [p for p in obj.parts if p[:, 1].max() > 0.025 - 1e-9 and p[:, 0].min() < 0.021
             and p[:, 0].max() > 0.001]
    assert len(under) >= 2, "the wall under the pad is one part: the test proves nothing"
    (jaw_robot / "c.json").write_text(json.dumps({
        "object": "open_box", "robot": "iiwa_jaws",
        "candidates": [{"id": "side", "position": [0.011, 0, 0.13],
                        "quaternion": [0, 1, 0, 0]}]}))
    grasps, rejected = solve_all(*load_candidates(jaw_robot / "c.json"), robot="iiwa_jaws")
    assert not rejected
    q = np.asarray(grasps[0].q0)[None]
    quality = {}
    for engine in ("pybullet", "fast"):
        with make_engine(engine, "iiwa_jaws", "open_box") as closing:
            draws = closing.run(q)
        points = np.sort(draws.points[0, :draws.n_contacts[0]], axis=0)
        np.testing.assert_allclose(points, [[0.011, -0.025, 0.045], [0.011, 0.025, 0.045]],
                                   atol=1e-5)
        quality[engine] = float(draws.quality[0])
    assert quality["pybullet"] > 0
    assert quality["fast"] == pytest.approx(quality["pybullet"], rel=1e-6), quality


def padded_jaw(side: str, sign: int, mimic: str = "") -> str:
    """:func:`jaw` with its box on a pad link of its own, fixed to the jaw's moving link
    (turned a quarter about z there, the box's x and y sizes swapped to match): the same
    shape at the same place."""
    return jaw(side, sign, mimic).replace(
        f'<collision><origin xyz="0 {0.06 * sign} 0.04"/><geometry><box size="0.02 0.01 0.08"/>'
        "\n    </geometry></collision>", "") + f"""
  <joint name="pad_{side}_joint" type="fixed">
    <parent link="finger_{side}"/><child link="pad_{side}"/>
    <origin xyz="0 {0.06 * sign} 0.04" rpy="0 0 1.5707963267948966"/>
  </joint>
  <link name="pad_{side}">
    <collision><geometry><box size="0.01 0.02 0.08"/></geometry></collision>
  </link>"""


def test_pads_fixed_to_the_jaws_close_as_the_jaws_own_boxes(jaw_robot, capsys):
    """The box jaws with each box on a pad link fixed to its jaw (a Robotiq-style URDF):
    ``robots add`` moves the pads' boxes onto the jaws in its copy and says so; a top-down
    candidate on the cube then closes as the jaws with their own boxes (the URDF written by
    hand), in both engines: the same contact points (to 1e-9 m) and Q (to 1e-9 relative);
    and the planner plans for it (it measured the opening between the pad links, which have
    no shapes left, and failed). Without the move, the closings ignored the pads (the jaws
    met in the middle)."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.toolkit.candidates import load_candidates, solve_all

    text = (jaw_robot / "jaws.urdf").read_text()
    padded = text.replace(jaw("left", 1), padded_jaw("left", 1)).replace(
        jaw("right", -1, '\n    <mimic joint="finger_left_joint" multiplier="1" offset="0"/>'),
        padded_jaw("right", -1,
                   '\n    <mimic joint="finger_left_joint" multiplier="1" offset="0"/>'))
    assert padded.count("pad_left") == 3 and padded.count("<box") == text.count("<box")
    (jaw_robot / "padded.urdf").write_text(padded)
    data = yaml.safe_load((jaw_robot / "jaws.yaml").read_text())
    data.update(name="iiwa_pads", urdf="padded.urdf")
    (jaw_robot / "padded.yaml").write_text(yaml.safe_dump(data))
    said = run(capsys, "robots", "add", str(jaw_robot / "padded.yaml"))
    assert "pad_left's collision shapes (fixed to finger_left" in said, said
    # the planner measures the jaws' opening between the links that carry the pads
    run(capsys, "plan", "--robot", "iiwa_pads", "--object", "cube", "--count", "1", "--seed",
        "0", "--out", "pads.json")
    assert len(json.loads((jaw_robot / "pads.json").read_text())["grasps"]) == 1
    draws = {}
    for robot in ("iiwa_jaws", "iiwa_pads"):
        (jaw_robot / f"{robot}.json").write_text(json.dumps({
            "object": "cube", "robot": robot,
            "candidates": [{"id": "top", "position": [0.004, 0.0, 0.13],
                            "quaternion": [0, 1, 0, 0]}]}))
        grasps, rejected = solve_all(*load_candidates(jaw_robot / f"{robot}.json"),
                                     robot=robot)
        assert not rejected, rejected
        for engine in ("pybullet", "fast"):
            with make_engine(engine, robot, "cube") as closing:
                draws[robot, engine] = closing.run(np.asarray(grasps[0].q0)[None])
    for engine in ("pybullet", "fast"):
        own, pads = draws["iiwa_jaws", engine], draws["iiwa_pads", engine]
        assert own.n_contacts[0] == pads.n_contacts[0] == 2 and own.quality[0] > 0
        np.testing.assert_allclose(pads.points[0, :2], own.points[0, :2], atol=1e-9)
        assert pads.quality[0] == pytest.approx(own.quality[0], rel=1e-9)


def test_moved_collision_shapes_lie_where_pybullet_puts_the_pads():
    """A pad fixed below a bracket fixed below a finger link, each by a turned, shifted
    joint, its box turned and shifted again in the pad's frame: in the URDF with the box
    moved onto the finger link, the box's corners on the finger link are those on the pad
    in the URDF as written, as pybullet places them (its link state and collision shape
    frames: it composes the fixed joints' and the collision's origins itself), at two joint
    values: to 1e-7 m (pybullet keeps these frames in single precision: 7e-9 m apart,
    measured)."""
    import pybullet

    from kinegrasp_env.closing.contact_patch import link_hull_vertices
    from kinegrasp_env.robot.fixed_collisions import move_fixed_collisions
    from kinegrasp_env.robot.model import load_urdf
    from kinegrasp_env.world.sim import BulletWorld

    text = """<?xml version="1.0"?><robot name="r">
  <link name="base"/>
  <joint name="slide" type="revolute"><parent link="base"/><child link="finger"/>
    <origin xyz="0.01 0.02 0.03" rpy="0.1 0.2 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <link name="finger"><inertial><mass value="0.1"/><inertia ixx="1e-4" ixy="0" ixz="0"
    iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
  <joint name="bracket_joint" type="fixed"><parent link="finger"/><child link="bracket"/>
    <origin xyz="0.004 0.003 0.02" rpy="-0.5 0.1 0.7"/></joint>
  <link name="bracket"/>
  <joint name="pad_joint" type="fixed"><parent link="bracket"/><child link="pad"/>
    <origin xyz="0.02 -0.01 0.05" rpy="0.3 -0.2 1.1"/></joint>
  <link name="pad"><inertial><mass value="0.01"/><inertia ixx="1e-5" ixy="0" ixz="0"
    iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
    <collision><origin xyz="0.005 0.002 -0.01" rpy="-0.4 0.5 0.2"/>
      <geometry><box size="0.02 0.01 0.04"/></geometry></collision></link>
</robot>"""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        written, moved = Path(folder) / "written.urdf", Path(folder) / "moved.urdf"
        written.write_text(text)
        moved.write_text(move_fixed_collisions(text, load_urdf(written), [("pad", "finger")]))
        assert "<collision" not in moved.read_text().split('<link name="pad"')[1]
        corners = {}
        with BulletWorld() as sim:
            for name, path, link in (("written", written, 2), ("moved", moved, 0)):
                body = sim.bullet.loadURDF(str(path), useFixedBase=True,
                                           flags=pybullet.URDF_USE_IMPLICIT_CYLINDER)
                for angle in (0.0, 0.7):
                    sim.bullet.resetJointState(body, 0, angle)
                    corners[name, angle] = link_hull_vertices(sim.bullet, body, link)
    for angle in (0.0, 0.7):
        np.testing.assert_allclose(corners["moved", angle], corners["written", angle],
                                   atol=1e-7)
    assert np.ptp(corners["moved", 0.0] - corners["moved", 0.7]) > 0.01  # the joint moved
