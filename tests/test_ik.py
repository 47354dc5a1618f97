"""IK reaches palm poses; self-motion keeps the palm while the elbow swings."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.ik import ArmIK
from kinegrasp_env.robot.kinematics import pose_error
from kinegrasp_env.robot.model import ELBOW_LINK, PALM_LINK


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
    from kinegrasp_env.robot.model import SHOULDER_LINK, WRIST_LINK

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
