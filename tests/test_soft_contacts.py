"""Soft-finger contacts: the primitives against their definition, force closure of pinches
against Nguyen's two-contact condition, random sets' verdicts against an LP (HiGHS), Q against
qhull run on the primitives directly, and a parallel-jaw pinch's Q against a hand derivation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from quality_cases import sphere_contacts
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from kinegrasp_env.quality import (
    contact_force_closure,
    contact_quality,
    contact_quality_batch,
    contact_wrenches,
    ferrari_canny,
    ferrari_canny_batch,
    torsion_coefficient,
    wrench_matrix,
)

#: Box half extents (metres) of the pinch tests, centred at the origin.
HALF = np.array([0.03, 0.02, 0.015])
SCALE = 1.0 / float(np.linalg.norm(HALF))  # 1 / r_max
#: Q of qhull on the primitives vs the project's Q, relative: measured max 6.5e-14 over the
#: 106 force-closure cases of test_q_matches_qhull_on_the_primitives; 1e-12 is a ~15x margin.
QHULL_REL = 1e-12
#: The hand-derived pinch Q vs the project's Q, relative: measured max 1.7e-15 (both methods,
#: every case of test_parallel_jaw_pinch_q_by_hand); 1e-13 is a ~60x margin.
HAND_REL = 1e-13
#: Soft Q at gamma = 0 vs point Q, relative: measured max 1.5e-14 (the sets of
#: test_soft_without_torsion_is_point_quality; the others are 0 on both); ~70x margin.
ZERO_TORSION_REL = 1e-12
#: LP margin t* (the smallest weight of a convex combination of the primitives giving 0)
#: above which the LP calls a full-rank set in force closure. HiGHS's tolerances are ~1e-9 on
#: these O(1) problems; the smallest finite |t*| of the random cases is 1.1e-5, far from both.
LP_TOL = 1e-7


def pinch(offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Two contacts on the box's +-x faces at (+-a, +-offset, 0), inward normals -+x."""
    a = HALF[0]
    return np.array([[a, offset, 0.0], [-a, -offset, 0.0]]), np.array([[-1.0, 0, 0],
                                                                       [1.0, 0, 0]])


def soft(**kwargs) -> dict:
    return {"contact_model": "soft", "torque_scale": SCALE, **kwargs}


# ----------------------------------------------------------------------------- the model
def test_point_model_is_the_point_contact_code_bit_for_bit():
    """contact_model="point" (the default) returns wrench_matrix's and ferrari_canny's
    outputs unchanged, one grasp and batched."""
    rng = np.random.default_rng(11)
    p, n = sphere_contacts(rng, 20, 4, jitter=0.3)
    for kw in ({}, {"friction": 0.3, "num_edges": 6, "torque_scale": 20.0,
                    "center": (0.001, 0.0, -0.002)}):
        assert np.array_equal(contact_wrenches(p, n, **kw), wrench_matrix(p, n, **kw))
        assert np.array_equal(contact_quality_batch(p, n, **kw),
                              ferrari_canny_batch(p, n, **kw))
        for b in range(3):
            assert contact_quality(p[b], n[b], **kw) == ferrari_canny(p[b], n[b], **kw)


def test_soft_primitives_follow_the_stated_model():
    """Per contact: wrench_matrix's m edge rows bit for bit, then (n, s (p - c) x n +- s gamma
    n) with gamma = (2/3) mu r, computed here with numpy from the docstring's formulas."""
    rng = np.random.default_rng(5)
    p, n = sphere_contacts(rng, 1, 3, jitter=0.3)
    p, n = p[0], n[0] * 2.5  # lengths other than 1 are normalized
    mu, m, s, c, r = 0.4, 6, 15.0, np.array([0.002, -0.001, 0.003]), 0.008
    w = contact_wrenches(p, n, contact_model="soft", friction=mu, num_edges=m,
                         torque_scale=s, center=tuple(c), finger_radius=r)
    assert w.shape == (3 * (m + 2), 6)
    edges = wrench_matrix(p, n, friction=mu, num_edges=m, torque_scale=s, center=tuple(c))
    gamma = 2.0 / 3.0 * mu * r
    assert torsion_coefficient(mu, r) == pytest.approx(gamma, rel=1e-15)
    for i in range(3):
        block = w[i * (m + 2):(i + 1) * (m + 2)]
        assert np.array_equal(block[:m], edges[i * m:(i + 1) * m])
        unit = n[i] / np.linalg.norm(n[i])
        moment = s * np.cross(p[i] - c, unit)
        np.testing.assert_allclose(block[m], np.r_[unit, moment + s * gamma * unit],
                                   rtol=0, atol=1e-15)
        np.testing.assert_allclose(block[m + 1], np.r_[unit, moment - s * gamma * unit],
                                   rtol=0, atol=1e-15)
    # torsion= sets gamma directly; batched input gives the same rows
    w2 = contact_wrenches(p[None], n[None], contact_model="soft", friction=mu, num_edges=m,
                          torque_scale=s, center=tuple(c), torsion=gamma)
    np.testing.assert_allclose(w2[0], w, rtol=0, atol=1e-15)


# ----------------------------------------------------------------------------- (1) pinches
@pytest.mark.parametrize("mu", [0.0, 0.05, 0.2, 0.5, 1.0, 2.0])
def test_antipodal_pinch_needs_soft_fingers(mu):
    """Face-centre pinch of a box: the line between the contacts is along both normals, so
    Nguyen's two-contact condition (the line strictly inside both friction cones) holds for
    every mu > 0: soft fingers are in force closure for mu > 0 (threshold 0), and at mu = 0
    (no friction, gamma = 0) they are not. Point contacts never are: no contact force has a
    moment about the line, so the wrenches span 5 dimensions, checked here by their rank."""
    p, n = pinch()
    point_w = contact_wrenches(p, n, friction=mu, torque_scale=SCALE)
    assert np.linalg.matrix_rank(point_w) <= 5
    assert np.all(np.abs(point_w[:, 3]) < 1e-15)  # no torque about x, the pinch axis
    assert contact_quality(p, n, friction=mu, torque_scale=SCALE) == 0.0
    assert contact_quality(p, n, friction=mu, torque_scale=SCALE, method="qhull") == 0.0
    closed = contact_force_closure(p, n, **soft(friction=mu))
    assert closed == (mu > 0)
    # the torsion is what closes it: soft contacts without it are point contacts again
    assert contact_quality(p, n, **soft(friction=mu, torsion=0.0)) == 0.0


@pytest.mark.parametrize("ratio", [0.5, 0.9, 0.99, 1.01, 1.1, 2.0])
def test_offset_pinch_closes_above_nguyen_threshold(ratio):
    """Contacts at (+-a, +-d, 0) on the +-x faces: the line between them leaves each normal
    at tan(alpha) = d / a towards -+y, an edge direction of both 8-edge cones (docs/
    conventions.md: for n = -+x, t2 = -+y), so the linearized cones contain it strictly iff
    mu > d / a: soft fingers are in force closure exactly above mu* = d / a; point contacts
    at no mu."""
    d = 0.012
    p, n = pinch(offset=d)
    mu = ratio * d / HALF[0]
    assert contact_force_closure(p, n, **soft(friction=mu)) == (ratio > 1)
    assert contact_force_closure(p, n, **soft(friction=mu), method="qhull") == (ratio > 1)
    assert not contact_force_closure(p, n, friction=mu, torque_scale=SCALE)


# ----------------------------------------------------------------------------- (2) LP
def lp_margin(w: np.ndarray) -> float:
    """max t s.t. sum_i lambda_i w_i = 0, sum_i lambda_i = 1, lambda_i >= t (HiGHS): > 0 iff
    the origin is a strictly positive combination of every primitive, i.e. in the relative
    interior of their hull; -inf when the origin is outside it (infeasible)."""
    count = len(w)
    cost = np.zeros(count + 1)
    cost[-1] = -1.0
    a_eq = np.zeros((7, count + 1))
    a_eq[:6, :count] = w.T
    a_eq[6, :count] = 1.0
    b_eq = np.zeros(7)
    b_eq[6] = 1.0
    a_ub = np.hstack([-np.eye(count), np.ones((count, 1))])  # t - lambda_i <= 0
    res = linprog(cost, A_ub=a_ub, b_ub=np.zeros(count), A_eq=a_eq, b_eq=b_eq,
                  bounds=[(0, None)] * count + [(None, 1)], method="highs")
    if res.status == 2:
        return -math.inf
    assert res.status == 0, res.message
    return float(-res.fun)


def random_soft_cases(rng: np.random.Generator, count: int, k: int):
    """``count`` random soft-contact sets of k contacts on a 5 cm sphere: (points (k, 3),
    normals (k, 3), keyword arguments); two contacts are roughly opposite, so that about half
    the sets are in force closure."""
    for _ in range(count):
        if k == 2:
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            v = -u + 0.3 * rng.normal(size=3)
            v /= np.linalg.norm(v)
            points = 0.05 * np.stack([u, v])
            normals = -points / 0.05 + 0.25 * rng.normal(size=(2, 3))
        else:
            points, normals = (a[0] for a in sphere_contacts(rng, 1, k, jitter=0.4))
        kwargs = soft(friction=float(rng.uniform(0.1, 1.0)),
                      num_edges=int(rng.choice([4, 6, 8])),
                      finger_radius=float(rng.uniform(0.002, 0.02)))
        kwargs["torque_scale"] = 20.0
        yield points, normals, kwargs


@pytest.fixture(scope="module")
def random_sets():
    """300 random soft sets (100 each of 2, 3 and 4 contacts) with their Q."""
    rng = np.random.default_rng(2026)
    cases = []
    for k in (2, 3, 4):
        for points, normals, kwargs in random_soft_cases(rng, 100, k):
            cases.append((k, contact_wrenches(points, normals, **kwargs),
                          contact_quality(points, normals, **kwargs)))
    return cases


def test_force_closure_agrees_with_an_lp(random_sets):
    """Force closure (Q > 0) of 300 random soft sets against the LP's verdict: the origin
    strictly inside the hull iff t* > 0 and the primitives span 6-D (numpy's rank)."""
    agree, closed, margins = 0, 0, []
    for _, w, q in random_sets:
        t = lp_margin(w)
        lp_closed = t > LP_TOL and np.linalg.matrix_rank(w) == 6
        agree += (q > 0) == lp_closed
        closed += lp_closed
        if math.isfinite(t):
            margins.append(abs(t))
    print(f"LP agreement {agree}/{len(random_sets)}, {closed} in force closure, "
          f"smallest finite |t*| {min(margins):.3g}")
    assert agree == len(random_sets)
    assert 0.2 * len(random_sets) < closed < 0.8 * len(random_sets)  # both verdicts tested


def test_one_compiled_call_gives_the_batch_q(monkeypatch):
    """``contact_quality`` of one soft grasp takes one compiled call (the wrenches, the
    expansion) and gives the batch path's verdict and Q (the same primitives in another
    order: measured at most 4.6e-14 relative; 1e-12 held). Both share the expansion: the
    independent checks of this path are the LP and qhull tests (their Q comes from it)."""
    import kinegrasp_env.quality.single as single

    calls = []
    real = single.single_epsilon

    def counted(*args):
        calls.append(args[9])  # gamma
        return real(*args)

    monkeypatch.setattr(single, "single_epsilon", counted)
    rng = np.random.default_rng(7)
    closed = 0
    for k in (2, 3, 4):
        for points, normals, kwargs in random_soft_cases(rng, 60, k):
            one = contact_quality(points, normals, **kwargs)
            batch = contact_quality_batch(points[None], normals[None], **kwargs)[0]
            assert (one > 0) == (batch > 0)
            assert one == pytest.approx(batch, rel=1e-12, abs=0.0)
            closed += one > 0
    assert len(calls) == 180 and all(g > 0 for g in calls)
    assert 30 < closed < 150  # both verdicts tested


# ----------------------------------------------------------------------------- (3) qhull
def test_q_matches_qhull_on_the_primitives(random_sets):
    """Q against scipy.spatial.ConvexHull run on the primitives directly: the smallest
    distance -offset from the origin to a facet (unit outward normals) when every offset is
    negative, else 0."""
    worst, count = 0.0, 0
    for _, w, q in random_sets:
        offsets = ConvexHull(w).equations[:, -1]
        reference = -offsets.max() if offsets.max() < 0 else 0.0
        if reference == 0.0:
            assert q == 0.0
            continue
        count += 1
        worst = max(worst, abs(q - reference) / reference)
    print(f"Q vs qhull: {count} sets in force closure, max relative difference {worst:.3g}")
    assert count > 50
    assert worst < QHULL_REL


# ----------------------------------------------------------------------------- (4) by hand
def hand_pinch_q(mu: float, gamma: float, a: float, s: float, m: int) -> float:
    """Q of a soft face-centre pinch (contacts at +-a x, normals -+x, m even) by hand.

    Q = 1 / max |d| over the polar polytope {d : d . w <= 1 for every primitive w}. With
    d = (dx, dy, dz, tx, ty, tz), kappa = s a mu and g = s gamma, the constraints are
    A(v1) <= 1 + dx, A(v2) <= 1 - dx, g |tx| <= 1 - |dx|, where v1 = (mu dy + kappa tz,
    mu dz - kappa ty), v2 = (mu dy - kappa tz, mu dz + kappa ty) and A the gauge of the
    m-gon of unit inradius (vertices at R = 1 / cos(pi / m), the same directions for both
    contacts). Inverting, dy^2 + dz^2 + ty^2 + tz^2 = |v1 + v2|^2 / (4 mu^2) +
    |v1 - v2|^2 / (4 kappa^2), convex, so maximal at polygon vertices v1 = (1 + dx) R e,
    v2 = +-(1 - dx) R e: R^2 max(1/mu^2 + dx^2/kappa^2, dx^2/mu^2 + 1/kappa^2). Adding
    dx^2 + (1 - |dx|)^2 / g^2 gives a convex function of |dx| in [0, 1], maximal at an end:
    1 / Q^2 = max(1/g^2 + R^2 max(1/mu^2, 1/kappa^2), 1 + R^2 (1/mu^2 + 1/kappa^2)).
    """
    kappa, g, r2 = s * a * mu, s * gamma, 1.0 / math.cos(math.pi / m) ** 2
    inv2 = max(1 / g**2 + r2 * max(1 / mu**2, 1 / kappa**2),
               1 + r2 * (1 / mu**2 + 1 / kappa**2))
    return 1.0 / math.sqrt(inv2)


@pytest.mark.parametrize("m", [4, 8, 16])
@pytest.mark.parametrize(("mu", "radius"), [(0.5, 0.01), (0.3, 0.005), (1.0, 0.02),
                                            (0.8, 0.2)])
def test_parallel_jaw_pinch_q_by_hand(m, mu, radius):
    """Dex-Net's setting: a parallel-jaw gripper with soft pads of radius r on two opposite
    faces' centres. The last case (r = 0.2 m) has the torsion large enough that the other
    branch of the hand formula is the binding one."""
    p, n = pinch()
    gamma = 2.0 / 3.0 * mu * radius
    expected = hand_pinch_q(mu, gamma, HALF[0], SCALE, m)
    for method in ("auto", "qhull"):
        q = contact_quality(p, n, **soft(friction=mu, num_edges=m, finger_radius=radius),
                            method=method)
        assert q == pytest.approx(expected, rel=HAND_REL)


def test_builtin_cube_pinch():
    """The built-in cube (6 cm, centre of mass at its centre, r_max = its half-diagonal)
    pinched at two opposite faces' centres, mu = 0.5, r = 0.01 m, 8 edges: the hand formula
    gives Q = 0.0623711... (torsion-limited: 1/g^2 dominates)."""
    from kinegrasp_env.world.objects import load_object

    cube = load_object("cube")
    com = np.asarray(cube.center_of_mass, dtype=float)
    a = float(cube.size[0]) / 2
    p = com + np.array([[a, 0, 0], [-a, 0, 0]])
    n = np.array([[-1.0, 0, 0], [1.0, 0, 0]])
    q = contact_quality(p, n, contact_model="soft", friction=0.5, finger_radius=0.01,
                        torque_scale=cube.torque_scale, center=tuple(com))
    expected = hand_pinch_q(0.5, torsion_coefficient(0.5, 0.01), a, cube.torque_scale, 8)
    assert q == pytest.approx(expected, rel=HAND_REL)
    assert expected == pytest.approx(0.0623711, abs=1e-7)
    assert contact_quality(p, n, friction=0.5, torque_scale=cube.torque_scale,
                           center=tuple(com)) == 0.0


# ----------------------------------------------------------------------------- consistency
@pytest.mark.parametrize("offset", [0.0, 0.004])
def test_linf_q_is_qhull_of_the_minkowski_sum(offset):
    """L-infinity Q (each contact's force bounded by 1) of a soft pinch against qhull of the
    Minkowski sum of each contact's {0} U primitives, built here with itertools."""
    from itertools import product

    p, n = pinch(offset=offset)
    kw = soft(friction=0.6, num_edges=4, finger_radius=0.01)
    w = contact_wrenches(p, n, **kw).reshape(2, 6, 6)
    sums = np.array([a + b for a, b in product(np.vstack([np.zeros(6), w[0]]),
                                               np.vstack([np.zeros(6), w[1]]))])
    offsets = ConvexHull(sums).equations[:, -1]
    q = contact_quality(p, n, **kw, norm="linf")
    assert offsets.max() < 0
    assert q == pytest.approx(-offsets.max(), rel=QHULL_REL)


def test_soft_without_torsion_is_point_quality():
    """gamma = 0: the torsional primitives are the normal wrenches, the centroids of each
    contact's edges, inside the point hull: the same Q as point contacts (3-5 contacts)."""
    rng = np.random.default_rng(8)
    closed = 0
    for k in (3, 4, 5):
        p, n = sphere_contacts(rng, 30, k, jitter=0.1)
        point = ferrari_canny_batch(p, n, torque_scale=20.0)
        zero = contact_quality_batch(p, n, contact_model="soft", torsion=0.0,
                                     torque_scale=20.0)
        np.testing.assert_allclose(zero, point, rtol=ZERO_TORSION_REL, atol=0)
        closed += int((point > 0).sum())
    assert closed > 20


def test_per_contact_torsion_matches_qhull_of_hand_built_primitives():
    """Each contact its own gamma (some 0: the patch model's corners), 120 random sets of 2-4
    contacts: Q against scipy's ConvexHull of primitives built here by hand (the point
    model's cone edges, then per contact (n, s (p - c) x n +- s gamma_i n)); the same gammas
    all equal give the scalar path's Q (the compiled kernel), to 1e-12 relative."""
    rng = np.random.default_rng(11)
    worst, closed = 0.0, 0
    for k in (2, 3, 4):
        for points, normals, kwargs in random_soft_cases(rng, 40, k):
            gamma = rng.choice([0.0, 0.004, 0.01], size=k)
            kwargs.pop("finger_radius")
            q = contact_quality_batch(points[None], normals[None], torsion=gamma[None],
                                      **kwargs)[0]
            unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
            s = kwargs["torque_scale"]
            edges = wrench_matrix(points, unit, friction=kwargs["friction"],
                                  num_edges=kwargs["num_edges"], torque_scale=s)
            twists = [np.concatenate([n, s * np.cross(p, n) + sign * s * g * n])
                      for p, n, g in zip(points, unit, gamma, strict=True) for sign in (1, -1)]
            w = np.vstack([edges, twists])
            offsets = ConvexHull(w).equations[:, -1] if np.linalg.matrix_rank(w) == 6 else [0]
            reference = -max(offsets) if max(offsets) < 0 else 0.0
            if reference == 0.0:
                assert q == 0.0
            else:
                closed += 1
                worst = max(worst, abs(q - reference) / reference)
            same = contact_quality_batch(points[None], normals[None],
                                         torsion=np.full((1, k), 0.004), **kwargs)[0]
            scalar = contact_quality_batch(points[None], normals[None], torsion=0.004,
                                           **kwargs)[0]
            assert same == pytest.approx(scalar, rel=1e-12, abs=0.0)
    assert closed > 20 and worst < QHULL_REL, (closed, worst)


@pytest.mark.parametrize(("torsion", "message"), [
    (np.array([0.01, -0.01]), "torsion must be finite and >= 0 .metres. for every contact"),
    (np.array([0.01, np.nan]), "torsion must be finite and >= 0 .metres. for every contact"),
    (np.zeros(3), r"torsion must be one number or one per contact \(1, 2\)"),
])
def test_bad_per_contact_torsion_is_refused(torsion, message):
    p, n = pinch()
    with pytest.raises(ValueError, match=message):
        contact_quality_batch(p[None], n[None], contact_model="soft", torsion=torsion)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"contact_model": "hard"}, "unknown contact_model"),
    ({"contact_model": "soft", "finger_radius": -0.01}, "finger_radius must be finite"),
    ({"contact_model": "soft", "finger_radius": 0.0}, "finger_radius must be finite"),
    ({"contact_model": "soft", "torsion": float("nan")}, "torsion must be finite"),
    ({"contact_model": "soft", "method": "fast"}, "method auto or qhull"),
    ({"contact_model": "soft", "norm": "l2"}, "unknown norm"),
    ({"contact_model": "soft", "friction": [0.5]}, "one friction coefficient"),
])
def test_bad_input_is_refused(kwargs, message):
    p, n = pinch()
    with pytest.raises(ValueError, match=message):
        contact_quality(p, n, **kwargs)
