"""The Panda (a description robot with parallel jaws) through the reference closing:
planning, closing, contacts and Monte Carlo evaluation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kinegrasp_env.closing.generic_reference import CONTACT_TOL
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine, evaluate_grasp
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.toolkit.grasp_planner import plan_grasps
from kinegrasp_env.world.grasps import Grasp, load_grasps, save_grasps

#: pybullet's GJK distances between convex hulls: measured at most 6e-8 m below zero on the
#: closed grasps here; 1e-6 m stated as margin.
GJK_TOL = 1e-6


@pytest.fixture(scope="module")
def grasps():
    return plan_grasps("panda", "cube", count=3, seed=0)


@pytest.fixture(scope="module")
def engine():
    with RobotReferenceEngine("panda", "cube") as e:
        yield e


def test_planner_finds_grasps_of_the_panda(grasps):
    assert len(grasps) == 3
    for g in grasps:
        assert g.robot == "panda" and g.q0.shape == (8,)
        assert g.q_nominal > 0 and len(g.points) == 2


def test_palm_by_forward_kinematics_matches_pybullet(grasps, engine):
    kin = Kinematics(engine.description.model)
    for g in grasps:
        engine.world.set_configuration(g.q0)
        np.testing.assert_allclose(engine.world.link_pose("panda_hand"),
                                   kin.pose(g.q0, "panda_hand")[0], atol=1e-6)


def test_contacts_against_pybullet_and_the_exact_object(grasps, engine):
    """Contacts at pybullet's own points (no patch centres): a separate closest-point query
    at the final state agrees with them; the point lies on the object's surface (its exact
    convex parts) and the normal is the face's inward normal there."""
    world, obj = engine.world, engine.obj
    world.patch = False
    try:
        _pybullet_contacts(grasps, engine, world, obj)
    finally:
        world.patch = True


def _pybullet_contacts(grasps, engine, world, obj):
    for g in grasps:
        result = engine.close_one(g.q0)
        assert not result.start_collision and not any(result.missed)
        assert len(result.contacts) == 2
        for c in result.contacts:
            link = engine.description.fingers[c.finger].links[c.link]
            rows = world.bullet.getClosestPoints(world.bodies["robot"], world.bodies["object"],
                                                 1.0, linkIndexA=world.link_index[link])
            row = min(rows, key=lambda r: r[8])
            margins = [world.bullet.getDynamicsInfo(row[i], row[j])[11] for i, j in ((1, 3),
                                                                                 (2, 4))]
            assert -GJK_TOL <= row[8] + sum(margins) <= CONTACT_TOL
            np.testing.assert_allclose(c.point, obj.to_object(np.array(row[6])), atol=1e-9)
            bullet_normal = -np.array(row[7]) @ obj.pose[:3, :3]
            _, distance, _ = obj.closest_points(c.point[None])
            assert abs(distance[0]) < 1e-6
            # the cube: faces at +-0.03 in x and y, 0 and 0.06 in z (object frame)
            on = np.abs(np.r_[np.abs(c.point[:2]) - 0.03, c.point[2] * (c.point[2] - 0.06)])
            faces = np.flatnonzero(on < 1e-6)
            if faces.size == 1:  # on one face, off its edges: the face's inward normal
                expected = np.zeros(3)
                k = int(faces[0])
                expected[k] = -np.sign(c.point[k] - (0.03 if k == 2 else 0.0))
                np.testing.assert_allclose(c.normal, expected, atol=1e-12)
                assert np.degrees(np.arccos(c.normal @ bullet_normal)) < 10.0
            else:  # an edge or a corner: pybullet's normal
                np.testing.assert_allclose(c.normal, bullet_normal, atol=1e-9)


def test_jaws_stop_within_contact_tol_of_touching(grasps, engine):
    """Each jaw ends with a gap in [0, CONTACT_TOL] (0.2 mm); 1 mm further it penetrates,
    1 mm back it is clear by more than CONTACT_TOL."""
    world = engine.world
    for g in grasps:
        result = engine.close_one(g.q0)
        for f, finger in enumerate(engine.description.fingers):
            assert -GJK_TOL <= result.gaps[f] <= CONTACT_TOL
            (joint,) = finger.joints
            value = result.joints[joint]
            for shift, check in ((-1e-3, lambda d: d < -5e-4), (1e-3, lambda d: d > CONTACT_TOL)):
                # the jaws close as the joint value decreases (close: -1)
                world.set_joint_values({joint: value + shift})
                gap, _ = world.gap(finger.links)
                assert check(gap), (g.id, f, shift, gap)
            world.set_joint_values({joint: value})


def test_sigma_zero_is_force_closure_on_planned_grasps(grasps, engine):
    for g in grasps:
        r = evaluate_grasp(g, sigma=0.0, n=3, seed=0, engine=engine)
        assert r.p_fc == 1.0 and r.counts["force_closure"] == 3
        np.testing.assert_allclose(r.draws.quality, g.q_nominal, rtol=1e-9)


def test_same_seed_same_result(grasps, engine):
    g = grasps[0]
    a = evaluate_grasp(g, sigma=0.0133, n=12, seed=5, engine=engine)
    b = evaluate_grasp(g, sigma=0.0133, n=12, seed=5, engine=engine)
    c = evaluate_grasp(g, sigma=0.0133, n=12, seed=6, engine=engine)
    np.testing.assert_array_equal(a.draws.outcome, b.draws.outcome)
    np.testing.assert_array_equal(a.draws.quality, b.draws.quality)
    assert not np.array_equal(a.draws.quality, c.draws.quality)
    again = plan_grasps("panda", "cube", count=1, seed=0)
    np.testing.assert_array_equal(again[0].q0, grasps[0].q0)


def test_noise_gives_sensible_outcomes(grasps, engine):
    r = evaluate_grasp(grasps[0], sigma=0.0133, n=20, seed=0, engine=engine)
    assert sum(r.counts.values()) == 20
    assert r.ci[0] <= r.p_fc <= r.ci[1]
    fc = r.draws.outcome == FORCE_CLOSURE
    assert np.all(r.draws.quality[fc] > 0) and np.all(r.draws.quality[~fc] == 0)


def test_grasp_file_records_its_robot(grasps, tmp_path):
    path = save_grasps(grasps, tmp_path / "g.json")
    data = json.loads(path.read_text())
    assert data["robot"] == "panda" and all(e["robot"] == "panda" for e in data["grasps"])
    loaded = load_grasps(path)
    assert [g.robot for g in loaded] == ["panda"] * len(grasps)
    np.testing.assert_array_equal(loaded[0].q0, grasps[0].q0)
    with pytest.raises(ValueError, match="grasp of robot 'panda', not of 'kuka_sdh'"):
        evaluate_grasp(loaded[0], sigma=0.0, n=1, robot="kuka_sdh")
    # a grasp file without a robot is the default robot's, and writes no robot field
    entry = {k: v for k, v in data["grasps"][0].items() if k != "robot"}
    with pytest.raises(ValueError, match="q0 must have 14 entries"):
        Grasp.from_dict(entry)
    default = Grasp("cube", np.zeros(14), np.eye(4), np.zeros((0, 3)), np.zeros((0, 3)),
                    np.zeros(0, int), np.zeros(0, int), 0.0)
    assert "robot" not in default.to_dict()


def test_patch_geometry_against_rectangles():
    """Clipping and centroids against overlaps of axis-aligned rectangles worked by hand."""
    from kinegrasp_env.closing.contact_patch import patch_centre
    from kinegrasp_env.closing.polygon_2d import centroid_2d, clip_convex

    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    moved = square * [2.0, 0.5] + [0.5, 0.25]  # [0.5, 2.5] x [0.25, 0.75]
    np.testing.assert_allclose(centroid_2d(clip_convex(moved, square)), [0.75, 0.5])
    segment = np.array([[-1.0, 0.5], [0.5, 0.5]])
    np.testing.assert_allclose(clip_convex(segment, square), [[0.0, 0.5], [0.5, 0.5]])
    assert len(clip_convex(np.array([[2.0, 2.0]]), square)) == 0
    # a 2 x 1 pad 0.1 above the face z = 0 of a unit cube's top... seen from above
    pad = np.array([[x, y, z] for x in (0.5, 2.5) for y in (0.25, 1.25) for z in (0.1, 0.6)])
    face = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    centre = patch_centre(pad, face, np.array([0.0, 0.0, -1.0]), np.zeros(3))
    np.testing.assert_allclose(centre, [0.75, 0.625, 0.0], atol=1e-12)


def test_patch_centres_lie_under_the_pad(grasps, engine):
    """With patches, a contact is on the face, under the pad's lowest vertices (the pad's
    geometry by trimesh: its hull vertices' distances to the exact object agree with
    pybullet's gap)."""
    from kinegrasp_env.closing.contact_patch import link_hull_vertices

    world, obj = engine.world, engine.obj
    for g in grasps:
        result = engine.close_one(g.q0)
        for c in result.contacts:
            link = engine.description.fingers[c.finger].links[c.link]
            v = obj.to_object(link_hull_vertices(world.bullet, world.bodies["robot"],
                                                 world.link_index[link]))
            _, d, _ = obj.closest_points(v)
            assert abs(d.min() - result.gaps[c.finger]) < 1e-6
            near = v[d <= d.min() + 1e-3]
            offset = near - c.point
            tangential = offset - np.outer(offset @ c.normal, c.normal)
            lo, hi = tangential.min(axis=0), tangential.max(axis=0)
            assert np.all(lo <= 1e-9) and np.all(hi >= -1e-9)  # the point within their box


def test_cli_plans_and_evaluates_the_panda(tmp_path):
    from cli_helpers import run_cli

    out = tmp_path / "g.json"
    done = run_cli("plan", "--robot", "panda", "--object", "cube", "--count", "2", "--seed", "0",
                   "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert json.loads(out.read_text())["robot"] == "panda"
    done = run_cli("evaluate", "--grasps", str(out), "--sigma", "0", "--samples", "4", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["robot"] == "panda" and result["p_fc"] == 1.0
    ranked = tmp_path / "r.csv"
    done = run_cli("rank", str(out), "--sigma", "0", "--samples", "3", "--out", str(ranked))
    assert done.returncode == 0, done.stderr
    rows = ranked.read_text().splitlines()
    assert len(rows) == 3 and all(r.split(",")[1] == "1" for r in rows[1:])
    done = run_cli("evaluate", "--grasps", str(out), "--robot", "kuka_sdh")
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1] == (
        "kinegrasp evaluate: error: grasp '0' is a grasp of robot 'panda', not of 'kuka_sdh'; "
        "use it with robot 'panda' (--robot panda)")


def test_generic_closing_takes_any_description_robot():
    """The same closing on the default robot's description (three revolute fingers): a
    shipped cube grasp closes with every finger within CONTACT_TOL of the object, its contacts
    on the exact surface."""
    from kinegrasp_env.world.grasps import shipped_grasps

    grasp = shipped_grasps("cube")[0]
    with RobotReferenceEngine("kuka_sdh", "cube") as kuka:
        result = kuka.close_one(grasp.q0)
        assert not result.start_collision and not any(result.missed)
        assert np.all((result.gaps >= -GJK_TOL) & (result.gaps <= CONTACT_TOL))
        points = np.array([c.point for c in result.contacts])
        _, distance, _ = kuka.obj.closest_points(points)
        assert len(points) >= 3 and np.all(np.abs(distance) < 1e-6)
        # each touching capsule against the exact object: its axis sampled (URDF collision
        # frame from pybullet's shape data), distance minus radius
        world, bullet = kuka.world, kuka.world.bullet
        robot = world.bodies["robot"]
        for c in result.contacts:
            link = kuka.description.fingers[c.finger].links[c.link]
            (shape,) = bullet.getCollisionShapeData(robot, world.link_index[link])
            assert shape[2] == 7  # GEOM_CAPSULE: (length, radius)
            length, radius = shape[3][:2]
            state = bullet.getLinkState(robot, world.link_index[link],
                                        computeForwardKinematics=True)
            pos, orn = bullet.multiplyTransforms(state[0], state[1], shape[5], shape[6])
            axis = np.reshape(bullet.getMatrixFromQuaternion(orn), (3, 3))[:, 2]
            s = np.linspace(-0.5 * length, 0.5 * length, 401)
            axis_points = kuka.obj.to_object(np.asarray(pos) + s[:, None] * axis)
            _, d, _ = kuka.obj.closest_points(axis_points)
            assert -GJK_TOL <= d.min() - radius <= CONTACT_TOL + 1e-5, (link, d.min() - radius)


def test_evaluate_grasp_takes_a_panda_grasp_with_every_kinematic_engine(grasps, engine):
    """evaluate_grasp evaluates a Panda grasp with the fast and the reference engine by name
    (each built for the grasp's own robot): at sigma 0 every planned grasp is in force
    closure by both, the reference's nominal Q the planner's (which closed it with the same
    reference closing); under noise the reference engine built by name draws and closes
    exactly what the fixture's Panda reference engine does. A default-robot grasp labelled
    'panda' (14 entries) is refused in one line before any draw."""
    import dataclasses

    from kinegrasp_env.world.grasps import shipped_grasps

    for name in ("fast", "pybullet"):
        for g in grasps:
            r = evaluate_grasp(g, sigma=0.0, n=2, seed=0, engine=name)
            assert r.counts["force_closure"] == 2 and r.q_nominal > 0, (name, g.id, r.counts)
            if name == "pybullet":
                assert r.q_nominal == pytest.approx(g.q_nominal, rel=1e-9)
    by_name = evaluate_grasp(grasps[0], sigma=0.0133, n=12, seed=5, engine="pybullet")
    given = evaluate_grasp(grasps[0], sigma=0.0133, n=12, seed=5, engine=engine)
    np.testing.assert_array_equal(by_name.draws.outcome, given.draws.outcome)
    np.testing.assert_array_equal(by_name.draws.quality, given.draws.quality)
    relabelled = dataclasses.replace(shipped_grasps("cube")[0], robot="panda")
    for name in ("fast", "pybullet"):
        with pytest.raises(ValueError, match=r"q0 must have 8 entries \(7 arm \+ 1 hand\), "
                                             r"got 14$") as refused:
            evaluate_grasp(relabelled, sigma=0.01, n=10, engine=name)
        assert "\n" not in str(refused.value)


def test_shipped_grasp_sets_per_robot():
    """The Panda's shipped sets are its own files (grasps recording robot 'panda'); an object
    without one is a one-line error naming those there are; the default robot's are the
    built-in objects' sets."""
    from kinegrasp_env.world.grasps import NoGraspSetError, shipped_grasps, shipped_objects
    from kinegrasp_env.world.names import OBJECT_NAMES

    assert shipped_objects() == OBJECT_NAMES
    objects = shipped_objects("panda")
    assert objects and set(objects) < set(OBJECT_NAMES)
    for name in objects:
        grasps = shipped_grasps(name, "panda")
        assert grasps and all(g.robot == "panda" and g.object == name for g in grasps)
    missing = next(n for n in OBJECT_NAMES if n not in objects)
    with pytest.raises(NoGraspSetError, match=f"no shipped grasps of {missing!r} \\(shipped: "
                       + ", ".join(objects)):
        shipped_grasps(missing, "panda")
