"""Capsules, spheres and cylinders in the fast generic closing: the default robot's SDH (its
capsule fingers, its cylinder palm and knuckles) run through the engines of every
description robot, against the generic reference (pybullet's closest points on the same
URDF, its cylinders implicit)."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinegrasp_env.closing.close_rules import EXACT_BAND
from kinegrasp_env.closing.finger_paths import link_poses
from kinegrasp_env.closing.link_geometry import CYLINDER_SIDES, link_geometry
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.world.grasps import shipped_grasps

SIGMA = 0.0133
DRAWS = 40
OBJECTS = ("drill", "mug")
#: Same outcome on the same draws: 600 of 600 measured (the four objects, 3 grasps x 50
#: draws; the fast engine's capsule kernel); 97% held.
SAME_OUTCOME = 0.97
#: Contact points: median 2.5e-12 m, 99th percentile 1.4e-9 measured on 600 draws (three
#: grasps of each object x 50 draws: both closings polish a revolute finger's touch to a
#: zero gap of the same exact pair); 1e-10 and 1e-8 held. Normals: median 3.3e-11, 99th
#: percentile 4.8e-8 there; 1e-9 and 1e-6 held. (With pybullet's distances near contact
#: the reference's were 6.6e-9 and 1.8e-5 apart.)
POINT_MEDIAN, POINT_P99, NORMAL_MEDIAN, NORMAL_P99 = 1e-10, 1e-8, 1e-9, 1e-6
#: A capsule link's exact distance against pybullet's: median 1.7e-6 m, at most 8.3e-6
#: measured (288 distances, closed and opened by 0.05 rad: pybullet's GJK on capsules);
#: 2e-5 held.
GAP_TOL = 2e-5


@pytest.fixture(scope="module")
def engines():
    pairs = {obj: (make_engine("fast", "kuka_sdh", obj), make_engine("pybullet", "kuka_sdh",
                                                                      obj))
             for obj in OBJECTS}
    yield pairs
    for fast, reference in pairs.values():
        fast.close()
        reference.close()


@pytest.fixture(scope="module")
def draws(engines):
    """(object, q (n, 14), fast draws, reference draws) for two shipped grasps an object."""
    out = []
    for obj, (fast, reference) in engines.items():
        for index in (0, 1):
            rng = np.random.default_rng(index)
            q = np.repeat(shipped_grasps(obj)[index].q0[None], DRAWS, axis=0)
            q[:, :7] += rng.normal(0.0, SIGMA, (DRAWS, 7))
            out.append((obj, q, fast.run(q), reference.run(q)))
    return out


def _urdf_shapes() -> dict[str, tuple[str, dict, np.ndarray]]:
    """link -> (shape kind, its attributes, its (4, 4) origin) of the SDH's collision
    shapes, read from the URDF's XML (independently of pybullet)."""
    root = ET.parse(load_robot("kuka_sdh").urdf).getroot()
    out = {}
    for link in root.iter("link"):
        collision = link.find("collision")
        if collision is None:
            continue
        shape = collision.find("geometry")[0]
        if shape.tag not in ("capsule", "cylinder"):
            continue
        origin = collision.find("origin")
        frame = np.eye(4)
        if origin is not None:
            frame[:3, 3] = [float(v) for v in origin.get("xyz", "0 0 0").split()]
            rpy = [float(v) for v in origin.get("rpy", "0 0 0").split()]
            frame[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF: fixed axes
        out[link.get("name")] = (shape.tag, {k: float(v) for k, v in shape.attrib.items()},
                                 frame)
    return out


def test_the_urdfs_capsules_and_cylinders_are_read_as_written():
    """Each capsule: a rounded part of the URDF's radius whose core is the shape's z axis,
    its length long, centred at the shape's origin (to 1e-12 m: read from the XML in double
    precision); each cylinder: a prism of CYLINDER_SIDES sides whose vertices lie on the
    cylinder's rims (distance r from the axis, +-length/2 along it), to 5e-8 m: pybullet's
    link frames, through which it is read, are single precision (1.3e-8 m measured). The
    frames here come from the XML by scipy's fixed-axis Euler angles, not the library's."""
    shapes = _urdf_shapes()
    geometry = link_geometry(load_robot("kuka_sdh"), tuple(shapes))
    assert sorted(kind for kind, _, _ in shapes.values()).count("capsule") == 6
    for link, (kind, attrs, frame) in shapes.items():
        geom = geometry[link]
        if kind == "capsule":
            (part,) = geom.rounded
            assert part.radius == pytest.approx(attrs["radius"], abs=1e-12)
            assert np.allclose(0.5 * (part.a + part.b), frame[:3, 3], rtol=0, atol=1e-12)
            assert np.allclose(part.b - part.a, attrs["length"] * frame[:3, 2], rtol=0,
                               atol=1e-12)
            assert geom.curved and not geom.parts
        else:
            (part,) = geom.parts
            local = (part.vertices - frame[:3, 3]) @ frame[:3, :3]  # the shape's frame
            assert len(local) == 2 * CYLINDER_SIDES
            assert np.allclose(np.hypot(local[:, 0], local[:, 1]), attrs["radius"], atol=5e-8)
            assert np.allclose(np.abs(local[:, 2]), 0.5 * attrs["length"], atol=5e-8)
            assert geom.curved and not geom.rounded


def test_the_sdh_closes_alike_in_both_generic_engines(draws):
    """The same outcome on the same draws, and the contacts of the draws that agree within
    the closings' stopping tolerance."""
    same = sum(int((a.outcome == b.outcome).sum()) for _, _, a, b in draws)
    total = sum(a.outcome.size for _, _, a, _ in draws)
    assert same >= SAME_OUTCOME * total, f"{same} of {total}"
    assert any((a.outcome == FORCE_CLOSURE).any() for _, _, a, _ in draws)
    points, normals = [], []
    for _, _, a, b in draws:
        for i in np.flatnonzero((a.outcome == b.outcome) & (a.n_contacts == b.n_contacts)):
            k = a.n_contacts[i]
            oa = np.lexsort((a.link[i, :k], a.finger[i, :k]))
            ob = np.lexsort((b.link[i, :k], b.finger[i, :k]))
            if not np.array_equal(a.finger[i, oa], b.finger[i, ob]):
                continue
            points += list(np.linalg.norm(a.points[i, oa] - b.points[i, ob], axis=1))
            normals += list(np.linalg.norm(a.normals[i, oa] - b.normals[i, ob], axis=1))
    assert len(points) > 100
    assert np.median(points) <= POINT_MEDIAN and np.median(normals) <= NORMAL_MEDIAN
    assert np.percentile(points, 99) <= POINT_P99
    assert np.percentile(normals, 99) <= NORMAL_P99


def test_a_capsule_links_exact_distance_is_pybullets(draws, engines):
    """At the reference's closed state of noisy draws, and with the fingers opened from
    there by 0.05 rad, each finger capsule's exact distance (the fast closing's) equals
    pybullet's GJK distance, and the reference's distance (exact near contact:
    ``RobotScene.link_gap``) equals the fast closing's to 1e-9 m (the same exact pair, the
    link placed by the model's kinematics, not pybullet's)."""
    checked = near = 0
    for obj, q_all, _, _ in draws:
        fast, reference = engines[obj]
        world, hand = reference.world, fast.hand
        for q in q_all[:4]:
            result = world.auto_close(q)
            if result.start_collision:
                continue
            for opening in (0.0, -0.05):
                values = {k: np.atleast_1d(v) for k, v in hand.model.expand(q[None]).items()}
                values.update({k: np.array([v + opening]) for k, v in result.joints.items()})
                world.set_joint_values({k: float(v[0]) for k, v in values.items()})
                palm = hand.obj.pose_inverse @ hand.kinematics.pose(q, hand.description.palm_link)
                for path in hand.paths:
                    for link in path.links:
                        d = hand.exact(link_poses(palm, values, path.chains[link]), link)[0]
                        expected = world.bullet_gap(link)
                        assert abs(d[0] - expected) <= GAP_TOL, (link, d[0], expected)
                        if abs(expected) <= EXACT_BAND:
                            assert abs(world.link_gap(link) - d[0]) <= 1e-9
                            near += 1
                        checked += 1
    assert checked >= 60 and near >= 20


def test_a_rounded_links_gap_is_the_same_with_or_without_the_exact_first_shortcut(draws,
                                                                                 engines):
    """``RobotScene.link_gap`` measures a rounded link that was near contact at its previous
    measurement exactly, without pybullet, where the exact gap lies inside the band by
    ``BULLET_TOLERANCE`` (10x the largest gap between pybullet's distance and the exact one,
    ``GAP_TOL``, above). At states around the reference's closed hands, the gap so measured
    equals the one measured pybullet-first (the hint cleared) bit for bit, and the shortcut is
    taken (the exact band's states are many)."""
    from kinegrasp_env.closing.scene import BULLET_TOLERANCE

    assert BULLET_TOLERANCE >= 10 * GAP_TOL
    shortcut = 0
    for obj, q_all, _, _ in draws:
        world = engines[obj][1].world
        for q in q_all[:4]:
            result = world.auto_close(q)
            if result.start_collision:
                continue
            # each state measured with the hint its predecessor left (near contact, then
            # farther from and nearer to it, then clear of it), then pybullet first
            for opening in (0.0, -0.002, 0.002, -0.05, 0.0):
                world.stage_joint_values({k: v + opening for k, v in result.joints.items()})
                for link in world.rounded:
                    hinted = link in world._near  # the hint (private)
                    gap = world.link_gap(link)
                    shortcut += hinted and world.surely_in_band(link, gap)
                    world.place_object(world.placed)  # forgets the state's distances
                    near = set(world._near)
                    world._near.clear()
                    assert world.link_gap(link) == gap, (link, opening)
                    world._near = near
    assert shortcut >= 20


def test_a_draws_closing_does_not_depend_on_its_batch(engines):
    """The batched loop's staged fingers polish their touches in groups (the draws that touch
    over several steps wait for one polish): a draw's closing must be the one it has alone.
    120 noisy draws of a drill grasp closed by the loop (the capsule kernel off) in one
    batch, in three shuffled batches and the first 12 one by one: every array of the result
    equal bit for bit."""
    from kinegrasp_env.closing.generic_fast import FastRobotHand

    fast = engines["drill"][0]
    hand = FastRobotHand(fast.description, fast.obj, compiled=False)
    rng = np.random.default_rng(21)
    q = np.repeat(shipped_grasps("drill")[1].q0[None], 120, axis=0)
    q[:, :7] += rng.normal(0.0, 0.02, (120, 7))
    whole = hand.close_batch(q)
    order = rng.permutation(len(q))
    parts = [order[:70], order[70:100], order[100:]] + [np.array([i]) for i in range(12)]
    for rows in parts:
        part = hand.close_batch(q[rows])
        np.testing.assert_array_equal(part.start_collision, whole.start_collision[rows])
        np.testing.assert_array_equal(part.gaps, whole.gaps[rows])
        np.testing.assert_array_equal(part.travel, whole.travel[rows])
        np.testing.assert_array_equal(part.queries, whole.queries[rows])
        for name, values in part.joints.items():
            np.testing.assert_array_equal(values, whole.joints[name][rows])
        for i, row in enumerate(rows):
            mine, theirs = part.row == i, whole.row == row
            np.testing.assert_array_equal(part.points[mine], whole.points[theirs])
            np.testing.assert_array_equal(part.normals[mine], whole.normals[theirs])
    assert len(whole.row) > 200  # the draws touch: the polish ran


def test_capsule_fingers_close_as_the_batched_loop():
    """The SDH's fingers (two capsule phalanxes) are closed by the compiled capsule kernel
    (the default robot's own closing model: grid gaps, exact within a band, bisection);
    the batched loop (GJK bounds, exact pairs, halving; an implementation of the generic
    model that shares no closing code with the kernel) on the same draws: the same outcome
    on 2400 of 2400 draws (two grasps of each object, 300 draws each; 98% held), and where
    the same links touch, contact points 1.7e-12 m apart at the median, 8.9e-10 at the 99th
    percentile (both polish a touch to a zero gap; 1e-9 held at the median)."""
    from kinegrasp_env.closing.capsule_fingers import capsule_finger
    from kinegrasp_env.closing.generic_fast import FastRobotHand

    same = total = 0
    offsets = []
    for obj in ("cube", "drill", "mug", "spray_flask"):
        fast = make_engine("fast", "kuka_sdh", obj)
        loop = FastRobotHand(fast.description, fast.obj, compiled=False)
        assert all(capsule_finger(f, path, loop.geometry) is not None
                   for f, path in enumerate(loop.paths))
        for index in (0, 1):
            rng = np.random.default_rng(40 + index)
            q = np.repeat(shipped_grasps(obj)[index].q0[None], 300, axis=0)
            q[:, :7] += rng.normal(0.0, SIGMA, (300, 7))
            a, b = fast.hand.close_batch(q), loop.close_batch(q)
            out_a = fast.scored(q, a, None).outcome
            out_b = fast.scored(q, b, None).outcome
            same += int((out_a == out_b).sum())
            total += len(q)
            for i in np.flatnonzero((out_a == out_b) & ~a.start_collision):
                pa, pb = a.points[a.row == i], b.points[b.row == i]
                keys_a = list(zip(a.finger[a.row == i], a.link[a.row == i], strict=True))
                keys_b = list(zip(b.finger[b.row == i], b.link[b.row == i], strict=True))
                if keys_a == keys_b:
                    offsets.extend(np.linalg.norm(pa - pb, axis=1))
        fast.close()
    assert same >= 0.98 * total, f"{same} of {total}"
    assert len(offsets) > 1000 and np.median(offsets) < 1e-9


def test_only_capsule_phalanx_fingers_take_the_kernel():
    """The Panda's jaws (prismatic, box and mesh pads) and a three-link finger do not
    qualify for the capsule kernel; the SDH's do, with its finger path's speed bounds (both
    joints turning, the distal one alone), the proximal one at least the phalanx's farthest
    end (0.0865 m) plus its radius (0.011 m)."""
    from kinegrasp_env.closing.capsule_fingers import capsule_finger

    panda = make_engine("fast", "panda", "cube").hand
    assert all(capsule_finger(f, p, panda.geometry) is None for f, p in enumerate(panda.paths))
    sdh = make_engine("fast", "kuka_sdh", "cube").hand
    finger = capsule_finger(0, sdh.paths[0], sdh.geometry)
    (prox_p, _), (dist_p, dist_d) = sdh.paths[0].speeds
    np.testing.assert_array_equal(finger.speeds, [prox_p, dist_p + dist_d, dist_d])
    assert 0.0865 + 0.011 - 1e-9 <= finger.speeds[0] <= 0.0865 + 0.011 + 2e-3
    np.testing.assert_array_equal(finger.sign, [1.0, 1.0])
    three = dataclasses.replace(sdh.paths[0], links=(*sdh.paths[0].links, "f1_distal"))
    assert capsule_finger(0, three, sdh.geometry) is None
