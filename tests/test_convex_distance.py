"""The certified distance bound between convex polytopes (GJK): against the exact distance of
two boxes (a formula), against the fast engine's exact closest pair (vertices against the
object's parts, the object's edges against the link's hulls: a different algorithm) on the
Panda's links and the catalog objects, started cold and where the last bound ended, and
against the same kernel interpreted; the support walked along a hull's edges against
NumPy's furthest vertex."""

from __future__ import annotations

import itertools
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinegrasp_env.closing.convex_distance import (
    WALK_MIN,
    hull_distance_bounds,
    new_hints,
    new_simplex,
    stacked_points,
    stacked_vertices,
)
from kinegrasp_env.world.polytope import ConvexPart, face_planes

#: The bound lies below the exact distance: measured at most 1.7e-16 m above the exact pair
#: (which has rounding of its own); 1e-14 m allowed.
ABOVE_TOL = 1e-14
#: ... and within 1.9e-12 m of it (measured, separated pairs); 1e-10 m allowed.
BELOW_TOL = 1e-10


def _bounds(a_vertices, rot, trans, b_vertices, a_starts=None, b_starts=None, motion=None,
            travel=False, short=0.0, enough=np.inf):
    n = rot.shape[0]
    a_starts = [0, len(a_vertices)] if a_starts is None else a_starts
    b_starts = [0, len(b_vertices)] if b_starts is None else b_starts
    a = stacked_points([a_vertices[s:e] for s, e in itertools.pairwise(a_starts)])
    b = stacked_points([b_vertices[s:e] for s, e in itertools.pairwise(b_starts)])
    out, far = np.empty(n), np.empty(n)
    motion = np.zeros((n, 3)) if motion is None else motion
    hull_distance_bounds(*a, np.ascontiguousarray(rot), np.ascontiguousarray(trans), *b,
                         np.ascontiguousarray(motion), short, new_hints(n, a, b),
                         new_simplex(), out, far, enough)
    return (out, far) if travel else out


def _box(lo, hi):
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])])


def test_boxes_against_the_exact_formula():
    # two boxes aligned with each other, both turned by one random rotation: their distance
    # is |max(0, lo_b - hi_a, lo_a - hi_b)| per axis, overlapping boxes give -inf
    rng = np.random.default_rng(3)
    n = 3000
    a_half, b_half = rng.uniform(0.005, 0.05, (n, 3)), rng.uniform(0.005, 0.05, (n, 3))
    offset = rng.uniform(-0.12, 0.12, (n, 3))
    turn = Rotation.random(n, random_state=4).as_matrix()
    exact = np.linalg.norm(np.maximum(0.0, np.abs(offset) - a_half - b_half), axis=1)
    got = np.empty(n)
    for i in range(n):
        a = _box(-a_half[i], a_half[i])
        b = _box(offset[i] - b_half[i], offset[i] + b_half[i]) @ turn[i].T
        got[i] = _bounds(a, turn[i][None], np.zeros((1, 3)), b)[0]
    apart = exact > 0
    assert apart.sum() > 1000 and (~apart).sum() > 100
    assert np.all(np.isneginf(got[~apart]))
    assert np.all(got[apart] <= exact[apart] + ABOVE_TOL)
    assert np.all(got[apart] >= exact[apart] - BELOW_TOL)


@pytest.fixture(scope="module")
def panda_hands():
    from kinegrasp_env.montecarlo.evaluate import make_engine

    return {name: make_engine("fast", "panda", name).hand for name in ("cube", "drill")}


@pytest.mark.parametrize("object_name", ["cube", "drill"])
@pytest.mark.parametrize("link", ["panda_leftfinger", "panda_hand"])
def test_panda_links_against_the_exact_pair(panda_hands, object_name, link):
    # random poses around the object: the bound never above the exact closest pair's
    # distance, within BELOW_TOL of it where they are apart, -inf only where they touch
    hand = panda_hands[object_name]
    n = 1500
    rot = Rotation.random(n, random_state=5).as_matrix()
    trans = hand.obj.center_of_mass + np.random.default_rng(6).normal(size=(n, 3)) * 0.06
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3], poses[:, :3, 3] = rot, trans
    exact = hand.exact(poses, link)[0]
    apart = exact > 1e-9
    assert apart.sum() > 300 and (exact < 0).sum() > 100
    # cold, then started where the last bounds ended at poses moved a little (as a closing's
    # next step), then at the same poses again
    hints = hand.distances.new_hints(link, n)
    moved = poses.copy()
    moved[:, :3, 3] += np.random.default_rng(11).normal(size=(n, 3)) * 1e-3
    hand.distance_bound(moved, link, hints=hints)
    for start in (None, hints, hints):
        bound = hand.distance_bound(poses, link, hints=start)[0]
        assert np.all(np.isneginf(bound[exact < 0]))
        assert np.all(np.isfinite(bound[apart]))
        assert np.all(bound[apart] <= exact[apart] + ABOVE_TOL)
        assert np.all(bound[apart] >= exact[apart] - BELOW_TOL)


INTERPRETED = """
import os, sys
os.environ["NUMBA_DISABLE_JIT"] = "1"
import numpy as np
from kinegrasp_env.closing.convex_distance import hull_distance_bounds, new_hints, new_simplex
d = np.load(sys.argv[1])
a = [d[f"a{k}"] for k in range(5)]
b = [d[f"b{k}"] for k in range(5)]
out, far = np.empty(len(d["rot"])), np.empty(len(d["rot"]))
hull_distance_bounds(*a, d["rot"], d["trans"], *b, np.zeros((len(out), 3)), 0.0,
                     new_hints(len(out), a, b), new_simplex(), out, far, np.inf)
np.save(sys.argv[2], out)
"""


def test_the_kernel_interpreted_gives_the_same_bounds(panda_hands, tmp_path):
    # the compiled kernel against its own source run by Python: equal to a few ulps
    hand = panda_hands["drill"]
    a = stacked_vertices(hand.geometry["panda_rightfinger"].parts)
    b = stacked_vertices(hand.obj.convex_parts)
    n = 150
    rot = Rotation.random(n, random_state=7).as_matrix()
    trans = hand.obj.center_of_mass + np.random.default_rng(8).normal(size=(n, 3)) * 0.06
    np.savez(tmp_path / "in.npz", rot=rot, trans=trans, **{f"a{k}": x for k, x in enumerate(a)},
             **{f"b{k}": x for k, x in enumerate(b)})
    subprocess.run([sys.executable, "-c", INTERPRETED, str(tmp_path / "in.npz"),
                    str(tmp_path / "out.npy")], check=True, timeout=600)
    plain = np.load(tmp_path / "out.npy")
    compiled = np.empty(n)
    hull_distance_bounds(*a, rot, trans, *b, np.zeros((n, 3)), 0.0, new_hints(n, a, b),
                         new_simplex(), compiled, np.empty(n), np.inf)
    assert np.isfinite(compiled).sum() > 30 and np.isneginf(compiled).sum() > 10
    np.testing.assert_array_equal(np.isneginf(compiled), np.isneginf(plain))
    finite = np.isfinite(compiled)
    np.testing.assert_allclose(compiled[finite], plain[finite], rtol=0, atol=1e-15)


def test_a_bound_sought_no_higher_than_enough_answers_the_same_question():
    # two random hulls of 30 points at random poses, near and far: a bound stopped once it
    # passes ``enough`` is still a lower bound of the full one (the iteration's bound only
    # grows), and it says "above enough" exactly where the full one does, so a caller that
    # asks only that (the start check: overlap or not, enough 0; the table check: within a
    # core's radius) gets the same answer; the early stop is taken (some bounds are lower)
    rng = np.random.default_rng(11)
    a, b = rng.normal(size=(30, 3)) * 0.02, rng.normal(size=(30, 3)) * 0.03
    n = 2000
    rot = Rotation.random(n, random_state=12).as_matrix()
    trans = rng.normal(size=(n, 3)) * 0.05
    full = _bounds(a, rot, trans, b)
    assert np.isneginf(full).sum() > 100 and (full > 0.01).sum() > 100
    for enough in (0.0, 0.002, 0.01):
        early = _bounds(a, rot, trans, b, enough=enough)
        assert np.all(early <= full)
        np.testing.assert_array_equal(early > enough, full > enough)
        assert (early < full).sum() > 100


def test_travel_of_boxes_moving_along_an_axis():
    # a box moving straight at another along x (faces parallel): its separating plane is
    # that face's, so the travel is the gap over the speed exactly; moving away (or across,
    # past it) no plane stands in the way: inf; touching: 0
    a = _box(np.full(3, -0.01), np.full(3, 0.01))
    b = _box([0.03, -0.02, -0.02], [0.05, 0.02, 0.02])  # gap 0.02 along x
    rot = np.tile(np.eye(3), (4, 1, 1))
    trans = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.05, 0.0],
                      [0.01, 0.0, 0.0]])
    motion = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0], [0.0, 0.0, 0.3],
                       [0.5, 0.0, 0.0]])
    bound, far = _bounds(a, rot, trans, b, motion=motion, travel=True)
    np.testing.assert_allclose(bound[:2], 0.02, rtol=1e-12)
    assert far[0] == pytest.approx(0.02 / 0.5, rel=1e-12)
    _, short = _bounds(a, rot, trans, b, motion=motion, travel=True, short=0.005)
    assert short[0] == pytest.approx(0.015 / 0.5, rel=1e-12)  # stops 5 mm short
    assert np.isinf(far[1]) and np.isinf(far[2])
    trans[3, 0] = 0.02  # touching
    bound, far = _bounds(a, rot, trans, b, motion=motion, travel=True)
    assert np.isneginf(bound[3]) and far[3] == 0.0


@pytest.mark.parametrize("link", ["panda_leftfinger", "panda_hand"])
def test_travel_never_lets_a_link_through_the_object(panda_hands, link):
    # the certificate: translated by 0.999 of its travel along the motion, the link is still
    # apart from the object (exact pair); the travel is not vacuous (often finite and at
    # least the plain bound over the speed)
    hand = panda_hands["drill"]
    n = 1200
    rng = np.random.default_rng(9)
    rot = Rotation.random(n, random_state=10).as_matrix()
    trans = hand.obj.center_of_mass + rng.normal(size=(n, 3)) * 0.08
    motion = rng.normal(size=(n, 3)) * 0.3
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3], poses[:, :3, 3] = rot, trans
    bound, far = hand.distance_bound(poses, link, motion)
    apart = np.isfinite(bound)
    finite = apart & np.isfinite(far)
    assert finite.sum() > 200
    assert np.all(far[apart] >= bound[apart] / np.linalg.norm(motion[apart], axis=1)
                  * (1 - 1e-12))
    moved = poses[finite].copy()
    moved[:, :3, 3] += 0.999 * far[finite, None] * motion[finite]
    exact = hand.exact(moved, link)[0]
    assert np.all(exact > 0), exact.min()




def test_bounds_walked_from_any_start_stay_below_the_exact_distance():
    # random hulls of more than WALK_MIN points (some inside: dropped from the walk) against
    # points around them, each bound's supports walked from a random vertex: a walk that
    # stopped short of the furthest vertex would give a plane beyond the hull, a bound above
    # the exact point-to-hull distance (ConvexPart.closest: face planes and edges, no GJK)
    rng = np.random.default_rng(12)
    n = 300
    for _ in range(15):
        count = int(rng.integers(WALK_MIN + 1, 400))
        points = rng.normal(size=(count, 3)) * rng.uniform(0.01, 0.05, 3)
        hull = stacked_points([points])
        assert 0 < len(hull[0]) < count and len(hull[4]) > 0  # walked, interior dropped
        part = ConvexPart(hull[0], face_planes(hull[0]))
        target = rng.normal(size=(n, 3)) * 0.06
        exact = part.closest(target)[1]
        single = stacked_points([np.zeros((1, 3))])
        hints = new_hints(n, hull, single)
        hints[:, 0, 0] = rng.integers(0, len(hull[0]), n)
        out = np.empty(n)
        hull_distance_bounds(*hull, np.tile(np.eye(3), (n, 1, 1)), -target, *single,
                             np.zeros((n, 3)), 0.0, hints, new_simplex(), out, np.empty(n), np.inf)
        apart = exact > 1e-9
        assert apart.sum() > 100
        assert np.all(np.isneginf(out[exact < 0]))
        assert np.all(out[apart] <= exact[apart] + ABOVE_TOL)
        assert np.all(out[apart] >= exact[apart] - BELOW_TOL)


@pytest.mark.parametrize("seed", [91, 97, 109, 146, 186])
def test_bounds_walked_on_a_hull_of_merged_faces(seed):
    # a cube [-1, 1]^3 given by a 7 x 7 grid of points on each face, each moved by 1e-14:
    # qhull merges each face's nearly coplanar facets and splits it into triangles that may
    # overlap, so a walk along the triangles' edges alone can stop inside a face (these seeds
    # did: bounds up to 1.5 m above the distance). Against the distance to the cube (a
    # formula), from cold and from random starts
    grid = np.linspace(-1.0, 1.0, 7)
    cube = np.array(np.meshgrid(grid, grid, grid)).reshape(3, -1).T
    points = cube[(np.abs(cube) == 1.0).any(axis=1)]
    points = points + 1e-14 * np.random.default_rng(seed).normal(size=points.shape)
    hull = stacked_points([points])
    assert len(hull[4]) > 0  # walked
    n = 4000
    rng = np.random.default_rng(0)
    target = rng.normal(size=(n, 3)) * 2.0
    exact = np.linalg.norm(np.maximum(np.abs(target) - 1.0, 0.0), axis=1)
    single = stacked_points([np.zeros((1, 3))])
    for random_start in (False, True):
        hints = new_hints(n, hull, single)
        if random_start:
            hints[:, 0, 0] = rng.integers(0, len(hull[0]), n)
        out = np.empty(n)
        hull_distance_bounds(*hull, np.tile(np.eye(3), (n, 1, 1)), -target, *single,
                             np.zeros((n, 3)), 0.0, hints, new_simplex(), out, np.empty(n), np.inf)
        apart = exact > 1e-9
        # the points lie off the cube by 1e-14 noise: measured at most 2.0e-14 above the
        # cube's distance and 1.4e-13 below it; 1e-13 and 1e-12 allowed
        assert np.all(out[apart] <= exact[apart] + 1e-13)
        assert np.all(out[apart] >= exact[apart] - 1e-12)


def test_hints_of_another_shape_are_refused(panda_hands):
    # hints made for another link or draw count would send the compiled kernel outside its
    # arrays: one ValueError naming the link and both shapes
    hand = panda_hands["cube"]
    poses = np.tile(np.eye(4), (5, 1, 1))
    poses[:, :3, 3] = hand.obj.center_of_mass + np.array([0.0, 0.0, 0.2])
    good = hand.distances.new_hints("panda_leftfinger", 5)
    hand.distance_bound(poses, "panda_leftfinger", hints=good)
    with pytest.raises(ValueError, match=r"panda_leftfinger.*expected"):
        hand.distance_bound(poses, "panda_leftfinger", hints=good[:4])
