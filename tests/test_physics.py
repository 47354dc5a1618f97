"""The physics closing (pybullet dynamics), the holding test and the physics engine.

Independent references: the kinematic reference closing (exact contacts), the object's exact
geometry (closest points), the robot's own forward kinematics, closed-form mass and inertia of
the cube, pybullet's reported contact forces (moment about the finger joint against the motor's
torque limit), scipy's rotations, and set-ups whose holding is known: an object welded to the
palm must hold in every phase, an object nothing touches must fail every phase, two fingers
pushing one face with nothing opposing them lose their grip.
"""

from __future__ import annotations

import numpy as np
import pybullet
import pytest

from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.montecarlo.engines import (
    FORCE_CLOSURE,
    MISSED,
    Engine,
    PybulletEngine,
)
from kinegrasp_env.montecarlo.evaluate import chunk_configurations
from kinegrasp_env.montecarlo.physics_engine import PhysicsEngine
from kinegrasp_env.physics.hold_runner import GRIP_JOINTS
from kinegrasp_env.physics.motion import hand_path, lift_motion, moved, shake_motion, smoothstep
from kinegrasp_env.physics.protocol import (
    GRAVITY_PHASES,
    GRIP_LOST,
    HELD,
    HOLD_OUTCOMES,
    NO_GRIP,
    PHASES,
    HoldProtocol,
    grip_verdict,
    pose_change,
)
from kinegrasp_env.physics.pybullet_closing import (
    MotorSettings,
    merge_records,
    physics_close,
)
from kinegrasp_env.physics.pybullet_hold import (
    PybulletHold,
    grip_control,
    grip_joints_now,
    grip_until_steady,
    hold_test,
    object_in_palm,
    run_phases,
)
from kinegrasp_env.physics.pybullet_world import PhysicsWorld, WorldSettings, pose_matrix
from kinegrasp_env.robot.default_robot import (
    FINGERS,
    default_description,
    default_hand_mount,
    hand_joint_values,
    kuka_sdh,
)
from kinegrasp_env.robot.ik import ArmIK
from kinegrasp_env.robot.kinematics import Kinematics, axis_angle_matrix
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import load_object

KIN = Kinematics(kuka_sdh())
MOUNT = default_hand_mount()  # the link whose pose places the hand


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


@pytest.mark.parametrize("bad", [{"max_shift": 0.0}, {"gravity_time": -1.0},
                                 {"torque_scale": float("nan")}, {"grip_min_time": 1.0}])
def test_hold_protocol_rejects_bad_values(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        HoldProtocol(**bad)


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


def test_lift_and_shake_move_as_stated():
    """The lift reaches its height with no speed at either end and stays; the shake's
    amplitude and angle peak at the stated values and vanish at both ends."""
    p = HoldProtocol(shake=True)
    times = np.array([0.0, 1e-6, p.lift_time - 1e-6, p.lift_time, p.lift_time + p.hold_time])
    z = lift_motion(p, times)[:, 2]
    assert z[0] == 0.0 and z[3] == pytest.approx(p.lift_height, abs=1e-15) and z[4] == z[3]
    assert z[1] / 1e-6 < 1e-4 and (z[3] - z[2]) / 1e-6 < 1e-4  # minimum jerk: no speed
    t = np.linspace(0, p.shake_time, 2001)
    shifts, angles = shake_motion(p, t)
    amplitude = np.linalg.norm(shifts, axis=1)
    assert p.shake_amplitude * 0.99 <= amplitude.max() <= p.shake_amplitude + 1e-12
    assert np.abs(angles).max() == pytest.approx(p.shake_angle, rel=0.01)
    assert amplitude[0] == 0.0 and amplitude[-1] < 1e-12 and abs(angles[-1]) < 1e-12
    assert smoothstep(-1.0) == 0.0 and smoothstep(2.0) == 1.0


def test_pose_change_against_scipy():
    """Distance of the centre of mass and rotation angle between two poses, against scipy's
    rotation magnitude and a direct difference of the transformed centre."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4)
    com = np.array([0.01, -0.02, 0.03])
    for _ in range(50):
        a, b = np.eye(4), np.eye(4)
        ra, rb = Rotation.random(2, random_state=rng.integers(1 << 30))
        a[:3, :3], b[:3, :3] = ra.as_matrix(), rb.as_matrix()
        a[:3, 3], b[:3, 3] = rng.normal(size=3), rng.normal(size=3)
        distance, angle = pose_change(a, b, com)
        assert distance == pytest.approx(np.linalg.norm(rb.apply(com) + b[:3, 3]
                                                        - ra.apply(com) - a[:3, 3]), rel=1e-12)
        assert angle == pytest.approx((ra.inv() * rb).magnitude(), abs=1e-7)


def test_grip_verdict_by_hand():
    """The grip's outcome rules on hand-made finger forces (contact force 0.05 N)."""
    p = HoldProtocol()
    assert grip_verdict([3.0, 0.0, 0.0], [3.0, 0.0, 0.0], p) == NO_GRIP  # one finger
    assert grip_verdict([3.0, 2.0, 1.0], [3.0, 2.0, 0.01], p) == GRIP_LOST  # a finger at ~0 N
    assert grip_verdict([3.0, 2.0, 0.0], [3.0, 0.0, 1.0], p) == GRIP_LOST  # one finger left
    assert grip_verdict([3.0, 2.0, 0.0], [2.5, 1.0, 0.0], p) == HELD
    assert grip_verdict([3.0, 2.0, 0.0], [2.5, 1.0, 4.0], p) == HELD  # a new contact is fine


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
    times = 1e-3 * np.arange(1, 1501)
    shifts, angles = shake_motion(HoldProtocol(), times)
    shifts = shifts + lift_motion(HoldProtocol(), times)
    positions, orientations, centres = hand_path(shifts, angles, root, centre)
    assert len(positions) == len(times)
    for i in range(0, len(positions), 97):
        np.testing.assert_allclose(pose_matrix(positions[i], orientations[i]),
                                   moved(root, centre, shifts[i], angles[i]), atol=1e-12)
        np.testing.assert_allclose(centres[i], centre + shifts[i], atol=1e-15)


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
        world.reset(KIN.pose(grasp.q0[None], MOUNT)[0], hand_joint_values(grasp.q0[7:]))
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
    world = PhysicsWorld(obj, WorldSettings(object_free=False))
    reference = RobotWorld(default_description(), obj)
    out = []
    try:
        for i in indices:
            q0 = shipped_grasps(name)[i].q0
            root = KIN.pose(q0[None], MOUNT)[0]
            ref = reference.auto_close(q0)
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


#: Largest gap between a loaded joint's commanded torque and the moment of pybullet's contact
#: forces about its axis, after the grip on the pinned cube, for a joint off its limits
#: (measured over the twelve shipped grasps: at most 0.017 N m, grasp 7, of torques up to
#: 2.1 N m), x 2.
MOMENT_TOL = 0.035
#: A joint within this angle of a limit rests on it, radians.
LIMIT_ANGLE = 1e-3


def _carried(joint: int, finger: int, link: int) -> bool:
    """Joint ``joint`` of :data:`GRIP_JOINTS` carries a contact on (finger, link): a flexion
    joint the contacts on its own link and beyond, a spread joint every link of its finger."""
    if joint < 6:
        return finger == joint // 2 and link >= joint % 2
    return finger == joint - 6


@pytest.mark.parametrize("index", range(12))
def test_grip_contact_forces_carry_the_commanded_joint_torques(index):
    """After the grip, the moment of pybullet's contact forces (normal and both friction
    directions, from its own records) about each loaded grip joint's axis (flexion and spread)
    equals the torque the grip commands there: the fingers press with the balanced torques,
    not with more. A joint resting on its limit (the spread of grasps with the fingers side by
    side) gets the limit's reaction added, only in the direction the limit pushes."""
    sim, _ = _closed_on_pinned("cube", shipped_grasps("cube")[index].q0)
    try:
        world = sim.world
        control = grip_control(world, sim.motors, sim.protocol)
        grip_until_steady(world, control, sim.protocol)
        angles, _ = world.joint_states(GRIP_JOINTS)
        commanded = control.spring.torques(angles)
        joints = grip_joints_now(world, sim.motors)
        moments = np.zeros(len(GRIP_JOINTS))
        links = {world.link_index[FINGERS[f][2 + k]]: (f, k) for f in range(3) for k in range(2)}
        for rec in world.contact_points():
            if rec[3] not in links:
                continue
            finger, link = links[rec[3]]
            on_object = (-rec[9] * np.asarray(rec[7]) + rec[10] * np.asarray(rec[11])
                         + rec[12] * np.asarray(rec[13]))
            for j in range(len(GRIP_JOINTS)):
                if _carried(j, finger, link):
                    lever = np.cross(joints.axes[j], np.asarray(rec[5]) - joints.origins[j])
                    moments[j] += lever @ on_object
        loaded = control.spring.loaded
        assert loaded[:6].sum() >= 4
        gap = moments - commanded
        bounds = np.array([world.bullet.getJointInfo(world.hand, world.joint_index[j])[8:10]
                           for j in GRIP_JOINTS])
        at_lower = np.abs(angles - bounds[:, 0]) < LIMIT_ANGLE
        at_upper = np.abs(angles - bounds[:, 1]) < LIMIT_ANGLE
        free = loaded & ~at_lower & ~at_upper
        np.testing.assert_allclose(moments[free], commanded[free], atol=MOMENT_TOL)
        # a joint resting on its limit: the limit adds its reaction, in its own direction
        assert np.all(gap[loaded & at_upper] <= MOMENT_TOL)
        assert np.all(gap[loaded & at_lower] >= -MOMENT_TOL)
        assert np.all(np.abs(commanded[loaded]) <= control.spring.limits[loaded] + 1e-12)
    finally:
        sim.close()


#: Largest grip shift allowed on a shipped grasp whose grip stands (the requirement), metres.
GRIP_SHIFT_MAX = 2e-3


def test_the_release_hardly_moves_the_cube_on_its_force_closure_grasps(cube_engine):
    """Every shipped cube grasp at sigma 0 is in force closure in physics, its grip stands
    (no contact lost on release) and the release moves the object by at most 2 mm against
    its pinned pose (measured: at most 0.38 mm)."""
    q = np.array([g.q0 for g in shipped_grasps("cube")])
    closing, hold = cube_engine.run_hold(q)
    fc = closing.outcome == FORCE_CLOSURE
    assert fc.sum() == len(q)
    lost = np.isin(hold.outcome, [HOLD_OUTCOMES.index(k) for k in ("no_grip", "grip_lost")])
    assert not lost.any(), hold.outcome
    assert np.all(hold.grip_shift <= GRIP_SHIFT_MAX), hold.grip_shift


# ---------------------------------------------------------------------------- engine


def test_physics_engine_is_an_engine_with_the_same_interface(cube_engine):
    assert isinstance(cube_engine, Engine) and cube_engine.name == "physics"
    with pytest.raises(ValueError, match="configuration 0 is not finite"):
        cube_engine.run(np.full((1, 14), np.nan))
    fixed = PhysicsEngine("cube", world=WorldSettings(object_free=False))
    try:
        with pytest.raises(ValueError, match="free object"):
            fixed.run_hold(shipped_grasps("cube")[0].q0[None])
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


def test_hold_is_deterministic_in_any_order(cube_engine):
    """The same configurations give the same bits, in either order (every draw starts from
    the saved state; the phases from one saved state per draw)."""
    q = chunk_configurations(shipped_grasps("cube")[9].q0, JointNoise(0.0133), 7, [(0, 2)])
    draws_a, hold_a = cube_engine.run_hold(q)
    draws_b, hold_b = cube_engine.run_hold(q[::-1])
    assert np.array_equal(draws_a.quality, draws_b.quality[::-1])
    for field in hold_a.FIELDS:
        assert np.array_equal(getattr(hold_a, field), getattr(hold_b, field)[::-1],
                              equal_nan=True), field


def _closed_on_pinned(name: str, q0: np.ndarray):
    """A world with the hand closed on the pinned object at q0 (14,), and its motors."""
    sim = PybulletHold(load_object(name), 0.5, HoldProtocol())
    closing = physics_close(sim.world, KIN.pose(q0[None], MOUNT)[0], q0[7:], sim.motors,
                            pin=True)
    return sim, closing


#: The pinned object's largest displacement while the hand closes and grips with the
#: assumed torques (measured on cube grasps 4 and 9: 0.19 and 0.05 mm, under grip forces of
#: 35-80 N per finger), x 2.5.
PIN_TOL = 5e-4


@pytest.mark.parametrize("index", [4, 9])
def test_a_pinned_object_stays_put_while_the_hand_closes_and_grips(index):
    """The object does not move before the test starts: against its catalog pose (not the
    code's own reading), while the hand closes and the grip builds up to steady forces; the
    pin then carries the grip's net force (pybullet's constraint state)."""
    sim, _ = _closed_on_pinned("cube", shipped_grasps("cube")[index].q0)
    try:
        world, p = sim.world, sim.protocol
        forces, _ = grip_until_steady(world, grip_control(world, sim.motors, sim.protocol), p)
        assert (forces > p.contact_force).sum() >= 2
        assert np.linalg.norm(world.object_pose()[:3, 3] - world.obj.pose[:3, 3]) < PIN_TOL
        assert np.abs(world.object_pose()[:3, :3] - world.obj.pose[:3, :3]).max() < 10 * PIN_TOL
        assert world.pin_load()[0] > 0.0
    finally:
        sim.close()


def test_two_fingers_on_one_face_have_no_grip():
    """Two fingers pushing one face, the third closing on nothing: no contact forces in
    equilibrium exist (both push the same way), so the grip does not start: ``no_grip``, no
    release, no phase run. Also the same draw through the engine, against the kinematic
    reference's outcome (missed: no force closure)."""
    x, z, preshape = ONE_FACE
    q0 = palm_down(x, z, preshape)
    sim, _ = _closed_on_pinned("cube", q0)
    try:
        assert grip_control(sim.world, sim.motors, sim.protocol) is None
        result = hold_test(sim.world, sim.motors, sim.protocol)
        assert HOLD_OUTCOMES[result.outcome] == "no_grip", result
        assert result.phase_held == {}
        assert np.isnan(result.grip_shift)
    finally:
        sim.close()
    assert PybulletEngine("cube").run(q0[None]).outcome[0] == MISSED


def _phase_world(weld: bool):
    """A world after the grip on cube grasp 9 whose object is then either welded to the palm
    (a fixed constraint: it must hold in every phase) or left with the hand moved away and
    open (nothing touches it: it must fail every phase)."""
    q0 = shipped_grasps("cube")[9].q0
    sim, _ = _closed_on_pinned("cube", q0)
    world = sim.world
    control = grip_control(world, sim.motors, sim.protocol)
    grip_until_steady(world, control, sim.protocol)
    bullet = world.bullet
    if weld:
        # pybullet's constraint frames are relative to the links' centres of mass
        palm = pose_matrix(*bullet.getLinkState(world.hand, world.link_index["palm"])[:2])
        com = pose_matrix(*bullet.getBasePositionAndOrientation(world.object_body))
        position, orientation = _pose(np.linalg.inv(palm) @ com)
        weld_id = bullet.createConstraint(world.hand, world.link_index["palm"],
                                          world.object_body, -1, pybullet.JOINT_FIXED,
                                          [0, 0, 0], position, [0, 0, 0],
                                          parentFrameOrientation=orientation)
        bullet.changeConstraint(weld_id, maxForce=1e4)
    else:
        away = world.link_pose("hand_root")
        away[:3, 3] += [0.0, 0.0, 0.5]
        world.bullet.resetBasePositionAndOrientation(world.hand, *_pose(away))
        world.move_anchor(away)
    world.release_object()
    world.step(1)
    return sim, control


def _pose(matrix):
    from kinegrasp_env.world.sim import matrix_to_pose

    return matrix_to_pose(matrix)


@pytest.mark.parametrize("weld", [True, False])
def test_the_phases_against_known_truths(weld):
    """Rest, six gravity directions, the lift and the shake: an object welded to the palm
    holds in every one (it moves with the hand: within 1 mm); an object nothing touches stays
    put at rest (no force on it) and fails every other one (it falls 2 cm in 64 ms under g,
    well inside a phase), whatever the direction."""
    import dataclasses

    sim, control = _phase_world(weld)
    try:
        world = sim.world
        protocol = dataclasses.replace(sim.protocol, shake=True)
        from kinegrasp_env.physics.protocol import HoldResult

        result = HoldResult(HELD)
        state = world.bullet.saveState()
        run_phases(world, control, protocol, object_in_palm(world), state, result)
        world.bullet.removeState(state)
        if weld:
            assert result.phase_held == dict.fromkeys(PHASES, True)
            assert max(result.phase_shift.values()) < 1e-3
        else:
            # the lift fails, so the shake is not run
            assert result.phase_held == {**dict.fromkeys(PHASES[:-1], False), "rest": True}
            assert set(result.phase_held) >= set(GRAVITY_PHASES)
    finally:
        sim.close()


def test_hold_counts_are_consistent_on_real_draws(cube_engine):
    """On real draws: phases run exactly on the draws whose grip stood, ``held`` exactly when
    every phase run held, the shake never run without the flag, shifts only where released."""
    q = np.array([g.q0 for g in shipped_grasps("cube")[3:6]])
    _, hold = cube_engine.run_hold(q)
    stood = np.isin(hold.outcome, [HOLD_OUTCOMES.index(k)
                                   for k in ("held", "dropped", "grip_unsteady")])
    ran = hold.phase_held[:, :8] >= 0
    assert np.array_equal(ran.all(axis=1), stood) and np.array_equal(ran.any(axis=1), stood)
    assert np.all(hold.phase_held[:, PHASES.index("shake")] == -1)
    assert np.array_equal(hold.held, stood & (hold.phase_held[:, :8] == 1).all(axis=1))
    rest = hold.phase_held[:, PHASES.index("rest")]
    assert np.array_equal(hold.outcome == HOLD_OUTCOMES.index("grip_unsteady"),
                          stood & (rest == 0))
    released = hold.outcome != HOLD_OUTCOMES.index("no_grip")
    assert np.array_equal(np.isfinite(hold.grip_shift), released)


def test_hold_test_needs_a_pinned_object():
    world = PhysicsWorld(load_object("cube"))
    try:
        with pytest.raises(ValueError, match="pinned"):
            hold_test(world, MotorSettings(), HoldProtocol())
    finally:
        world.close()


def test_torque_scale_scales_the_grip_forces():
    """Twice the torque limits, twice the grip: the fingers' steady normal forces on the
    pinned cube scale with the torque (pybullet's contact forces, not the code's own numbers;
    within 25%: the contact points shift a little with the force)."""
    x, z, preshape = OPPOSED
    q0 = palm_down(x, z, preshape)
    totals = []
    for scale in (1.0, 2.0):
        protocol = HoldProtocol(torque_scale=scale)
        sim = PybulletHold(load_object("cube"), 0.5, protocol)
        try:
            physics_close(sim.world, KIN.pose(q0[None], MOUNT)[0], q0[7:], sim.motors,
                          pin=True)
            control = grip_control(sim.world, sim.motors, protocol)
            forces, _ = grip_until_steady(sim.world, control, protocol)
            totals.append(forces.sum())
            assert sim.motors.distal_torque == pytest.approx(1.4 * scale)
        finally:
            sim.close()
    assert totals[1] / totals[0] == pytest.approx(2.0, rel=0.25)


def test_quaternion_matrix_is_bullets_own():
    """The same bits as pybullet's getMatrixFromQuaternion (an independent implementation:
    Bullet's C++) on random unit and non-unit quaternions."""
    import pybullet

    from kinegrasp_env.physics.pybullet_world import quaternion_matrix

    rng = np.random.default_rng(0)
    for q in rng.normal(size=(2000, 4)) * rng.uniform(0.5, 2.0, size=(2000, 1)):
        expected = np.reshape(pybullet.getMatrixFromQuaternion(q.tolist()), (3, 3))
        np.testing.assert_array_equal(quaternion_matrix(q), expected)


def test_a_phase_verdict_does_not_depend_on_the_phases_before():
    """The phases run twice from one saved post-release state, the second time right after
    the first run's lift (the hand 10 cm up, its contacts cached): the same verdicts, shifts
    and turns, bit for bit: every phase restarts from the state, the hand's anchor (which
    ``restoreState`` leaves where the lift put it) included. Cube grasp 7 at twice the
    assumed torques (a draw close to its limits)."""
    from kinegrasp_env.physics.protocol import HoldResult

    q0 = shipped_grasps("cube")[7].q0
    protocol = HoldProtocol(torque_scale=2.0)
    sim = PybulletHold(load_object("cube"), 0.5, protocol)
    try:
        world = sim.world
        physics_close(world, KIN.pose(q0[None], MOUNT)[0], q0[7:], sim.motors, pin=True)
        control = grip_control(world, sim.motors, protocol)
        grip_until_steady(world, control, protocol)
        world.release_object()
        control.step(200)
        reference, state = object_in_palm(world), world.bullet.saveState()
        runs = []
        for _ in range(2):
            result = HoldResult(HELD)
            run_phases(world, control, protocol, reference, state, result)
            runs.append(result)
        world.bullet.removeState(state)
        assert runs[0].phase_held == runs[1].phase_held
        assert runs[0].phase_shift == runs[1].phase_shift
        assert runs[0].phase_turn == runs[1].phase_turn
    finally:
        sim.close()
