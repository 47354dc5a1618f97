"""Candidates given as palm poses in the object frame (kinegrasp_env.toolkit.candidates):
IK round trip, ``rank``/``evaluate`` on a palm-pose file, and bad entries."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pybullet
import pytest
from cli_helpers import run_cli
from scipy.spatial.transform import Rotation

from kinegrasp_env.robot.default_robot import PALM_LINK, kuka_sdh, urdf_path
from kinegrasp_env.robot.palm_pose import PalmCandidate, quaternion_matrix
from kinegrasp_env.toolkit.candidates import solve_all
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import load_object

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "palm_pose_candidates.json"
#: Contacts of the round trip against the shipped ones: measured <= 6e-11 m on all 12 drill
#: grasps (the IK lands on the shipped configuration to ~2e-10 rad); a 1e-8 margin.
CONTACT_TOL = 1e-8


def pybullet_palm(q: np.ndarray) -> np.ndarray:
    """(4, 4) palm frame at q (14,) from pybullet's own forward kinematics (independent of
    the package's kinematics that IK iterates on)."""
    client = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(urdf_path()), useFixedBase=True, physicsClientId=client)
        joints, palm = {}, None
        for j in range(pybullet.getNumJoints(body, physicsClientId=client)):
            info = pybullet.getJointInfo(body, j, physicsClientId=client)
            joints[info[1].decode()] = j
            if info[12].decode() == PALM_LINK:
                palm = j
        for name, value in kuka_sdh().expand(q).items():
            pybullet.resetJointState(body, joints[name], float(value), physicsClientId=client)
        state = pybullet.getLinkState(body, palm, computeForwardKinematics=True,
                                      physicsClientId=client)
    finally:
        pybullet.disconnect(client)
    pose = np.eye(4)
    pose[:3, :3] = np.array(pybullet.getMatrixFromQuaternion(state[5])).reshape(3, 3)
    pose[:3, 3] = state[4]
    return pose


def test_quaternion_matrix_matches_scipy():
    quats = Rotation.random(20, random_state=3).as_quat()  # [x, y, z, w]
    for quat in quats:
        assert np.allclose(quaternion_matrix(quat), Rotation.from_quat(quat).as_matrix(),
                           atol=1e-12)


def test_shipped_palm_poses_round_trip():
    """Shipped drill grasps' palm poses, in the object frame, solve to configurations whose
    palm (pybullet FK) is the target to 1e-6 m / 1e-6 rad, with the shipped contacts."""
    obj = load_object("drill")
    shipped = [shipped_grasps("drill")[i] for i in (0, 2, 7)]
    candidates = [PalmCandidate(g.id, np.linalg.inv(obj.pose) @ g.palm_pose, g.hand.copy())
                  for g in shipped]
    grasps, rejected = solve_all("drill", candidates)
    assert rejected == []
    for want, got in zip(shipped, grasps, strict=True):
        reached = pybullet_palm(got.q0)
        assert np.abs(reached[:3, 3] - want.palm_pose[:3, 3]).max() < 1e-6
        turn = Rotation.from_matrix(reached[:3, :3].T @ want.palm_pose[:3, :3]).magnitude()
        assert turn < 1e-6
        assert got.points.shape == want.points.shape
        assert np.abs(got.points - want.points).max() < CONTACT_TOL
        assert np.abs(got.normals - want.normals).max() < CONTACT_TOL
        assert np.array_equal(got.fingers, want.fingers)
        assert abs(got.q_nominal - want.q_nominal) < CONTACT_TOL


def test_an_elbow_the_first_ik_branch_cannot_reach_is_a_default_robot_grasp():
    """The mug's shipped grasps 2, 5 and 10 as palm poses at elbow 0.4 rad: the self-motion
    of the IK's first solution leaves the joint limits before 0.4 rad (checked with the
    default robot's own IK, robot/ik.py, written apart from the description's self-motion);
    the default robot's candidates are solved as every robot's, on further IK branches, so
    each is a grasp: its palm at the pose by pybullet's own forward kinematics (1e-6 m,
    rad), its elbow angle 0.4 rad as robot/ik.py measures it, its joints within the model's
    limits and its hand at the candidate's pre-shape."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.ik import ArmIK
    from kinegrasp_env.robot.kinematics import Kinematics

    obj = load_object("mug")
    ik = ArmIK(Kinematics(kuka_sdh()))
    chosen = [shipped_grasps("mug")[i] for i in (2, 5, 10)]
    candidates = [PalmCandidate(g.id, np.linalg.inv(obj.pose) @ g.palm_pose, g.hand.copy(),
                                0.4) for g in chosen]
    home = np.concatenate([load_robot("kuka_sdh").home_arm(), np.zeros(7)])
    for g in chosen:
        seed = home.copy()
        seed[7:] = g.hand
        first = ik.solve(g.palm_pose, seed, rng=np.random.default_rng(0))
        assert first.success[0]
        assert not ik.set_elbow_angle(first.q[0], 0.4)[1][0]
    grasps, rejected = solve_all("mug", candidates)
    assert rejected == []
    for want, got in zip(chosen, grasps, strict=True):
        reached = pybullet_palm(got.q0)
        assert np.abs(reached[:3, 3] - want.palm_pose[:3, 3]).max() < 1e-6
        assert Rotation.from_matrix(reached[:3, :3].T @ want.palm_pose[:3, :3]).magnitude() < 1e-6
        assert abs(float(ik.elbow_angle(got.q0[None])[0]) - 0.4) < 1e-6
        assert kuka_sdh().within_limits(got.q0[None])[0]  # the branch within the limits
        np.testing.assert_array_equal(got.q0[7:], want.hand)


def test_rank_example_file_ranks_reachable_and_lists_rejected(tmp_path):
    out = tmp_path / "r.csv"
    proc = run_cli("rank", str(EXAMPLE), "--samples", "40", "--seed", "0", "--engine", "fast",
                   "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    assert sorted(r["id"] for r in rows) == sorted(
        ["shipped0", "shipped1", "shipped3", "shipped6_spread", "shipped6_elbow"])
    p = [float(r["p_fc"]) for r in rows]
    assert p == sorted(p, reverse=True)
    with out.with_name("r.csv.rejected.csv").open() as handle:
        rejected = {r["id"]: r["reason"] for r in csv.DictReader(handle)}
    assert rejected == {"far_away": "unreachable", "from_below": "unreachable",
                        "inside_object": "arm_collision"}
    for cid, reason in rejected.items():
        assert f"candidate {cid} rejected: {reason}" in proc.stderr


def test_evaluate_palm_pose_candidate_and_rejected_one(tmp_path):
    proc = run_cli("evaluate", "--grasps", str(EXAMPLE), "--grasp", "shipped1", "--samples",
                   "20", "--engine", "fast", "--json")
    assert proc.returncode == 0, proc.stderr
    shipped = shipped_grasps("drill")[1]
    assert abs(json.loads(proc.stdout)["q_nominal"] - shipped.q_nominal) < CONTACT_TOL
    proc = run_cli("evaluate", "--grasps", str(EXAMPLE), "--grasp", "far_away", "--samples",
                   "20", "--engine", "fast")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1].startswith(
        "kinegrasp evaluate: error: candidate far_away of ")
    assert "unreachable" in proc.stderr


GOOD = {"id": "c", "position": [0.0, 0.0, 0.3], "quaternion": [1.0, 0.0, 0.0, 0.0],
        "spread": 0.0}


@pytest.mark.parametrize("change, message", [
    ({"position": None}, "candidate c: missing field 'position'"),
    ({"quaternion": [1.0, 0.1, 0.0, 0.0]}, "candidate c: quaternion must be unit"),
    ({"quaternion": [1.0, 0.0, 0.0]}, "candidate c: quaternion must have shape [4]"),
    ({"spread": "wide"}, "candidate c: spread must be numbers"),
    ({"hand": [0.0] * 6}, "candidate c: hand has 6 values; robot 'kuka_sdh' has 7 hand joints"),
    ({"position": None, "quaternion": None, "pose": [[1, 0, 0], [0, 1, 0]]},
     "candidate c: pose must have shape [4, 4]"),
    ({"position": None, "quaternion": None, "pose": np.diag([1, 1, 2, 1]).tolist()},
     "candidate c: pose's rotation is not orthonormal"),
    ({"elbow": "up"}, "candidate c: elbow must be numbers"),
    ({"elbow": 45}, "candidate c: elbow must be an angle in [-pi, pi] radians, got 45 (in "
     "degrees that is 0.7854 rad)"),
    ({"elbw": 1.0}, "candidate c: unknown field 'elbw'; a palm pose has id, position, "),
    ({"pose": np.eye(4).tolist()}, "candidate c: give 'pose' (4x4) or 'position' + "
     "'quaternion', not both (pose and position and quaternion given)"),
])
def test_bad_entries_are_one_line_errors_naming_the_candidate(tmp_path, change, message):
    entry = {k: v for k, v in {**GOOD, **change}.items() if v is not None}
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"object": "drill", "candidates": [entry]}))
    out = tmp_path / "r.csv"
    proc = run_cli("rank", str(path), "--samples", "10", "--engine", "fast", "--out", str(out))
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], proc.stderr
    assert list(tmp_path.iterdir()) == [path]


def test_repeated_ids_and_unknown_object_are_refused(tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"object": "drill", "candidates": [GOOD, GOOD]}))
    proc = run_cli("rank", str(path), "--samples", "10", "--out", str(tmp_path / "r.csv"))
    assert proc.returncode == 2 and "the same id 'c'" in proc.stderr
    path.write_text(json.dumps({"object": "no_such_thing", "candidates": [GOOD]}))
    proc = run_cli("rank", str(path), "--samples", "10", "--out", str(tmp_path / "r.csv"))
    assert proc.returncode == 2 and "no_such_thing" in proc.stderr
    # a misspelt top-level field is refused (a "frmae" read every pose in the object frame)
    path.write_text(json.dumps({"object": "drill", "frmae": "source", "candidates": [GOOD]}))
    proc = run_cli("rank", str(path), "--samples", "10", "--out", str(tmp_path / "r.csv"))
    assert proc.returncode == 2 and "unknown field 'frmae'; a palm-pose file has object, " \
        "robot, frame, candidates" in proc.stderr, proc.stderr
    path.write_text(json.dumps({"candidates": [GOOD]}))
    proc = run_cli("rank", str(path), "--samples", "10", "--out", str(tmp_path / "r.csv"))
    assert proc.returncode == 2 and "missing field 'object'" in proc.stderr, proc.stderr
    assert list(tmp_path.iterdir()) == [path]


def test_spread_sets_the_hands_one_pre_shape_only_joint():
    """``spread`` sets the joint ``close`` leaves out (the SDH's f1_spread, read from the YAML
    here, not through the description code), the other joints at their ``open`` values; no
    ``hand`` and no ``spread``: the open pre-shape; beside a ``hand`` mapping that leaves the
    spread joint out, ``spread`` sets it; a ``spread`` that contradicts ``hand`` is refused."""
    import yaml

    from kinegrasp_env.assets import asset_path
    from kinegrasp_env.robot.palm_pose import parse_palm_pose

    raw = yaml.safe_load(asset_path("robots", "kuka_sdh.yaml").read_text())
    opened = [raw["open"][j] for j in raw["hand_joints"]]
    pre_shape_only = [j for j in raw["hand_joints"] if j not in raw["close"]]
    assert pre_shape_only == ["f1_spread"]
    pose = {"position": [0.0, 0.0, 0.3], "quaternion": [1.0, 0.0, 0.0, 0.0]}
    alone = parse_palm_pose({**pose, "spread": 0.25}, "c").hand
    assert alone.tolist() == [0.25, *opened[1:]]
    assert parse_palm_pose(pose, "c").hand.tolist() == opened
    both = parse_palm_pose({**pose, "spread": 0.25, "hand": [0.25, *opened[1:]]}, "c")
    assert both.hand.tolist() == alone.tolist()
    with pytest.raises(ValueError, match=r"c: spread 0\.3 differs from hand's f1_spread 0\.25"):
        parse_palm_pose({**pose, "spread": 0.3, "hand": [0.25, *opened[1:]]}, "c")
    # beside a hand mapping that leaves the spread joint out, spread sets it
    flexion = raw["hand_joints"][1]
    mapped = parse_palm_pose({**pose, "spread": 0.25, "hand": {flexion: 0.5}}, "c").hand
    assert mapped.tolist() == [0.25, 0.5, *opened[2:]]
    with pytest.raises(ValueError, match=r"c: spread 0\.3 differs from hand's f1_spread 0\.25"):
        parse_palm_pose({**pose, "spread": 0.3, "hand": {"f1_spread": 0.25}}, "c")


def test_an_output_over_the_candidates_is_refused_before_any_solving(tmp_path):
    """``rank FILE --out FILE`` of a palm-pose file: one line, before the candidates are
    solved (solving would first print a line per rejected candidate), the file kept."""
    path = tmp_path / "c.json"
    shutil.copy(EXAMPLE, path)
    kept = path.read_bytes()
    proc = run_cli("rank", str(path), "--samples", "10", "--engine", "fast", "--out", str(path))
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"kinegrasp rank: error: --out {path} is the candidates file the command reads; give "
        "another file name"]
    assert path.read_bytes() == kept


def test_a_planned_file_renamed_to_candidates_is_read_as_the_docs_say(tmp_path):
    """The docs (and rank's refusal of a moved object's grasps) say to rename a planned
    file's ``grasps`` list ``candidates`` to solve its palm poses again: the file ``plan``
    writes (with its top-level ``planner_seed``) is then read as palm poses, one candidate
    per grasp (the seed was refused as an unknown field)."""
    from kinegrasp_env.toolkit.candidates import read_candidates
    from kinegrasp_env.world.grasps import save_grasps

    grasps = shipped_grasps("cube")[:3]
    planned = save_grasps(grasps, tmp_path / "planned.json", planner_seed=7)
    data = json.loads(planned.read_text())
    assert data["planner_seed"] == 7
    data["candidates"] = data.pop("grasps")
    renamed = tmp_path / "renamed.json"
    renamed.write_text(json.dumps(data))
    read = read_candidates(renamed)
    assert [c.id for c in read.candidates] == [g.id for g in grasps]


def test_a_file_without_a_robot_says_whose_candidates_it_solves(tmp_path):
    """A palm-pose file that names no robot, ranked without --robot: its candidates are the
    default robot's, and stderr says so in one line (a user of another gripper would get
    the SDH's numbers without a word); naming the robot, in the file or by --robot, drops
    the line."""
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"object": "drill", "candidates": [GOOD]}))
    args = ("rank", str(path), "--samples", "10", "--engine", "fast")
    proc = run_cli(*args, "--out", str(tmp_path / "r.csv"))  # (GOOD collides: rejected)
    assert proc.stderr.splitlines()[0] == (
        f"{path} names no robot: its candidates are solved for the default robot kuka_sdh "
        '(give a "robot" field or --robot for another)')
    note = proc.stderr.splitlines()[0]
    for other in (("validate", "--grasps", str(path), "--samples", "1", "--out",
                   str(tmp_path / "v")),
                  ("report", "--grasps", str(path), "--grasp", "c", "--samples", "10",
                   "--out", str(tmp_path / "p.html")),
                  ("evaluate", "--grasps", str(path), "--grasp", "c", "--samples", "10")):
        assert run_cli(*other).stderr.splitlines()[0] == note, other
    proc = run_cli(*args, "--robot", "kuka_sdh", "--out", str(tmp_path / "r2.csv"))
    assert "names no robot" not in proc.stderr and "rejected" in proc.stderr
    path.write_text(json.dumps({"object": "drill", "robot": "kuka_sdh", "candidates": [GOOD]}))
    proc = run_cli(*args, "--out", str(tmp_path / "r3.csv"))
    assert "names no robot" not in proc.stderr and "rejected" in proc.stderr
