"""The patch contact model against independent references.

* **pybullet's contact point**: at a closed Panda grasp, the point pybullet's collision
  detection reports for a pad on the object is a corner of the patch computed here (the pad's
  hull clipped to the face), and lies in the thinned patch the model scores.
* **an LP of the patch's wrench set**: force closure of the corners' friction cones (the
  quality code's Q > 0) against HiGHS: the origin is strictly inside the convex hull of the
  wrenches W (6, m) iff max s s.t. W lam = 0, sum lam = 1, lam >= s has s > 0 and W has
  rank 6. On random opposed pads on a thin wall, and on the engine's own draws.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import linprog

from kinegrasp_env.closing.close_batch import RobotCloseBatch
from kinegrasp_env.closing.contact_patch import PATCH_CORNERS
from kinegrasp_env.montecarlo.description_engine import score_batch
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine, make_engine
from kinegrasp_env.montecarlo.patch_contacts import PatchContacts
from kinegrasp_env.quality.soft_contacts import contact_quality_batch, contact_wrenches
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.world.grasps import shipped_grasps

MU, EDGES = 0.5, 8


def lp_force_closure(points: np.ndarray, normals: np.ndarray, scale: float,
                     center: np.ndarray, torsion: np.ndarray | None = None) -> bool:
    """Force closure of point contacts (m, 3) by the LP of the module docstring; ``torsion``
    (m,) metres: each contact's torsion, its two torsional wrenches built here by hand,
    (n, s (p - c) x n +- s gamma n)."""
    w = contact_wrenches(points[None], normals[None], contact_model="point", friction=MU,
                         num_edges=EDGES, torque_scale=scale, center=tuple(center))[0].T
    if torsion is not None:
        unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        moment = scale * np.cross(points - center, unit)
        extra = [np.concatenate([n, m + sign * scale * g * n])
                 for n, m, g in zip(unit, moment, torsion, strict=True) if g > 0
                 for sign in (1.0, -1.0)]
        if extra:
            w = np.hstack([w, np.array(extra).T])
    if np.linalg.matrix_rank(w, tol=1e-9) < 6:
        return False
    m = w.shape[1]
    c = np.zeros(m + 1)
    c[-1] = -1.0  # maximise s
    a_eq = np.vstack([np.hstack([w, np.zeros((6, 1))]), np.append(np.ones(m), 0.0)])
    b_eq = np.append(np.zeros(6), 1.0)
    a_ub = np.hstack([-np.eye(m), np.ones((m, 1))])  # s - lam_i <= 0
    res = linprog(c, A_ub=a_ub, b_ub=np.zeros(m), A_eq=a_eq, b_eq=b_eq,
                  bounds=[(0, None)] * m + [(None, None)], method="highs")
    return bool(res.status == 0 and -res.fun > 1e-9)


def square(centre: np.ndarray, half: float) -> np.ndarray:
    """(4, 3) corners of a square in a plane x = const."""
    y, z = centre[1], centre[2]
    return np.array([[centre[0], y + sy * half, z + sz * half]
                     for sy, sz in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


PATCHED = dataclasses.replace(load_robot("panda"), contact_model="patch")


def noisy(obj: str, count: int, seed: int, robot: str = "panda") -> np.ndarray:
    """(count, dof): the robot's first shipped grasp of ``obj`` with joint noise of 0.0133 rad
    on its seven arm joints (seed ``seed``)."""
    grasp = shipped_grasps(obj, robot)[0]
    q = np.tile(np.asarray(grasp.q0, dtype=float), (count, 1))
    q[:, :7] += 0.0133 * np.random.default_rng(seed).standard_normal((count, 7))
    return q


def patch_closings(obj: str, q: np.ndarray, **kwargs):
    """The Panda's fast engine with the patch model on q: (draws, the expanded contacts
    (points, normals, finger, link, soft), the object's torque scale and centre of mass)."""
    with make_engine("fast", PATCHED, obj, **kwargs) as engine:
        batch = engine.close_batch(engine.check(q))
        draws = engine.scored(q, batch)
        expanded = engine.patches.expand(q, batch.joints, draws.points, draws.normals,
                                         draws.finger, draws.link)
        return draws, expanded, engine.obj.torque_scale, engine.obj.center_of_mass


def test_thin_wall_pinch_is_force_closure_only_as_patches():
    """Two 10 mm pads on an 8 mm wall, their centres 12 mm apart in height: the centres as
    points are not in force closure (the line between them leaves both cones), the patches
    overlap across the wall and are; the LP says the same of both."""
    left, right = np.array([-0.004, 0.0, 0.0]), np.array([0.004, 0.0, 0.012])
    centres = np.stack([left, right])
    normals = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    corners = np.vstack([square(left, 0.01), square(right, 0.01)])
    corner_normals = np.repeat(normals, 4, axis=0)
    scale, centre = 10.0, np.zeros(3)
    q_point = contact_quality_batch(centres[None], normals[None], torque_scale=scale)[0]
    q_patch = contact_quality_batch(corners[None], corner_normals[None], torque_scale=scale)[0]
    assert q_point == 0 and not lp_force_closure(centres, normals, scale, centre)
    assert q_patch > 0 and lp_force_closure(corners, corner_normals, scale, centre)


def test_patch_quality_agrees_with_the_lp_on_random_pinches():
    """200 random pairs of opposed square pads: Q > 0 exactly where the LP finds force
    closure (both outcomes occur)."""
    rng = np.random.default_rng(0)
    verdicts = []
    for _ in range(200):
        left = np.array([-0.004, *rng.uniform(-0.02, 0.02, 2)])
        right = np.array([0.004, *rng.uniform(-0.02, 0.02, 2)])
        half = rng.uniform(0.002, 0.012)
        pts = np.vstack([square(left, half), square(right, half)])
        nrm = np.repeat(np.array([[1.0, 0, 0], [-1.0, 0, 0]]), 4, axis=0)
        q = contact_quality_batch(pts[None], nrm[None], torque_scale=10.0)[0]
        lp = lp_force_closure(pts, nrm, 10.0, np.zeros(3))
        assert (q > 0) == lp
        verdicts.append(lp)
    assert 20 < sum(verdicts) < 180


@pytest.fixture(scope="module")
def reference():
    with RobotReferenceEngine("panda", "cube") as engine:
        yield engine


def test_pybullets_contact_point_is_a_patch_corner(reference):
    """Three shipped Panda grasps of the cube, closed by the reference engine: pybullet's
    contact point for each pad (performCollisionDetection, the object side) is within 0.05 mm
    of a corner of the full patch (every corner kept) and within 0.05 mm of the thinned
    patch's plane region (inside its polygon)."""
    engine = reference
    patches = PatchContacts(engine.description, engine.obj)
    world, bullet = engine.world, engine.world.bullet
    checked = 0
    for grasp in shipped_grasps("cube", "panda")[:3]:
        q = np.asarray(grasp.q0, dtype=float)[None]
        batch = RobotCloseBatch.of_results([engine.close_one(grasp.q0)])
        draws = score_batch(batch, engine.max_contacts, None)
        corners, normals, _, _, _ = patches.expand(q, batch.joints, draws.points, draws.normals,
                                                draws.finger, draws.link)
        world.set_configuration(grasp.q0)
        world.set_joint_values({k: float(v[0]) for k, v in batch.joints.items()})
        bullet.performCollisionDetection()
        for j in range(int(draws.n_contacts[0])):
            f, k = int(draws.finger[0, j]), int(draws.link[0, j])
            name = engine.description.fingers[f].links[k]
            found = bullet.getContactPoints(bodyA=world.bodies["robot"],
                                            bodyB=world.bodies["object"],
                                            linkIndexA=world.link_index[name])
            assert found, name
            point = engine.obj.to_object(np.array(found[0][6]))
            full = full_patch(patches, q, batch, draws, j)
            assert np.min(np.linalg.norm(full - point, axis=1)) < 5e-5
            thinned = corners[0, j * PATCH_CORNERS:(j + 1) * PATCH_CORNERS]
            assert inside(thinned, normals[0, j * PATCH_CORNERS], point, 5e-5)
            checked += 1
    assert checked == 6


def full_patch(patches: PatchContacts, q, batch, draws, j) -> np.ndarray:
    """Every corner of contact j's patch (none thinned)."""
    from kinegrasp_env.closing.finger_paths import link_poses
    from kinegrasp_env.closing.generic_reference import EDGE_TOL
    from kinegrasp_env.closing.pad_faces import faces_of

    name, chain = patches.links[(int(draws.finger[0, j]), int(draws.link[0, j]))]
    palm = patches.obj.pose_inverse @ patches.kinematics.pose(q, patches.description.palm_link)
    full = patches.description.model.expand(q)
    full.update({k: np.asarray(v, dtype=float) for k, v in batch.joints.items()})
    pose = link_poses(palm, full, chain)
    part, plane = faces_of(patches.obj, draws.points[0, j][None], EDGE_TOL)
    _, _, corners, counts = patches.patch.patches(patches.geometry[name].vertices, pose, part,
                                                  plane, draws.points[0, j][None], 32)
    return corners[0, :counts[0]]


def inside(polygon: np.ndarray, normal: np.ndarray, point: np.ndarray, tol: float) -> bool:
    """point within tol of the convex polygon (k, 3) (ordered, in a plane of normal n)."""
    centre = polygon.mean(axis=0)
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        out = np.cross(b - a, normal)  # in-plane, perpendicular to the edge
        out /= np.linalg.norm(out)
        if (centre - a) @ out > 0:
            out = -out  # pointing away from the polygon
        if (point - a) @ out > tol:
            return False
    return True


@pytest.mark.parametrize(("obj", "flat_share"), [("cube", (0.9, 1.0)),
                                                 ("spray_flask", (0.8, 0.97))])
def test_engine_scores_the_patch_corners(obj, flat_share):
    """The fast engine with the patch model on 60 noisy Panda draws of each object: force
    closure exactly where the LP finds it for the contacts PatchContacts gives, the corners
    of a pad flat on a face as point contacts, a contact off a face with the soft model's
    torsion (its torsional wrenches built by hand). On the cube nearly every pad lies flat on
    a face; on the spray flask's curved neck (a mesh of narrow facets) some contacts are off
    a face, where a pad crosses the planes of the facets on both sides of the point
    (measured: 5% of them)."""
    from kinegrasp_env.quality.soft_contacts import FINGER_RADIUS, torsion_coefficient

    draws, expanded, scale, centre = patch_closings(obj, noisy(obj, 60, 1))
    corners, normals, finger, _, soft = expanded
    touched = np.flatnonzero(draws.n_contacts == 2)
    assert touched.size > 30
    present = finger[touched] >= 0
    share = 1.0 - soft[touched][present].mean()  # flat on a face
    assert flat_share[0] <= share <= flat_share[1], share
    gamma = torsion_coefficient(MU, FINGER_RADIUS)
    for i in touched:
        here = finger[i] >= 0
        lp = lp_force_closure(corners[i, here], normals[i, here], scale, centre,
                              np.where(soft[i, here], gamma, 0.0))
        assert (draws.outcome[i] == FORCE_CLOSURE) == lp, i


def test_the_patch_model_off_every_face_is_the_soft_model():
    """Panda draws of the spray flask whose contacts all lie off a face (12 of these 800): the
    patch model scores them as the soft model does (the same Q to 1e-9 relative, computed by
    the soft engine's own path, and the same static hold verdicts); with a pad flat on a
    face the two differ somewhere."""
    q = noisy("spray_flask", 800, 2)
    draws, expanded, _, _ = patch_closings("spray_flask", q, static_hold=True)
    soft_slots = expanded[4]
    with make_engine("fast", dataclasses.replace(PATCHED, contact_model="soft"),
                     "spray_flask", static_hold=True) as engine:
        soft = engine.run(q)
    present = np.repeat(draws.finger >= 0, PATCH_CORNERS, axis=1)
    off = (draws.n_contacts > 0) & (soft_slots | ~present).all(axis=1)
    assert off.sum() >= 10
    np.testing.assert_allclose(draws.quality[off], soft.quality[off], rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(draws.outcome[off], soft.outcome[off])
    np.testing.assert_array_equal(draws.held[off], soft.held[off])  # the static hold check
    on = (~soft_slots & present).any(axis=1)
    assert on.sum() >= 10 and not np.allclose(draws.quality[on], soft.quality[on])


def test_rounded_fingertips_stay_point_contacts_under_the_patch_model():
    """kuka_sdh's capsule fingertips under the patch model: every contact stays a point
    contact (no corners, no torsion), so Q and the outcomes are the point model's, draw for
    draw, on 40 noisy draws of a shipped cube grasp (its reference engine)."""
    description = load_robot("kuka_sdh")
    q = noisy("cube", 40, 3, robot="kuka_sdh")
    with make_engine("pybullet", dataclasses.replace(description, contact_model="patch"),
                     "cube") as engine:
        patched = engine.run(q)
    with make_engine("pybullet", description, "cube") as engine:
        point = engine.run(q)
    assert (point.outcome == FORCE_CLOSURE).sum() > 10
    np.testing.assert_array_equal(patched.outcome, point.outcome)
    np.testing.assert_allclose(patched.quality, point.quality, rtol=1e-9, atol=1e-15)


def test_the_distinct_slots_score_as_every_slot():
    """The engine scores a patch draw on its distinct slots (a soft contact once, a patch
    without its padding): every expanded slot scored with the soft model's per-contact
    torsion (corners 0) gives the same Q, to 1e-9 relative, on the touched ones of 200 Panda
    draws of the spray flask (pads flat on faces and off them both occur)."""
    from kinegrasp_env.quality.soft_contacts import FINGER_RADIUS, torsion_coefficient

    draws, expanded, scale, centre = patch_closings("spray_flask", noisy("spray_flask", 200, 5))
    points, normals, finger, _, soft = expanded
    rows = np.flatnonzero(draws.n_contacts == 2)
    assert rows.size >= 20 and soft[rows].any() and (~soft[rows] & (finger[rows] >= 0)).any()
    gamma = np.where(soft[rows], torsion_coefficient(MU, FINGER_RADIUS), 0.0)
    every = contact_quality_batch(points[rows], normals[rows], contact_model="soft",
                                  friction=MU, num_edges=EDGES, torque_scale=scale,
                                  center=centre, torsion=gamma, method="qhull")
    np.testing.assert_allclose(draws.quality[rows], every, rtol=1e-9, atol=1e-15)


def test_the_static_hold_check_takes_the_patch_models_soft_contacts():
    """Mixed Panda draws of the spray flask (a pad flat on a face, the other off one; 16 of
    these 800 draws): the
    engine's static hold verdicts are the check's on the expanded contacts with their soft
    slots, and scoring every slot without torsion (the soft slots dropped) changes some,
    so the engine passes them on."""
    q = noisy("spray_flask", 800, 6)
    with make_engine("fast", PATCHED, "spray_flask", static_hold=True) as engine:
        batch = engine.close_batch(engine.check(q))
        draws = engine.scored(q, batch)
        points, normals, finger, link, soft = engine.patches.expand(
            q, batch.joints, draws.points, draws.normals, draws.finger, draws.link)
        present = finger >= 0
        mixed = np.flatnonzero((soft & present).any(axis=1) & (~soft & present).any(axis=1))
        assert mixed.size >= 10, mixed.size
        values = {name: v[mixed] for name, v in batch.joints.items()}
        args = (q[mixed], values, points[mixed], normals[mixed], finger[mixed], link[mixed])
        with_soft = engine.hold_check.held(*args, soft=soft[mixed])
        without = engine.hold_check.held(*args, soft=np.zeros_like(soft[mixed]))
    np.testing.assert_array_equal(draws.held[mixed], with_soft)
    assert (with_soft != without).any()


def test_the_patch_model_at_each_draws_friction():
    """Per-draw friction (alternating mu 0.3 and 0.5) on 40 Panda draws of the spray flask:
    each draw's Q is the one an engine at that one mu gives (1e-9 relative)."""
    q = noisy("spray_flask", 40, 7)
    mu = np.where(np.arange(40) % 2 == 0, 0.3, 0.5)
    with make_engine("fast", PATCHED, "spray_flask") as engine:
        mixed = engine.run(q, friction=mu)
    expected = np.empty(40)
    for value in (0.3, 0.5):
        with make_engine("fast", PATCHED, "spray_flask", friction=value) as engine:
            rows = mu == value
            expected[rows] = engine.run(q[rows]).quality
    assert (mixed.quality > 0).sum() > 10
    np.testing.assert_allclose(mixed.quality, expected, rtol=1e-9, atol=1e-15)


def test_distinct_slots_keep_each_point_once():
    """By hand, C = 4 slots a contact: a patch of three corners keeps them and its centre
    once (the centre an engine reports may lie outside the corners' polygon), a full patch
    its four corners, a soft contact and a rounded tip's point one slot, an absent contact
    none."""
    from kinegrasp_env.montecarlo.patch_contacts import distinct_slots

    assert PATCH_CORNERS == 4
    centres = np.array([[[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [np.nan] * 3]])
    points = np.repeat(centres, 4, axis=1)
    points[0, 0:3] = [[0, 1, 0], [0, 0, 1], [0, 1, 1]]      # three corners, then the centre
    points[0, 4:8] = [[1, 1, 0], [1, 0, 1], [1, 1, 1], [1, 2, 2]]  # four corners
    soft = np.zeros((1, 20), dtype=bool)
    soft[0, 8:12] = True  # contact 2 off a face; contact 3 a rounded tip's point
    keep = distinct_slots(points, soft, centres)
    assert np.flatnonzero(keep[0]).tolist() == [0, 1, 2, 3, 4, 5, 6, 7, 8, 12]
