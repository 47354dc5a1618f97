"""One schema for grasp files and palm-pose files: ``plan``'s output read back as full
configurations (``load_grasps``) and as palm-pose candidates (``load_candidates``) solved by IK
gives the same palm poses, the same configurations when the elbow angle is given, and the
same P(FC) on the same seed (docs: the palm-poses guide)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
from cli_helpers import run_cli
from scipy.spatial.transform import Rotation

from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.robot.default_robot import PALM_LINK, kuka_sdh
from kinegrasp_env.toolkit.candidates import load_candidates, solve_all
from kinegrasp_env.toolkit.elbow import configuration_at, with_configuration
from kinegrasp_env.world.grasps import load_grasps, save_grasps, shipped_grasps
from kinegrasp_env.world.objects import load_object

#: Palm pose (m, rad) and configuration (rad) of the IK round trip. The candidates' IK stops
#: only once the palm is within 1e-7 m and 1e-7 rad (norms) of the file's pose, the planned
#: grasp's own forward kinematics, so the palm's bound holds by the solver's stopping rule
#: (measured on 18 grasps of the cube, drill and mug, 12 planned and 6 moved along the
#: self-motion: 1.9e-8 m and 6.8e-8 rad at most); q has no such rule: measured <= 8.2e-8
#: rad, held to 1e-6 (margin x12).
PALM_TOL, Q_TOL = 1e-7, 1e-6
#: The fields against pybullet's own forward kinematics (single-precision link frames):
#: measured 2.6e-8 m and 3.7e-8 rad on the cube's grasps (test_candidates holds the same
#: FK to 1e-6).
FK_TOL = 1e-6
FIELDS = {"id", "object", "position", "quaternion", "hand", "spread", "elbow", "q0",
          "palm_pose", "q_nominal", "contacts", "meta"}


def _turn(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) between the rotations of two (4, 4) poses."""
    return float(Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).magnitude())


def _bullet_palm(bullet_robot, q: np.ndarray) -> np.ndarray:
    """(4, 4) palm frame at q (14,) by pybullet's own forward kinematics."""
    client, body, joints, links = bullet_robot
    for name, value in kuka_sdh().expand(q).items():
        client.resetJointState(body, joints[name], float(value))
    state = client.getLinkState(body, links[PALM_LINK], computeForwardKinematics=True)
    pose = np.eye(4)
    pose[:3, :3] = np.array(client.getMatrixFromQuaternion(state[5])).reshape(3, 3)
    pose[:3, 3] = state[4]
    return pose


def _moved(grasp, dpsi: float):
    """The grasp at elbow angle psi + dpsi (same palm pose): a configuration the IK alone
    does not find, so only the file's ``elbow`` gives it back."""
    psi = grasp.meta["elbow_angle"] + dpsi
    return with_configuration(grasp, configuration_at(grasp, psi), psi)


def test_plan_output_reads_as_configurations_and_as_palm_poses(tmp_path, bullet_robot):
    path = tmp_path / "cube.json"
    proc = run_cli("plan", "--object", "cube", "--count", "2", "--seed", "0", "--out",
                   str(path))
    assert proc.returncode == 0, proc.stderr
    entries = json.loads(path.read_text())["grasps"]
    assert all(set(e) == FIELDS for e in entries)
    planned = load_grasps(path)  # today's reader: full configurations
    pose = load_object("cube").pose
    for entry, grasp in zip(entries, planned, strict=True):  # the fields, independently
        in_object = np.eye(4)
        in_object[:3, :3] = Rotation.from_quat(entry["quaternion"]).as_matrix()
        in_object[:3, 3] = entry["position"]
        palm = _bullet_palm(bullet_robot, grasp.q0)  # pybullet's own FK of q0
        assert np.abs((pose @ in_object)[:3, 3] - palm[:3, 3]).max() < FK_TOL
        assert _turn(pose @ in_object, palm) < FK_TOL
        assert entry["hand"] == list(grasp.q0[7:]) and entry["spread"] == grasp.q0[7]
        assert entry["elbow"] == grasp.meta["elbow_angle"]

    grasps = [*planned, _moved(planned[0], 0.6)]
    save_grasps(grasps, path)
    name, candidates = load_candidates(path)
    assert name == "cube" and [c.id for c in candidates] == [g.id for g in grasps]
    solved, rejected = solve_all(name, candidates)
    assert rejected == []
    for want, got in zip(grasps, solved, strict=True):
        assert np.abs(got.palm_pose[:3, 3] - want.palm_pose[:3, 3]).max() < PALM_TOL
        assert _turn(got.palm_pose, want.palm_pose) < PALM_TOL
        assert np.abs(got.q0 - want.q0).max() < Q_TOL
        a, b = (evaluate_grasp(g, sigma=0.0133, n=100, seed=7, engine="fast")
                for g in (want, got))
        assert a.p_fc == b.p_fc and a.counts == b.counts
        assert abs(a.q_mean - b.q_mean) < Q_TOL
    # without the elbow angle the IK gives the same palm pose with another arm configuration
    again, _ = solve_all(name, [dataclasses.replace(candidates[-1], elbow=None)])
    assert np.abs(again[0].palm_pose - grasps[-1].palm_pose).max() < PALM_TOL
    assert np.abs(again[0].q0 - grasps[-1].q0).max() > 0.1


def test_grasp_file_without_palm_pose_fields_reads_as_palm_poses(tmp_path):
    """A file written before the fields existed (here: the shipped set's entries): its
    world-frame ``palm_pose`` and ``q0``'s hand are the candidate."""
    shipped = shipped_grasps("cube")[:2]
    path = tmp_path / "old.json"
    path.write_text(json.dumps({"object": "cube", "grasps": [g.to_dict() for g in shipped]}))
    name, candidates = load_candidates(path)
    solved, rejected = solve_all(name, candidates)
    assert rejected == []
    for want, got in zip(shipped, solved, strict=True):
        assert np.abs(got.palm_pose[:3, 3] - want.palm_pose[:3, 3]).max() < PALM_TOL
        assert _turn(got.palm_pose, want.palm_pose) < PALM_TOL
        assert np.array_equal(got.q0[7:], want.q0[7:])
