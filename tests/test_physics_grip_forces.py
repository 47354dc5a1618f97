"""The grip's balanced torques (kinegrasp_env.physics.grip_forces) on set-ups with known answers.

Independent references: the net wrench and the cone membership of the returned forces
recomputed here from the forces alone (not the solver's matrices), joint torques from finite
differences of a hand-written planar finger's kinematics, and configurations whose answer is
known (two antipodal contacts need no friction; two contacts pushing one face have no
equilibrium).
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.physics.grip_forces import (
    GripContact,
    GripJoints,
    GripTorques,
    SpringGrip,
    balanced_torques,
    loaded_joints,
    tip_offsets,
    torque_rows,
)

LIMITS = np.array([2.1, 1.4] * 3)


def hand_joints(axes: np.ndarray, origins: np.ndarray, tips: np.ndarray,
                torque_limits: tuple[float, float],
                spread: tuple[np.ndarray, np.ndarray, np.ndarray, float] | None = None
                ) -> GripJoints:
    """A three-finger hand's grip joints (a test set-up, as the SDH's): the six flexion joints
    (finger-major, proximal before distal) and, with ``spread``, the spread joints after
    them.

    Args:
        axes, origins: (6, 3) the flexion joints' unit axes (closing positive) and points on
            them, world frame; tips: (3, 3) the fingertips, world frame.
        torque_limits: (proximal, distal) the flexion joints' torque limits, N m.
        spread: (axes (s, 3), origins (s, 3), fingers (s,), torque limit N m) of the spread
            joints, or None (then they are not part of the grip: held where they are).
    """
    limits = np.array(list(torque_limits) * 3, dtype=float)
    fingers, first = np.repeat(np.arange(3), 2), np.tile(np.arange(2), 3)
    lower = np.zeros(6)
    if spread is not None:
        s_axes, s_origins, s_fingers, s_limit = spread
        s_fingers = np.asarray(s_fingers, dtype=int)
        axes, origins = np.vstack([axes, s_axes]), np.vstack([origins, s_origins])
        fingers = np.concatenate([fingers, s_fingers])
        first = np.concatenate([first, np.zeros(s_fingers.size, dtype=int)])
        limits = np.concatenate([limits, np.full(s_fingers.size, float(s_limit))])
        lower = np.concatenate([lower, -limits[6:]])
    tips = np.asarray(tips, dtype=float)[fingers]
    return GripJoints(np.asarray(axes, dtype=float), np.asarray(origins, dtype=float),
                      fingers, first, lower, limits, tips)


def flexion(axes, origins, tips=None, scale: float = 1.0) -> GripJoints:
    """The six flexion joints (torque limits ``scale`` x LIMITS), no spread joint."""
    tips = np.zeros((3, 3)) if tips is None else tips
    return hand_joints(axes, origins, tips, (2.1 * scale, 1.4 * scale))


def planar_finger(base: np.ndarray, direction: np.ndarray, axis: np.ndarray,
                  angles: tuple[float, float], lengths=(0.0865, 0.0685)):
    """Joint origins (2, 3) and the tip (3,) of a two-link finger whose links start along
    ``direction`` at ``base`` and turn about ``axis`` (unit) by ``angles`` (radians)."""
    def turn(v, angle):  # Rodrigues
        return (v * np.cos(angle) + np.cross(axis, v) * np.sin(angle)
                + axis * (axis @ v) * (1 - np.cos(angle)))
    first = turn(direction, angles[0])
    second = turn(direction, angles[0] + angles[1])
    elbow = base + lengths[0] * first
    return np.array([base, elbow]), elbow + lengths[1] * second


def three_finger_cube(offset: float = 0.0):
    """Three distal contacts on a 6 cm cube at the origin: two on the +-y faces, one on -x
    (moved off the faces' centres by ``offset``-scaled steps: then force balance alone leaves
    a net torque), each finger's axes and origins (flexion axes perpendicular to its plane)."""
    points = np.array([[0.0, 0.03, 0.0], [0.0, -0.03, 0.0], [-0.03, 0.0, 0.0]])
    points += offset * np.array([[1.0, 0.0, 0.5], [-1.0, 0.0, 0.0], [0.0, 0.5, 1.0]])
    normals = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    axes, origins = np.zeros((6, 3)), np.zeros((6, 3))
    for f, (p, n) in enumerate(zip(points, normals, strict=True)):
        axis = np.cross(n, [0.0, 0.0, 1.0])
        axis /= np.linalg.norm(axis)
        # a finger above the contact, its tip pressing along n when the joints close
        origins[2 * f] = p - 0.04 * n + [0.0, 0.0, 0.12]
        origins[2 * f + 1] = p - 0.02 * n + [0.0, 0.0, 0.05]
        axes[2 * f] = axes[2 * f + 1] = axis
    contacts = [GripContact(f, 1, points[f], normals[f]) for f in range(3)]
    return contacts, axes, origins


def test_the_solution_is_in_equilibrium_inside_the_cones_and_within_the_limits():
    contacts, axes, origins = three_finger_cube(offset=0.01)
    friction = 0.5
    out = balanced_torques(contacts, flexion(axes, origins), np.zeros(3), friction)
    assert isinstance(out, GripTorques)
    points = np.array([c.point for c in contacts])
    normals = np.array([c.normal for c in contacts])
    f = out.forces
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.cross(points, f).sum(axis=0), 0.0, atol=1e-9)
    normal = np.einsum("kd,kd->k", f, normals)
    tangential = np.linalg.norm(f - normal[:, None] * normals, axis=1)
    assert np.all(normal >= out.min_normal - 1e-9) and out.min_normal > 0
    assert np.all(tangential <= out.fraction * friction * normal + 1e-9)
    # tau = J^T f, J's columns the contact points' velocities per joint speed
    expected = np.zeros(6)
    for c, force in zip(contacts, f, strict=True):
        for k in range(2):
            j = 2 * c.finger + k
            expected[j] = np.cross(axes[j], c.point - origins[j]) @ force
    np.testing.assert_allclose(out.torques, expected, atol=1e-9)
    assert np.all(out.torques >= -1e-9) and np.all(out.torques <= LIMITS + 1e-9)
    assert np.isclose(out.torques / LIMITS, 1.0).any()  # the firmest grip reaches a limit


def test_the_torques_are_the_power_of_the_forces_by_finite_differences():
    """tau_j = dW/dq_j: a contact on a planar finger's distal link, moved by a small turn of
    either joint (the finger's own kinematics), does work f . dp."""
    axis = np.array([0.0, 1.0, 0.0])
    base, direction = np.array([0.05, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    angles = (-0.3, -0.4)
    origins, tip = planar_finger(base, direction, axis, angles)
    force = np.array([0.3, 0.1, -1.0])
    contact = GripContact(0, 1, tip, np.array([0.0, 0.0, -1.0]))
    axes6 = np.tile(axis, (6, 1))
    origins6 = np.vstack([origins, np.zeros((4, 3))])
    rows = torque_rows([contact], flexion(axes6, origins6), force[None, None, :])[:, 0]
    h = 1e-6
    for j in range(2):
        bumped = list(angles)
        bumped[j] += h
        _, moved = planar_finger(base, direction, axis, tuple(bumped))
        assert rows[j] == pytest.approx(force @ (moved - tip) / h, rel=1e-5)


def test_antipodal_contacts_need_the_least_friction():
    contacts, axes, origins = three_finger_cube()
    two = contacts[:2]
    out = balanced_torques(two, flexion(axes, origins), np.zeros(3), 0.5)
    assert out is not None and out.fraction == 0.2
    np.testing.assert_allclose(out.forces[0], -out.forces[1], atol=1e-9)


def test_two_contacts_pushing_one_face_have_no_equilibrium():
    contacts, axes, origins = three_finger_cube()
    same = [contacts[0], GripContact(1, 1, np.array([0.01, 0.03, 0.0]), contacts[0].normal)]
    joints = flexion(axes, origins)
    assert balanced_torques(same, joints, np.zeros(3), 0.5) is None
    assert balanced_torques(contacts[:1], joints, np.zeros(3), 0.5) is None


def test_torques_scale_with_the_limits():
    contacts, axes, origins = three_finger_cube()
    one = balanced_torques(contacts, flexion(axes, origins), np.zeros(3), 0.5)
    two = balanced_torques(contacts, flexion(axes, origins, scale=2.0), np.zeros(3), 0.5)
    np.testing.assert_allclose(two.torques, 2 * one.torques, rtol=1e-6, atol=1e-9)


def test_spring_presses_with_the_balanced_torque_at_the_stall_angle():
    contacts, axes, origins = three_finger_cube()
    tips = np.array([c.point for c in contacts])
    joints = flexion(axes, origins, tips)
    out = balanced_torques(contacts, joints, np.zeros(3), 0.5)
    offsets = tip_offsets(joints, 0.0015)
    radial = [np.linalg.norm(np.cross(axes[j], tips[j // 2] - origins[j])) for j in range(6)]
    np.testing.assert_allclose(offsets * radial, 0.0015)
    stall = np.linspace(0.1, 0.6, 6)
    spring = SpringGrip.of(stall, out, offsets, LIMITS, loaded_joints(contacts, joints))
    np.testing.assert_allclose(spring.torques(stall), out.torques)
    np.testing.assert_allclose(spring.torques(spring.targets), 0.0, atol=1e-12)
    assert np.all(spring.torques(stall - 1.0) <= LIMITS + 1e-12)
    loaded = loaded_joints([GripContact(0, 1, tips[0], contacts[0].normal),
                            GripContact(2, 0, tips[2], contacts[2].normal)], joints)
    assert loaded.tolist() == [True, True, False, False, True, False]


def with_spread(contacts, axes, origins, limit: float = 10.0) -> GripJoints:
    """The flexion joints plus a spread joint on fingers 0 and 1: each turns its finger
    about the vertical through a point above the cube (as the hand's spread does)."""
    tips = np.array([c.point for c in contacts])
    spread_axes = np.tile([0.0, 0.0, 1.0], (2, 1))
    spread_origins = np.array([[0.02, 0.0, 0.15], [-0.02, 0.0, 0.15]])
    return hand_joints(axes, origins, tips, (2.1, 1.4),
                       (spread_axes, spread_origins, np.array([0, 1]), limit))


def test_spread_joints_carry_their_fingers_forces_and_set_them():
    """With the spread joints in the grip: their torques are J^T f of every contact of their
    finger (recomputed here from the forces), within +-limit, and a finger with two flexion
    joints and a spread joint has its force fixed by those three torques (J^T f = tau has
    one solution, the LP's force), which a held spread joint would leave to the simulator."""
    contacts, axes, origins = three_finger_cube(offset=0.01)
    joints = with_spread(contacts, axes, origins)
    out = balanced_torques(contacts, joints, np.zeros(3), 0.5)
    assert out is not None and out.torques.shape == (8,)
    np.testing.assert_allclose(out.forces.sum(axis=0), 0.0, atol=1e-9)
    for j in (6, 7):
        finger = j - 6
        expected = sum(np.cross(joints.axes[j], c.point - joints.origins[j]) @ f
                       for c, f in zip(contacts, out.forces, strict=True) if c.finger == finger)
        assert out.torques[j] == pytest.approx(expected, abs=1e-9)
        assert -10.0 - 1e-9 <= out.torques[j] <= 10.0 + 1e-9
    for finger in (0, 1):
        rows = [j for j in range(8) if joints.fingers[j] == finger]
        c = contacts[finger]
        jacobian = np.array([np.cross(joints.axes[j], c.point - joints.origins[j])
                             for j in rows])  # (3, 3): tau = J f
        assert np.linalg.matrix_rank(jacobian) == 3
        solved = np.linalg.solve(jacobian, out.torques[rows])
        np.testing.assert_allclose(solved, out.forces[finger], atol=1e-9)


def test_a_spring_presses_with_a_negative_balanced_torque_too():
    contacts, axes, origins = three_finger_cube(offset=0.01)
    joints = with_spread(contacts, axes, origins)
    out = balanced_torques(contacts, joints, np.zeros(3), 0.5)
    torques = out.torques.copy()
    torques[6] = -abs(torques[6]) - 0.05  # a spread torque turning the other way
    solution = GripTorques(torques, out.forces, out.fraction, out.min_normal)
    stall = np.linspace(0.1, 0.8, 8)
    spring = SpringGrip.of(stall, solution, tip_offsets(joints, 0.0015), joints.upper,
                           loaded_joints(contacts, joints))
    np.testing.assert_allclose(spring.torques(stall), torques, atol=1e-12)
    np.testing.assert_allclose(spring.torques(spring.targets), 0.0, atol=1e-12)
    assert spring.targets[6] < stall[6]
