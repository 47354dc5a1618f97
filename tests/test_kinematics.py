"""Batched FK against pybullet, Jacobians against finite differences, URDF parsing."""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.robot.default_robot import ARM_JOINTS, FINGERTIP_LINKS, HAND_JOINTS, PALM_LINK
from kinegrasp_env.robot.kinematics import (
    axis_angle_matrix,
    pose_error,
    rotation_log,
    snap_rotation,
)
from kinegrasp_env.robot.model import load_urdf, rpy_to_matrix


def test_model_read_from_urdf(model):
    assert model.dof == 14
    assert model.actuated == ARM_JOINTS + HAND_JOINTS
    assert PALM_LINK in model.links and all(t in model.links for t in FINGERTIP_LINKS)
    # limits come from the file: the iiwa's joint 7 is +-175 degrees
    assert model.upper[6] == pytest.approx(np.deg2rad(175), abs=1e-6)
    # coupled spread: finger 2 mimics finger 1 with multiplier -1
    assert model.joint("f2_spread").mimic == ("f1_spread", -1.0, 0.0)
    values = model.expand(np.r_[np.zeros(7), 0.4, np.zeros(6)])
    assert values["f1_spread"] == pytest.approx(0.4)
    assert values["f2_spread"] == pytest.approx(-0.4)


def test_fk_matches_pybullet(kin, model, bullet_robot):
    client, body, joints, links = bullet_robot
    rng = np.random.default_rng(0)
    q = rng.uniform(model.lower, model.upper, size=(1000, model.dof))
    names = (PALM_LINK, *FINGERTIP_LINKS)
    poses = kin.forward(q, names)
    worst_pos = worst_rot = 0.0
    for i in range(q.shape[0]):
        for name, value in model.expand(q[i]).items():
            client.resetJointState(body, joints[name], float(value))
        for name in names:
            state = client.getLinkState(body, links[name], computeForwardKinematics=1)
            rot = np.array(client.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            worst_pos = max(worst_pos, np.abs(np.array(state[4]) - poses[name][i, :3, 3]).max())
            rel = rotation_log(rot.T @ poses[name][i, :3, :3])
            worst_rot = max(worst_rot, np.linalg.norm(rel))
    # pybullet computes in single precision: float32 round-off is ~1e-7
    assert worst_pos < 1e-6
    assert worst_rot < 1e-6


def test_fk_matches_a_plain_chain_of_4x4_products(kin, model):
    """Every link's pose against an independent formulation: per draw, the URDF origins
    (rotations snapped as the kinematics snap them) times Rodrigues rotations about the joint
    axes, as 4x4 products, with the mimic joints' values from RobotModel.expand. Agreement
    measured 8.9e-16 (bound 1e-15: a few ulps of 1 m); unsnapped origins differ by 2e-11
    (the URDF's right angles written to 11 digits)."""
    rng = np.random.default_rng(3)
    q = rng.uniform(model.lower, model.upper, size=(200, model.dof))
    poses = kin.forward(q)
    frames = {}
    worst = 0.0
    for i in range(q.shape[0]):
        values = model.expand(q[i])
        frames[model.base_link] = np.eye(4)
        for joint in model.joints:
            step = joint.origin.copy()
            step[:3, :3] = snap_rotation(step[:3, :3])
            if joint.movable:
                motion = np.eye(4)
                if joint.kind == "prismatic":
                    motion[:3, 3] = joint.axis * values[joint.name]
                else:
                    motion[:3, :3] = axis_angle_matrix(joint.axis, values[joint.name])
                step = step @ motion
            frames[joint.child] = frames[joint.parent] @ step
        for link in model.links:
            worst = max(worst, np.abs(frames[link] - poses[link][i]).max())
    assert worst < 1e-15


def test_fk_kernel_interpreted_matches_compiled(kin, model, rng, monkeypatch):
    """The compiled pass against its own loop run as plain Python (numba's py_func; the
    small helpers it calls stay compiled): the same numbers to 8 ulps of 1 (poses: unit
    rotations, positions ~1 m). Two code paths (LLVM's code and CPython's floats), which a
    compiler or another CPU's libm may round differently: not bit for bit."""
    import kinegrasp_env.robot.kinematics as kinematics

    q = rng.uniform(model.lower, model.upper, size=(20, model.dof))
    compiled = kin.forward(q)
    monkeypatch.setattr(kinematics, "forward_pass", kinematics.forward_pass.py_func)
    interpreted = kin.forward(q)
    for link in model.links:
        np.testing.assert_allclose(interpreted[link], compiled[link], rtol=0,
                                   atol=8 * np.finfo(float).eps)


def test_fk_single_equals_batch(kin, model, rng):
    q = rng.uniform(model.lower, model.upper, size=(5, model.dof))
    batch = kin.pose(q, PALM_LINK)
    for i in range(5):
        np.testing.assert_allclose(kin.pose(q[i], PALM_LINK)[0], batch[i], atol=1e-15)


def test_jacobian_matches_finite_differences(kin, model, rng):
    q = rng.uniform(model.lower, model.upper, size=(20, model.dof))
    for link in (PALM_LINK, "f1_tip", "f2_tip"):
        jac = kin.jacobian(q, link)
        h = 1e-6
        for j in range(model.dof):
            dq = np.zeros(model.dof)
            dq[j] = h
            numeric = pose_error(kin.pose(q - dq, link), kin.pose(q + dq, link)) / (2 * h)
            np.testing.assert_allclose(jac[:, :, j], numeric, atol=1e-7)


def test_rotation_log_roundtrip(rng):
    from kinegrasp_env.robot.kinematics import axis_angle_matrix

    for angle in (0.0, 1e-9, 0.3, 2.0, np.pi - 1e-6, np.pi):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        vec = rotation_log(axis_angle_matrix(axis, np.array([angle]))[0])
        np.testing.assert_allclose(np.linalg.norm(vec), angle, atol=1e-8)
        if angle > 1e-6:
            np.testing.assert_allclose(abs(vec @ axis), angle, atol=1e-6)


def test_rpy_convention():
    # URDF: R = Rz(yaw) Ry(pitch) Rx(roll)
    rot = rpy_to_matrix(0.0, 0.0, np.pi / 2)
    np.testing.assert_allclose(rot @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    rot = rpy_to_matrix(np.pi / 2, 0.0, 0.0)
    np.testing.assert_allclose(rot @ [0, 1, 0], [0, 0, 1], atol=1e-12)


def test_bad_urdf(tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text('<robot name="r"><link name="a"/><link name="b"/>'
                   '<joint name="j" type="floating"><parent link="a"/><child link="b"/></joint>'
                   "</robot>")
    with pytest.raises(ValueError, match="unsupported type 'floating'"):
        load_urdf(bad)


def test_bad_configuration_shape(kin):
    with pytest.raises(ValueError, match=r"shape \(n, 14\)"):
        kin.forward(np.zeros(7))


def test_joint_angles_against_the_closed_form():
    # every driver kind (directly, negated, scaled with an offset, prismatic, fixed) against
    # cos / sin of mult q + offset computed by NumPy: the half-angle formula agrees within a
    # few ulps, a prismatic value is the same expression bit for bit, a fixed joint stays 0
    from kinegrasp_env.robot.fk_kernel import FIXED, PRISMATIC, ROTATING, joint_angles

    rng = np.random.default_rng(3)
    kind = np.array([ROTATING, ROTATING, ROTATING, PRISMATIC, FIXED, ROTATING], dtype=np.int64)
    index = np.array([0, 1, 2, 3, 0, 2], dtype=np.int64)
    mult = np.array([1.0, -1.0, 0.7, 0.5, 1.0, 1.0])
    offset = np.array([0.0, 0.0, 0.2, 0.01, 0.0, -0.3])
    q = rng.uniform(-3.1, 3.1, (400, 4))
    cos, sin, shift = (np.zeros((6, 400)) for _ in range(3))
    joint_angles(q, kind, index, mult, offset, cos, sin, shift)
    value = mult[:, None] * q[:, index].T + offset[:, None]
    rotating = kind == ROTATING
    np.testing.assert_allclose(cos[rotating], np.cos(value[rotating]), rtol=0, atol=2e-15)
    np.testing.assert_allclose(sin[rotating], np.sin(value[rotating]), rtol=0, atol=2e-15)
    np.testing.assert_array_equal(shift[kind == PRISMATIC], value[kind == PRISMATIC])
    assert not cos[kind == FIXED].any() and not sin[kind == FIXED].any()
    assert not shift[rotating].any() and not cos[kind == PRISMATIC].any()
