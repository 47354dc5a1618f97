"""Ferrari-Canny Q for 4+ contacts without the whole hull: nearest-facet-first expansion.

Q is the distance from the origin to the nearest facet of conv(W). Instead of every facet
(qhull builds ~1,000 for 32-40 wrenches in R^6), grow a polytope inside conv(W) from the
origin outwards (the expanding-polytope idea of EPA):

1. A simplex of 7 wrenches containing the origin: a basic feasible solution of
   ``W^T lam = 0, sum(lam) = 1, lam >= 0`` (phase-1 simplex: the most negative reduced
   cost enters, ~10 pivots for 5 contacts x 12 edges where Bland's rule took ~49; Bland's
   after a number of pivots, so that it cannot cycle: :mod:`kinegrasp_env.quality.phase_one`).
   No solution: the origin is outside conv(W), Q = 0. A degenerate end (the origin on the hull, an
   equilibrium that is not force closure) is certified Q = 0 when the duals give a
   hyperplane that every wrench lies within FC_TOL / 2 of, on one side (Q is at most that).
2. Repeat: take the nearest facet (unit normal a, offset b); if no wrench lies beyond it,
   stop; else add the wrench furthest beyond it (facets it sees are removed, the horizon
   ridges, between a facet it sees and a neighbour it does not, are coned to it; the facets
   it sees are found from the nearest one across their ridges, :func:`_mark_visible`: on
   facing flat pads' sets this leaves half as many sets uncertified as testing every facet
   did, whose far-off facets seen by round-off broke the coning). Each
   facet knows its neighbour across each ridge, so a new facet's hyperplane is the one
   through the apex in the pencil of its two parents' (:func:`pencil_facet`: ~40
   multiplications where Gram-Schmidt on its vertices takes ~700; accepted where all its
   vertices lie within 1e-13 of the wrench scale of it, else computed afresh), and the
   facets that give Q are recomputed from their vertices at the end
   (:func:`_exact_nearest`): the same Q as Gram-Schmidt on every facet to ~1e-13 relative,
   for less work (timings: ``benchmarks/bench_quality.py``).
3. The answer is *certified* before it is returned: the final facet supports every wrench
   (so Q <= b: it is a facet hyperplane of conv(W)) and the polytope is closed (every ridge
   in exactly two facets) and convex (every facet has every vertex on its inner side,
   checked; a facet a vertex lies beyond is first refit from its own vertices, since a
   pencil hyperplane of a thin facet can miss another wrench on it), so the ball of radius b
   around the origin lies inside it, hence inside conv(W) (Q >= b). Closed by
   construction: the simplex is; each step retires the visible facets, re-pairs each
   horizon ridge (held by a visible facet f and a hidden h) with its new
   facet, checking that h names f as its neighbour there, and pairs the new facets' ridges
   through the apex (a new vertex, so no older facet holds them), checking that each is
   held by exactly two of them (:func:`link_new_facets`); the ridges between visible facets
   go with them. So every step keeps every ridge in exactly two live facets (the tests count
   them independently). Anything that fails a check (a near-degenerate facet, a degenerate
   basis, a broken pairing, a full facet table) returns "not certified" and the caller
   falls back to qhull.

The polytope's tables, its facets' hyperplanes and the pairing of their ridges are
:mod:`kinegrasp_env.quality.facets`; this module grows and certifies it.

The kernels that allocate nothing are compiled without numba's reference counting
(``_nrt=False``): with it, every call passing the polytope and ridge tables (then 14
arrays) paid an atomic increment and decrement per array, a fifth of the expansion's time
(measured with perf). It changes no number (tested: the same Q and certificates as before
on engine and random sets).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.quality.facets import (
    MAX_FACETS,
    MAX_POINTS,
    clear_polytope,
    hyperplane,
    link_new_facets,
    new_polytope,
    new_ridges,
    pencil_facet,
    set_facet,
    start_polytope,
)
from kinegrasp_env.quality.phase_one import initial_simplex, wrench_scale

REL_TOL = 1e-11  # beyond/visible tolerance, relative to the wrench scale
#: Q is taken from the facets within this (relative to the wrench scale) of the nearest,
#: recomputed by Gram-Schmidt (:func:`_exact_nearest`).
NEAREST_BAND = 1e-9


@jit.kernel(_nrt=False, inline="always")
def _nearest_facet(offset: np.ndarray, alive: np.ndarray, count: int) -> int:
    """The live facet of smallest offset among the first ``count``."""
    near = -1
    for f in range(count):
        if alive[f] and (near < 0 or offset[f] < offset[near]):
            near = f
    return near


@jit.kernel(_nrt=False, inline="always")
def _furthest_beyond(w: np.ndarray, a: np.ndarray, limit: float) -> int:
    """The wrench furthest along ``a`` (6,) beyond ``limit``, -1 if none is."""
    far = -1
    far_dist = limit
    for i in range(w.shape[0]):
        d = 0.0
        for c in range(6):
            d += a[c] * w[i, c]
        if d > far_dist:
            far_dist = d
            far = i
    return far


@jit.kernel(_nrt=False, inline="always")
def _mark_visible(w, far, poly, near, step, tol) -> int:
    """Mark the live facets that see wrench ``far`` (more than tol beyond them: poly's
    ``visible``) and how far beyond (``height``), from facet ``near`` (which sees it) across
    the ridges of the facets that see it: the facets a point outside a convex polytope sees
    form one connected patch of its boundary, so only they and the facets around them are
    tested, not every facet. Returns their number, listed in poly's ``found`` in increasing
    order (the order of the facets, as the horizon is coned). Each facet tested is stamped
    with ``step`` (poly's ``checked``). A facet seen only across one that misses by round-off
    is left unmarked (it sees the wrench by a hair, and no facet that sees it is its
    neighbour, so every ridge stays in two facets); the certification's convexity check
    (:func:`_is_convex`) then refits it from its own vertices, and a set it still finds not
    convex goes to the next exact path."""
    normal, offset, visible, height, neighbour = poly[1], poly[2], poly[6], poly[9], poly[8]
    checked, found = poly[11], poly[12]
    checked[near] = step
    d = -offset[near]
    for c in range(6):
        d += normal[near, c] * w[far, c]
    if not d > tol:
        return 0
    visible[near], height[near] = True, d
    found[0] = near
    seen = 1
    head = 0
    while head < seen:
        f = found[head]
        head += 1
        for j in range(6):
            h = neighbour[f, j]
            if checked[h] == step:
                continue
            checked[h] = step
            d = -offset[h]
            for c in range(6):
                d += normal[h, c] * w[far, c]
            if d > tol:
                visible[h], height[h] = True, d
                found[seen] = h
                seen += 1
    for i in range(1, seen):  # insertion sort: a few to a few dozen facets
        f = found[i]
        k = i - 1
        while k >= 0 and found[k] > f:
            found[k + 1] = found[k]
            k -= 1
        found[k + 1] = f
    return seen


@jit.kernel(_nrt=False)
def _cone_horizon(w, far, poly, count, seen, ridges, scale) -> int:
    """Cone the horizon (the ridges between a visible facet and a facet that is not) to
    wrench ``far``, link the new facets to their neighbours and retire the visible ones
    (the ``seen`` facets :func:`_mark_visible` listed); returns the new facet count, -1 on
    a full table, a degenerate facet or broken structure. New facets are made in the order
    of their visible facet, then of its ridges; each starts unmarked and untested."""
    verts, normal, offset, alive = poly[0], poly[1], poly[2], poly[3]
    interior, visible, neighbour, checked, found = poly[4], poly[6], poly[8], poly[11], \
        poly[12]
    first = count
    for i in range(seen):
        f = found[i]
        for j in range(6):
            h = neighbour[f, j]
            if visible[h]:
                continue
            if count >= MAX_FACETS:
                return -1
            g = count
            k = 0
            for v in range(6):
                if v != j:
                    verts[g, k] = verts[f, v]
                    k += 1
            verts[g, 5] = far
            neighbour[g, 5] = h
            slot = -1
            for v in range(6):
                if neighbour[h, v] == f:
                    slot = v
            if slot < 0:
                return -1
            neighbour[h, slot] = g
            if not pencil_facet(w, poly, g, f, h, scale):
                if not set_facet(w, verts, normal, offset, alive, g, interior, scale,
                                  poly[7]):
                    return -1
            visible[g], checked[g] = False, -1
            count += 1
    if not link_new_facets(poly, first, count, ridges):
        return -1
    for i in range(seen):
        alive[found[i]] = False
    return count


@jit.kernel(_nrt=False)
def _is_convex(w, poly, count, tol, scale) -> bool:
    """Every vertex lies on the inner side (to tol) of every live facet. The live facets'
    normals and offsets are first copied column by column into poly's ``planes`` (7, F), so
    that the inner loop, over the live facets only, reads contiguous rows. A facet that a
    vertex lies beyond has its hyperplane computed afresh from its own vertices
    (:func:`_refit`, Gram-Schmidt) before the polytope is called not convex: a pencil
    hyperplane passes within PENCIL_TOL of its six vertices, yet where they span a thin
    simplex it can miss another vertex on the same hyperplane (a flat pad puts all its
    corners' cone wrenches on one) by one to hundreds of times tol. Gram-Schmidt is
    itself only as accurate as such a thin simplex allows (a few times tol off the exact
    hyperplane): the check is then made, at tol, against the hyperplane it gives, as for
    any facet it computes."""
    normal, offset, alive, used, planes = poly[1], poly[2], poly[3], poly[5], poly[10]
    n_live = 0
    for f in range(count):
        if alive[f]:
            for c in range(6):
                planes[c, n_live] = normal[f, c]
            planes[6, n_live] = offset[f]
            n_live += 1
    for i in range(w.shape[0]):
        if used[i]:
            w0, w1, w2, w3, w4, w5 = w[i, 0], w[i, 1], w[i, 2], w[i, 3], w[i, 4], w[i, 5]
            beyond = 0
            for t in range(n_live):
                d = (planes[0, t] * w0 + planes[1, t] * w1 + planes[2, t] * w2
                     + planes[3, t] * w3 + planes[4, t] * w4 + planes[5, t] * w5
                     - planes[6, t])
                beyond += d > tol
            if beyond and not _refit_beyond(w, poly, count, tol, scale, i):
                return False
    return True


@jit.kernel(_nrt=False)
def _refit_beyond(w, poly, count, tol, scale, i) -> bool:
    """Refit (:func:`_refit`) each live facet that used wrench ``i`` lies beyond, copying its
    new hyperplane into ``planes``; False where a refit facet still has a vertex beyond it
    (or is degenerate)."""
    normal, offset, alive, planes = poly[1], poly[2], poly[3], poly[10]
    t = 0
    for f in range(count):
        if not alive[f]:
            continue
        d = -offset[f]
        for c in range(6):
            d += normal[f, c] * w[i, c]
        if d > tol:
            if not _refit(w, poly, f, tol, scale):
                return False
            for c in range(6):
                planes[c, t] = normal[f, c]
            planes[6, t] = offset[f]
        t += 1
    return True


@jit.kernel(_nrt=False)
def _refit(w, poly, f, tol, scale) -> bool:
    """Facet f's hyperplane by Gram-Schmidt on its vertices (:func:`hyperplane`); True where
    every used wrench then lies on its inner side (to tol)."""
    verts, normal, offset, interior, used = poly[0], poly[1], poly[2], poly[4], poly[5]
    b = hyperplane(w, verts[f], interior, normal[f], scale, poly[7])
    if np.isnan(b):
        return False
    offset[f] = b
    for j in range(w.shape[0]):
        if used[j]:
            d = -b
            for c in range(6):
                d += normal[f, c] * w[j, c]
            if d > tol:
                return False
    return True


@jit.kernel(_nrt=False)
def _expand(w, poly, count, tol, scale, ridges) -> int:
    """Grow the polytope (``count`` facets) nearest facet first until no wrench lies beyond
    the nearest facet; returns the facet count, -1 if not certified (a wrench found beyond
    twice, a failed step, or more steps than wrenches). ridges: :func:`new_ridges`."""
    n = w.shape[0]
    normal, offset, alive, used = poly[1], poly[2], poly[3], poly[5]
    for step in range(n + 1):
        near = _nearest_facet(offset, alive, count)
        if near < 0:  # no live facet (impossible for consistent planes): not certified
            return -1
        far = _furthest_beyond(w, normal[near], offset[near] + tol)
        if far < 0:
            return count
        if used[far]:
            return -1
        seen = _mark_visible(w, far, poly, near, step, tol)
        if seen == 0:
            return -1
        count = _cone_horizon(w, far, poly, count, seen, ridges, scale)
        if count < 0:
            return -1
        used[far] = True
    return -1


@jit.kernel
def epsilon_epa(w: np.ndarray) -> tuple[float, bool]:
    """(Q, certified) for wrenches w (N, 6); Q = 0 if the origin is outside. More than
    :data:`MAX_POINTS` wrenches: not certified (the caller uses qhull)."""
    start, q, certified = screen(w)
    if start[0] < 0:
        return q, certified
    return expand_from(w, start, new_polytope(), new_ridges())


@jit.kernel
def screen(w: np.ndarray):
    """Phase 1 of :func:`epsilon_epa`: (start (7,), the initial simplex, or [code] (see
    :func:`initial_simplex`; [-2] past :data:`MAX_POINTS` wrenches), and where it is a code,
    the answer (Q, certified): Q = 0, certified unless undecided)."""
    if w.shape[0] > MAX_POINTS:
        return np.array([-2]), 0.0, False
    start = initial_simplex(w, 1e-12)
    return start, 0.0, start[0] == -1 or start[0] == -3


@jit.kernel(_nrt=False)
def expand_from(w: np.ndarray, start: np.ndarray, poly, ridges) -> tuple[float, bool]:
    """:func:`epsilon_epa` from the initial simplex ``start`` (:func:`screen`), in the
    polytope and ridge tables given (:func:`new_polytope`, :func:`new_ridges`: ~2 MB, so a
    batch allocates them once, and a set that phase 1 settles needs none)."""
    scale = wrench_scale(w)
    tol = REL_TOL * scale
    clear_polytope(poly)
    interior, used = poly[4], poly[5]
    for i in range(7):
        for c in range(6):
            interior[c] += w[start[i], c] / 7.0
    if not start_polytope(w, start, poly, scale):
        return 0.0, False
    for i in range(7):
        used[start[i]] = True
    count = _expand(w, poly, 7, tol, scale, ridges)
    # certify: closed (by construction, see the module docstring) and convex
    if count < 0:
        return 0.0, False
    if not _is_convex(w, poly, count, tol, scale):
        return 0.0, False
    return _exact_nearest(w, poly, count, tol, scale)


@jit.kernel(_nrt=False)
def _exact_nearest(w, poly, count, tol, scale) -> tuple[float, bool]:
    """(Q, certified) of a closed, convex polytope of ``count`` facets: the smallest offset
    of its facets within :data:`NEAREST_BAND` x the wrench scale of the nearest, their
    hyperplanes computed afresh from their vertices (:func:`hyperplane`: the numbers the
    facets of :func:`pencil_facet` approximate), certified where that nearest facet
    supports every wrench (to tol) and its recomputed offset stays within the band (else a
    facet outside the band, not recomputed, could be nearer: pencil offsets of thin facets
    far from the origin's projection can be off by ~1e-8 of the scale)."""
    verts, normal, offset, alive, interior = poly[0], poly[1], poly[2], poly[3], poly[4]
    first = _nearest_facet(offset, alive, count)
    if first < 0:
        return 0.0, False
    limit = offset[first] + NEAREST_BAND * scale
    near = -1
    for f in range(count):
        if alive[f] and offset[f] <= limit:
            b = hyperplane(w, verts[f], interior, normal[f], scale, poly[7])
            if np.isnan(b):
                return 0.0, False
            offset[f] = b
            if near < 0 or b < offset[near]:
                near = f
    if near < 0 or offset[near] > limit:
        # recomputed above the band: a facet outside it, not recomputed, could be nearer
        return 0.0, False
    if _furthest_beyond(w, normal[near], offset[near] + tol) >= 0:
        return 0.0, False
    return max(offset[near], 0.0), True


@jit.kernel
def outside_batch(w: np.ndarray) -> np.ndarray:
    """(B,) bool: True where phase 1 of :func:`epsilon_epa` certifies that the origin is
    outside conv(W) of the wrench set w[b] (w: (B, N, 6)) by a separating hyperplane: Q = 0
    on every exact path. Cheap (phase 1 only): a screen before a costlier path."""
    out = np.zeros(w.shape[0], np.bool_)
    for b in range(w.shape[0]):
        out[b] = initial_simplex(w[b], 1e-12)[0] == -1
    return out


@jit.kernel
def epsilon_epa_batch(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Q (B,), certified (B,)) for wrench sets w (B, N, 6)."""
    q = np.zeros(w.shape[0])
    ok = np.zeros(w.shape[0], np.bool_)
    poly, ridges = new_polytope(), new_ridges()
    for b in range(w.shape[0]):
        start, q[b], ok[b] = screen(w[b])
        if start[0] >= 0:
            q[b], ok[b] = expand_from(w[b], start, poly, ridges)
    return q, ok
