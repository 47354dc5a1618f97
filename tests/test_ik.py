"""IK reaches palm poses; self-motion keeps the palm while the elbow swings."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.default_robot import ELBOW_LINK, PALM_LINK
from kinegrasp_env.robot.ik import ARM_ANGLE_LINKS, ArmIK
from kinegrasp_env.robot.kinematics import pose_error


def _reachable_targets(kin, model, rng, n):
    q = rng.uniform(model.lower * 0.85, model.upper * 0.85, size=(n, model.dof))
    return q, kin.pose(q, PALM_LINK)


def test_ik_reaches_random_reachable_poses(kin, model, rng):
    _, targets = _reachable_targets(kin, model, rng, 60)
    ik = ArmIK(kin)
    result = ik.solve(targets, np.zeros(model.dof), rng=np.random.default_rng(1))
    assert result.success.all()
    err = pose_error(kin.pose(result.q, PALM_LINK), targets)
    assert np.linalg.norm(err[:, :3], axis=1).max() < 1e-6
    assert np.linalg.norm(err[:, 3:], axis=1).max() < 1e-5
    assert model.within_limits(result.q).all()


def test_ik_reports_unreachable(kin, model):
    target = np.eye(4)
    target[:3, 3] = [3.0, 0.0, 0.5]  # 3 m away: beyond the arm's reach (~1.3 m)
    result = ArmIK(kin).solve(target, np.zeros(model.dof), restarts=2)
    assert not result.success[0]
    assert result.position_error[0] > 1.0


def test_self_motion_keeps_palm_and_moves_elbow(kin, model, rng):
    q, _ = _reachable_targets(kin, model, rng, 40)
    ik = ArmIK(kin)
    psi0 = ik.elbow_angle(q)
    q1, ok = ik.set_elbow_angle(q, psi0 + 0.25)
    assert ok.mean() > 0.5  # some start near limits and cannot swing that far
    palm0, palm1 = kin.pose(q[ok], PALM_LINK), kin.pose(q1[ok], PALM_LINK)
    err = pose_error(palm1, palm0)
    assert np.abs(err[:, :3]).max() < 1e-6
    assert np.abs(err[:, 3:]).max() < 1e-6
    dpsi = np.angle(np.exp(1j * (ik.elbow_angle(q1[ok]) - psi0[ok])))
    np.testing.assert_allclose(dpsi, 0.25, atol=1e-8)
    elbow_moved = np.linalg.norm(kin.pose(q1[ok], ELBOW_LINK)[:, :3, 3]
                                 - kin.pose(q[ok], ELBOW_LINK)[:, :3, 3], axis=1)
    assert np.all(elbow_moved > 1e-4)
    assert model.within_limits(q1).all()
    # failures keep a valid configuration that still holds the palm
    np.testing.assert_allclose(kin.pose(q1, PALM_LINK), kin.pose(q, PALM_LINK), atol=1e-8)


def test_elbow_angle_is_a_rotation_about_shoulder_wrist(kin, model):
    """The elbow travels on a circle about the shoulder-wrist line: its distance to the line
    and its projection on it are constant along the self-motion."""
    from kinegrasp_env.robot.default_robot import SHOULDER_LINK, WRIST_LINK

    q = np.zeros(model.dof)
    q[[1, 3, 5]] = [0.6, -1.2, 0.8]
    ik = ArmIK(kin)
    qs = np.vstack([ik.set_elbow_angle(q, psi)[0] for psi in np.linspace(-0.6, 0.6, 7)])
    poses = kin.forward(qs, [SHOULDER_LINK, ELBOW_LINK, WRIST_LINK])
    s, e, w = (poses[k][:, :3, 3] for k in (SHOULDER_LINK, ELBOW_LINK, WRIST_LINK))
    axis = (w - s) / np.linalg.norm(w - s, axis=1, keepdims=True)
    along = np.sum((e - s) * axis, axis=1)
    radial = np.linalg.norm((e - s) - along[:, None] * axis, axis=1)
    assert np.ptp(along) < 1e-8 and np.ptp(radial) < 1e-8
    assert np.ptp(w, axis=0).max() < 1e-8


def test_self_motion_result_does_not_depend_on_the_continuation_step(kin):
    from kinegrasp_env.world.grasps import shipped_grasps

    ik = ArmIK(kin)
    rng = np.random.default_rng(7)
    grasps = [g for name in ("cube", "drill") for g in shipped_grasps(name)[:4]]
    targets = rng.uniform(-np.pi, np.pi, len(grasps))
    q0 = np.array([g.q0 for g in grasps])
    fine, ok_fine = ik.set_elbow_angle(q0, targets, max_step=0.05)
    coarse, ok_coarse = ik.set_elbow_angle(q0, targets)
    assert ok_fine.any()
    np.testing.assert_array_equal(ok_fine, ok_coarse)
    np.testing.assert_allclose(coarse[ok_fine], fine[ok_fine], atol=1e-6)


def test_compiled_self_motion_pieces_match_the_numpy_kinematics(kin, model, rng):
    """The compiled Newton's chain poses against the batched numpy kinematics (an
    independent implementation: column-wise rotations from half-angle tangents, not 4x4
    products with Rodrigues matrices); its elbow angle against the dihedral angle between
    the planes (shoulder-wrist line, z) and (shoulder-wrist line, elbow) from numpy's cross
    products, and its palm error against the position difference and scipy's rotation
    vector of R_target R^T (independent derivations); rotations near pi included (the
    other branch of the rotation log). Tolerances 1e-13 (rotation errors: 5e-13, measured
    1.0e-13 where the angle is ~2 rad; near pi 1e-10, see below)."""
    from scipy.spatial.transform import Rotation

    from kinegrasp_env.robot.kinematics import axis_angle_matrix
    from kinegrasp_env.robot.self_motion import (
        arm_chain,
        chain_forward,
        elbow_angle_one,
        palm_error,
    )

    ik = ArmIK(kin)
    chain = arm_chain(kin, PALM_LINK, ik.arm_index, ARM_ANGLE_LINKS)
    links = [joint.child for joint in kin.chain(PALM_LINK)]
    q = rng.uniform(model.lower, model.upper, size=(200, model.dof))
    poses = kin.forward(q, links)
    targets = kin.pose(rng.uniform(model.lower, model.upper, size=(200, model.dof)), PALM_LINK)
    targets = np.array(targets)
    # half of the targets a rotation of pi - 1e-6 .. pi - 1e-5 away from the palm
    axis = rng.normal(size=(100, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    near_pi = np.stack([axis_angle_matrix(a, np.pi - rng.uniform(1e-6, 1e-5)) for a in axis])
    targets[:100, :3, :3] = near_pi @ poses[PALM_LINK][:100, :3, :3]
    palm = poses[PALM_LINK]
    relative = targets[:, :3, :3] @ np.swapaxes(palm[:, :3, :3], -1, -2)
    expected_err = np.concatenate([targets[:, :3, 3] - palm[:, :3, 3],
                                   Rotation.from_matrix(relative).as_rotvec()], axis=1)
    shoulder, elbow, wrist = (poses[name][:, :3, 3] for name in ARM_ANGLE_LINKS)
    line = (wrist - shoulder) / np.linalg.norm(wrist - shoulder, axis=1, keepdims=True)
    plane_z = np.cross(line, [0.0, 0.0, 1.0])  # the normal of the plane through line and z
    plane_e = np.cross(line, elbow - shoulder)
    expected_psi = np.arctan2(np.sum(line * np.cross(plane_z, plane_e), axis=1),
                              np.sum(plane_z * plane_e, axis=1))
    frames = np.empty((len(links), 4, 4))
    err = np.empty(6)
    for i in range(len(q)):
        chain_forward(chain.origins, chain.axes, chain.index, q[i, ik.arm_index], frames)
        for j, link in enumerate(links):
            np.testing.assert_allclose(frames[j], poses[link][i], rtol=0, atol=1e-13)
        assert abs(elbow_angle_one(frames, chain.marks) - expected_psi[i]) < 1e-13
        palm_error(frames, targets[i], err)
        # near pi the angle comes from an arccos at its end: rounding of 1e-16 in the cosine
        # moves it by ~1e-16 / sin(angle), up to 1e-10 at pi - 1e-6 (measured 1.3e-10
        # against scipy's quaternion-based rotation vector; margin 4x)
        np.testing.assert_allclose(err, expected_err[i], rtol=0, atol=5e-10 if i < 100 else 5e-13)
    assert np.linalg.norm(expected_err[:100, 3:], axis=1).min() > np.pi - 1e-4


def test_compiled_self_motion_converges_on_the_shipped_grasps(kin):
    """Newton's own residual test: from every shipped grasp, 0.25 rad of elbow motion in one
    continuation step reaches the palm pose and the angle (checked with the numpy
    kinematics) where the path stays within the limits."""
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import OBJECT_NAMES

    ik = ArmIK(kin)
    q0 = np.array([g.q0 for name in OBJECT_NAMES for g in shipped_grasps(name)])
    psi0 = ik.elbow_angle(q0)
    moved, ok = ik.set_elbow_angle(q0, psi0 + 0.25)
    assert ok.mean() > 0.8
    err = pose_error(kin.pose(moved[ok], PALM_LINK), kin.pose(q0[ok], PALM_LINK))
    assert np.abs(err).max() < 1e-10
    dpsi = np.angle(np.exp(1j * (ik.elbow_angle(moved[ok]) - psi0[ok])))
    np.testing.assert_allclose(dpsi, 0.25, rtol=0, atol=1e-10)
