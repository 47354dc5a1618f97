"""The physics closing (pybullet dynamics), the lift test and the physics engine.

Independent references: the kinematic reference closing (exact contacts), the object's exact
geometry (closest points), the robot's own forward kinematics, closed-form mass and inertia of
the cube, pybullet's reported contact forces (moment about the finger joint against the motor's
torque limit), and hand-built grasps whose holding is obvious (opposed fingers; two fingers
pushing one face with nothing opposing them).
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.closing.reference import auto_close, hand_joint_values
from kinegrasp_env.montecarlo.engines import (
    FORCE_CLOSURE,
    MISSED,
    OUTCOMES,
    DrawBatch,
    Engine,
    PybulletEngine,
)
from kinegrasp_env.montecarlo.evaluate import chunk_configurations
from kinegrasp_env.montecarlo.physics_engine import PhysicsEngine
from kinegrasp_env.physics.pybullet_closing import (
    MotorSettings,
    grip,
    merge_records,
    physics_close,
)
from kinegrasp_env.physics.pybullet_lift import LiftProfile, hand_path, lift_test, moved, smoothstep
from kinegrasp_env.physics.pybullet_world import PhysicsWorld, WorldSettings, pose_matrix
from kinegrasp_env.robot.ik import ArmIK
from kinegrasp_env.robot.kinematics import Kinematics, axis_angle_matrix
from kinegrasp_env.robot.model import FINGERS, kuka_sdh
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import grasp_by_index, shipped_grasps
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.sim import GraspWorld

KIN = Kinematics(kuka_sdh())


def palm_down(x: float, z: float, preshape) -> np.ndarray:
    """q0 (14,) with the palm at (x, 0, z) (world), facing down, palm x = world x."""
    target = np.eye(4)
    target[:3, :3] = np.diag([1.0, -1.0, -1.0])
    target[:3, 3] = [x, 0.0, z]
    seed = shipped_grasps("cube")[0].q0.copy()
    seed[7:] = preshape
    result = ArmIK(KIN).solve(target, seed, rng=np.random.default_rng(0))
    assert result.success[0]
    return result.q[0]


#: The cube between opposed fingers: spread 90 deg puts fingers 1 and 2 face to face across
#: the cube's +-y faces, finger 3 presses its -x face (kinematic Q = 0.23, five contacts).
OPPOSED = (0.581, 0.26, [np.pi / 2, -0.3, -0.1, -0.3, -0.1, -0.3, -0.1])
#: No force closure at all: spread 0, the cube in front of fingers 1 and 2 only; both push
#: its +x face, finger 3 closes on nothing (kinematic outcome: missed).
ONE_FACE = (0.70, 0.24, [0.0] * 7)


@pytest.fixture(scope="module")
def cube_engine():
    engine = PhysicsEngine("cube")
    yield engine
    engine.close()


# ---------------------------------------------------------------------------- settings


@pytest.mark.parametrize("bad", [{"density": 0.0}, {"friction": -0.5},
                                 {"time_step": float("nan")}, {"support_damping": -1.0},
                                 {"solver_iterations": 0}])
def test_world_settings_reject_bad_values(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        WorldSettings(**bad)


@pytest.mark.parametrize("bad", [{"distal_torque": 0.0}, {"closing_speed": float("inf")},
                                 {"creep_speed": -0.1}, {"stall_checks": 0}])
def test_motor_settings_reject_bad_values(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        MotorSettings(**bad)


def test_lift_profile_rejects_bad_values():
    with pytest.raises(ValueError, match="hold_distance"):
        LiftProfile(hold_distance=-0.01)


# ---------------------------------------------------------------------------- pieces


def _record(point, normal_on_b, distance, force):
    """A pybullet contact record with the fields merge_records reads (5-9)."""
    rec = [0] * 14
    rec[6], rec[7], rec[8], rec[9] = tuple(point), tuple(normal_on_b), distance, force
    return tuple(rec)


def test_merge_records_takes_the_centre_of_pressure_of_one_face():
    # two records on the face z = 0 (normal on B +z: inward -z), one on another face
    records = [_record((0.0, 0.0, 0.0), (0, 0, 1), -1e-4, 3.0),
               _record((0.04, 0.0, 0.0), (0, 0, 1), -5e-5, 1.0),
               _record((0.0, 0.0, 0.05), (1, 0, 0), 0.0, 50.0)]
    point, normal = merge_records(records)
    np.testing.assert_allclose(point, [0.01, 0.0, 0.0], atol=1e-15)  # (3 * 0 + 1 * 0.04) / 4
    np.testing.assert_allclose(normal, [0.0, 0.0, -1.0], atol=1e-15)


def test_merge_records_without_forces_averages_and_keeps_the_deepest_face():
    records = [_record((0.0, 0.0, 0.0), (1, 0, 0), 0.0, 0.0),
               _record((0.0, 0.02, 0.0), (1, 0, 0), 0.0, 0.0),
               _record((0.0, 0.0, 0.1), (0, 1, 0), 1e-4, 0.0)]
    point, normal = merge_records(records)
    np.testing.assert_allclose(point, [0.0, 0.01, 0.0], atol=1e-15)
    np.testing.assert_allclose(normal, [-1.0, 0.0, 0.0], atol=1e-15)


def test_lift_profile_lifts_holds_and_shakes_as_stated():
    profile = LiftProfile()
    assert profile.motion(0.0)[0] == pytest.approx(np.zeros(3), abs=1e-15)
    end_of_lift = profile.lift_time
    np.testing.assert_allclose(profile.motion(end_of_lift)[0], [0, 0, profile.height],
                               atol=1e-15)
    h = 1e-6  # minimum jerk: no speed at either end of the lift
    for t in (h, end_of_lift - h):
        assert abs(profile.motion(t)[0][2] - profile.motion(t - h)[0][2]) / h < 1e-4
    hold = [profile.motion(end_of_lift + t)[0] for t in np.linspace(0, profile.hold_time, 7)]
    np.testing.assert_allclose(hold, np.repeat(hold[:1], 7, axis=0), atol=1e-15)
    start = profile.lift_time + profile.hold_time
    shake = np.array([profile.motion(start + t)[0] for t in
                      np.linspace(0, profile.shake_time, 2001)]) - [0, 0, profile.height]
    angles = np.array([profile.motion(start + t)[1] for t in
                       np.linspace(0, profile.shake_time, 2001)])
    amplitude = np.linalg.norm(shake, axis=1)
    assert amplitude.max() <= profile.shake_amplitude + 1e-12
    assert amplitude.max() >= 0.99 * profile.shake_amplitude
    assert np.abs(angles).max() == pytest.approx(profile.shake_angle, rel=0.01)
    assert amplitude[0] == 0.0 and amplitude[-1] < 1e-12 and angles[-1] == pytest.approx(0.0,
                                                                                         abs=1e-12)
    assert smoothstep(-1.0) == 0.0 and smoothstep(2.0) == 1.0


def test_moved_rotates_about_the_palm_centre():
    rng = np.random.default_rng(1)
    root = np.eye(4)
    root[:3, 3] = rng.normal(size=3)
    palm_offset = np.eye(4)
    palm_offset[:3, 3] = [0.0, 0.0, 0.085]
    centre = (root @ palm_offset)[:3, 3]
    shift = np.array([0.01, -0.02, 0.03])
    new = moved(root, centre, shift, 0.3)
    np.testing.assert_allclose((new @ palm_offset)[:3, 3], centre + shift, atol=1e-12)
    # a rotation about x: the x axis of the frame is unchanged, y turns by 0.3 rad
    np.testing.assert_allclose(new[:3, 0], root[:3, 0], atol=1e-12)
    assert new[:3, 1] @ root[:3, 1] == pytest.approx(np.cos(0.3), abs=1e-12)


def test_hand_path_is_moved_at_every_step():
    """The batched path (quaternion products) against :func:`moved` (matrices), step by step."""
    root = np.eye(4)
    root[:3, :3] = axis_angle_matrix(np.array([2.0, -1.0, 2.0]) / 3.0, np.array(2.2))
    root[:3, 3] = [0.5, 0.1, 0.3]
    centre = np.array([0.55, 0.12, 0.25])
    profile = LiftProfile()
    positions, orientations, centres = hand_path(profile, root, centre, 1e-3)
    assert len(positions) == round(profile.duration / 1e-3)
    for i in range(0, len(positions), 97):
        shift, angle = profile.motion((i + 1) * 1e-3)
        np.testing.assert_allclose(pose_matrix(positions[i], orientations[i]),
                                   moved(root, centre, shift, angle), atol=1e-12)
        np.testing.assert_allclose(centres[i], centre + shift, atol=1e-15)


# ---------------------------------------------------------------------------- the world


def test_object_body_has_the_cubes_mass_inertia_and_pose():
    obj = load_object("cube")
    world = PhysicsWorld(obj, WorldSettings(density=500.0))
    try:
        mass = 500.0 * 0.06**3  # closed form: a 6 cm cube
        assert world.mass == pytest.approx(mass, rel=1e-12)
        info = world.bullet.getDynamicsInfo(world.object_body, -1)
        assert info[0] == pytest.approx(mass, rel=1e-12)
        np.testing.assert_allclose(info[2], [mass * 0.06**2 / 6] * 3, rtol=1e-9)
        assert info[1] == pytest.approx(0.5)  # lateral friction = mu (hand links: 1.0)
        np.testing.assert_allclose(world.object_pose(), obj.pose, atol=1e-12)
    finally:
        world.close()


def test_hand_frames_match_the_robot_kinematics():
    grasp = shipped_grasps("spray_flask")[3]
    world = PhysicsWorld(load_object("spray_flask"))
    try:
        world.reset(KIN.pose(grasp.q0[None], "sdh_base")[0], hand_joint_values(grasp.q0[7:]))
        for link in ("palm", "f1_tip", "f2_tip", "f3_tip", "f2_distal"):
            np.testing.assert_allclose(world.link_pose(link), KIN.pose(grasp.q0[None], link)[0],
                                       atol=1e-6)
        assert world.penetration() == 0.0
    finally:
        world.close()


# ---------------------------------------------------------------------------- closing


def _compare_with_kinematic(name: str, indices) -> list[tuple[float, float]]:
    """(point distance m, normal angle rad) of every contact pair: physics closing with the
    object fixed and no noise against the kinematic reference, per shipped grasp."""
    obj = load_object(name)
    world, reference = PhysicsWorld(obj, WorldSettings(object_free=False)), GraspWorld(obj)
    out = []
    try:
        for i in indices:
            q0 = shipped_grasps(name)[i].q0
            root = KIN.pose(q0[None], "sdh_base")[0]
            ref = auto_close(reference, root, q0[7:])
            phys = physics_close(world, root, q0[7:])
            assert not phys.start_collision and not any(phys.missed)
            ref_contacts = {(c.finger, c.link): c for c in ref.contacts}
            phys_contacts = {(c.finger, c.link): c for c in phys.contacts}
            assert set(phys_contacts) == set(ref_contacts), (name, i)
            for key, c in ref_contacts.items():
                p = phys_contacts[key]
                out.append((float(np.linalg.norm(p.point - c.point)),
                            float(np.arccos(np.clip(p.normal @ c.normal, -1.0, 1.0)))))
    finally:
        world.close()
        reference.close()
    return out


#: Measured over the 24 shipped cube and spray-flask grasps: largest distance 0.99 mm, largest
#: angle 5.3 deg (a cube edge, where the normal turns); median 0.01 mm, 0.1 deg.
CONTACT_DISTANCE_TOL = 2e-3
CONTACT_ANGLE_TOL = np.radians(8.0)


@pytest.mark.parametrize("name", ["cube", "spray_flask"])
def test_fixed_object_contacts_match_the_kinematic_closing_on_every_shipped_grasp(name):
    pairs = np.array(_compare_with_kinematic(name, range(len(shipped_grasps(name)))))
    assert pairs[:, 0].max() < CONTACT_DISTANCE_TOL
    assert pairs[:, 1].max() < CONTACT_ANGLE_TOL
    assert np.median(pairs[:, 0]) < 1e-4


def test_grip_presses_with_the_distal_motors_torque():
    """The moment of pybullet's contact forces about each distal joint balances the motor's
    torque limit (measured 1.28-1.30 N m of 1.4 with the object fixed: within 15%)."""
    x, z, preshape = OPPOSED
    q0 = palm_down(x, z, preshape)
    settings = MotorSettings()
    world = PhysicsWorld(load_object("cube"), WorldSettings(object_free=False))
    try:
        physics_close(world, KIN.pose(q0[None], "sdh_base")[0], q0[7:], settings)
        grip(world, settings)
        world.step(250)
        for finger in FINGERS:
            link = world.link_index[finger[3]]
            frame = world.link_pose(finger[3])
            axis, origin = frame[:3, 1], frame[:3, 3]  # the distal joint turns about link y
            moment = 0.0
            for rec in world.contact_points():
                if rec[3] == link:
                    force = (rec[9] * np.asarray(rec[7]) + rec[10] * np.asarray(rec[11])
                             + rec[12] * np.asarray(rec[13]))
                    moment += np.cross(np.asarray(rec[5]) - origin, force) @ axis
            assert -moment == pytest.approx(settings.distal_torque, rel=0.15), finger
    finally:
        world.close()


# ---------------------------------------------------------------------------- engine


def test_physics_engine_is_an_engine_with_the_same_interface(cube_engine):
    assert isinstance(cube_engine, Engine) and cube_engine.name == "physics"
    with pytest.raises(ValueError, match="configuration 0 is not finite"):
        cube_engine.run(np.full((1, 14), np.nan))
    fixed = PhysicsEngine("cube", world=WorldSettings(object_free=False))
    try:
        with pytest.raises(ValueError, match="free object"):
            fixed.run_lift(shipped_grasps("cube")[0].q0[None])
    finally:
        fixed.close()


def test_same_draws_same_numbers_in_any_order(cube_engine):
    q = chunk_configurations(shipped_grasps("cube")[2].q0, JointNoise(0.0133), 7, [(0, 4)])
    first = cube_engine.run(q)
    again = cube_engine.run(q[::-1])
    for field in ("outcome", "quality", "n_contacts", "points", "normals", "finger", "hand"):
        assert np.array_equal(getattr(first, field), getattr(again, field)[::-1],
                              equal_nan=True), field
    # the contacts lie on the object where it ended (exact geometry, object frame)
    obj = cube_engine.obj
    for i in range(len(q)):
        k = first.n_contacts[i]
        if k:
            _, distance, _ = obj.closest_points(first.points[i, :k])
            assert np.abs(distance).max() < 1e-3


def test_lift_is_deterministic_and_closes_as_run_does(cube_engine):
    q = chunk_configurations(shipped_grasps("cube")[2].q0, JointNoise(0.0133), 7, [(0, 1)])
    draws_a, lift_a = cube_engine.run_lift(q)
    draws_b, lift_b = cube_engine.run_lift(q)
    plain = cube_engine.run(q)
    assert np.array_equal(draws_a.quality, plain.quality)
    assert np.array_equal(draws_a.quality, draws_b.quality)
    assert np.array_equal(lift_a.held, lift_b.held)
    assert np.array_equal(lift_a.max_offset, lift_b.max_offset)


def test_a_draw_closes_as_in_a_fresh_engine_whatever_came_before():
    """Regression: ``restoreState`` does not reset the contact caches of the object's parts;
    the mug's (52 parts) kept some from the previous draw, and the next draw closed
    differently (here draws 3, 6, 9, 10 of 20) unless the pair is dropped at reset."""
    q = chunk_configurations(grasp_by_index("mug", 0).q0, JointNoise(0.0133), 0, [(0, 7)])
    engine, fresh = PhysicsEngine("mug"), PhysicsEngine("mug")
    try:
        after = engine.run(q[[2, 3, 5, 6]])
        alone = DrawBatch.concatenate([fresh.run(q[i:i + 1]) for i in (3, 6)])
        for field in ("outcome", "quality", "points", "hand"):
            assert np.array_equal(getattr(after, field)[[1, 3]], getattr(alone, field),
                                  equal_nan=True), field
    finally:
        engine.close()
        fresh.close()


def test_a_cube_between_opposed_fingers_holds_at_sigma_zero(cube_engine):
    x, z, preshape = OPPOSED
    q0 = palm_down(x, z, preshape)
    draws, lift = cube_engine.run_lift(q0[None])
    assert OUTCOMES[draws.outcome[0]] == "force_closure"
    assert lift.held[0] and lift.max_offset[0] < 0.01  # measured 1.8 mm
    assert lift.tracking[0] < 3e-3  # the hand follows its path (measured 1.5 mm)


def test_two_fingers_on_one_face_drop_the_cube(cube_engine):
    x, z, preshape = ONE_FACE
    q0 = palm_down(x, z, preshape)
    kinematic = PybulletEngine("cube").run(q0[None])
    assert kinematic.outcome[0] == MISSED  # no force closure at all
    draws, lift = cube_engine.run_lift(q0[None])
    assert draws.outcome[0] != FORCE_CLOSURE
    assert not lift.held[0] and lift.time[0] < 0.5  # falls as soon as gravity is on


@pytest.mark.expensive
def test_two_fingers_on_one_face_almost_never_hold_under_noise(cube_engine):
    x, z, preshape = ONE_FACE
    q = chunk_configurations(palm_down(x, z, preshape), JointNoise(0.0133), 11, [(0, 8)])
    draws, lift = cube_engine.run_lift(q)
    assert not np.any(draws.outcome == FORCE_CLOSURE)
    assert lift.held.sum() <= 1


def test_lift_test_needs_a_free_object():
    world = PhysicsWorld(load_object("cube"), WorldSettings(object_free=False))
    try:
        with pytest.raises(ValueError, match="free object"):
            lift_test(world)
    finally:
        world.close()


def test_quaternion_matrix_is_bullets_own():
    """The same bits as pybullet's getMatrixFromQuaternion (an independent implementation:
    Bullet's C++) on random unit and non-unit quaternions."""
    import pybullet

    from kinegrasp_env.physics.pybullet_world import quaternion_matrix

    rng = np.random.default_rng(0)
    for q in rng.normal(size=(2000, 4)) * rng.uniform(0.5, 2.0, size=(2000, 1)):
        expected = np.reshape(pybullet.getMatrixFromQuaternion(q.tolist()), (3, 3))
        np.testing.assert_array_equal(quaternion_matrix(q), expected)
