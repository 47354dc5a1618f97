"""Ferrari-Canny Q for 4+ contacts without the whole hull: nearest-facet-first expansion.

Q is the distance from the origin to the nearest facet of conv(W). Instead of every facet
(qhull builds ~1,000 for 32-40 wrenches in R^6), grow a polytope inside conv(W) from the
origin outwards (the expanding-polytope idea of EPA):

1. A simplex of 7 wrenches containing the origin: a basic feasible solution of
   ``W^T lam = 0, sum(lam) = 1, lam >= 0`` (phase-1 simplex: the most negative reduced
   cost enters, ~10 pivots for 5 contacts x 12 edges where Bland's rule took ~49; Bland's
   after :data:`DANTZIG_PIVOTS`, so that it cannot cycle). No solution:
   the origin is outside conv(W), Q = 0. A degenerate end (the origin on the hull, an
   equilibrium that is not force closure) is certified Q = 0 when the duals give a
   hyperplane that every wrench lies within FC_TOL / 2 of, on one side (Q is at most that).
2. Repeat: take the nearest facet (unit normal a, offset b); if no wrench lies beyond it,
   stop; else add the wrench furthest beyond it (facets it sees are removed, the horizon
   ridges, between a facet it sees and a neighbour it does not, are coned to it). Each
   facet knows its neighbour across each ridge, so a new facet's hyperplane is the one
   through the apex in the pencil of its two parents' (:func:`_pencil_facet`: ~40
   multiplications where Gram-Schmidt on its vertices takes ~700; accepted where all its
   vertices lie within 1e-13 of the wrench scale of it, else computed afresh), and the
   facets that give Q are recomputed from their vertices at the end
   (:func:`_exact_nearest`): the same Q as Gram-Schmidt on every facet to ~1e-13 relative,
   in ~35% less time for 4-5 contacts.
3. The answer is *certified* before it is returned: the final facet supports every wrench
   (so Q <= b: it is a facet hyperplane of conv(W)) and the polytope is closed (every ridge
   in exactly two facets) and convex (every facet has every vertex on its inner side,
   checked), so the ball of radius b around the origin lies inside it, hence inside conv(W)
   (Q >= b). Closed by construction: the simplex is; each step retires the visible facets,
   re-pairs each horizon ridge (held by a visible facet f and a hidden h) with its new
   facet, checking that h names f as its neighbour there, and pairs the new facets' ridges
   through the apex (a new vertex, so no older facet holds them), checking that each is
   held by exactly two of them (:func:`_link_new_facets`); the ridges between visible facets
   go with them. So every step keeps every ridge in exactly two live facets (the tests count
   them independently). Anything that fails a check (a near-degenerate facet, a degenerate
   basis, a broken pairing, a full facet table) returns "not certified" and the caller
   falls back to qhull.

The kernels that allocate nothing are compiled without numba's reference counting
(``_nrt=False``): with it, every call passing the polytope and ridge tables (then 14
arrays) paid an atomic increment and decrement per array, a fifth of the expansion's time
(measured with perf). It changes no number (tested: the same Q and certificates as before
on engine and random sets).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.quality.wrenches import FC_TOL

MAX_FACETS = 4096
#: Phase-1 pivots by Dantzig's rule before Bland's takes over (measured: 5 contacts x 12
#: edges need ~49 pivots by Bland's rule alone).
DANTZIG_PIVOTS = 50
MAX_POINTS = 64  # ridge keys are sets of vertex ids, the bits of an int64
REL_TOL = 1e-11  # beyond/visible tolerance, relative to the wrench scale
#: A facet hyperplane from its neighbours' (:func:`_pencil_facet`) must pass within this
#: (relative to the wrench scale) of each of its vertices, else it is computed afresh.
PENCIL_TOL = 1e-13
#: ... and its unnormalized normal must not be shorter than this relative to its weights
#: (two nearly opposite neighbour normals: cancellation).
PENCIL_MIN = 1e-3
#: Q is taken from the facets within this (relative to the wrench scale) of the nearest,
#: recomputed by Gram-Schmidt (:func:`_exact_nearest`).
NEAREST_BAND = 1e-9


@jit.kernel
def _phase_one_tableau(w: np.ndarray) -> np.ndarray:
    """Phase-1 tableau (8, N + 8) of ``W^T lam = 0, sum(lam) = 1, lam >= 0`` for w (N, 6):
    rows 0-6 the constraints with one artificial column each (N..N+6), the last column the
    right-hand side, the last row the reduced costs of minimizing the sum of artificials."""
    n = w.shape[0]
    rows, cols = 7, n + 7
    tab = np.zeros((rows + 1, cols + 1))
    for i in range(6):
        for j in range(n):
            tab[i, j] = w[j, i]
    for j in range(n):
        tab[6, j] = 1.0
    tab[6, cols] = 1.0
    for i in range(rows):
        tab[i, n + i] = 1.0
    # objective row: minimize the sum of artificials -> reduced costs
    for j in range(cols + 1):
        s = 0.0
        for i in range(rows):
            s += tab[i, j]
        tab[rows, j] = -s
    for i in range(rows):
        tab[rows, n + i] = 0.0
    return tab


@jit.kernel(_nrt=False)
def _leaving_row(tab: np.ndarray, basis: np.ndarray, enter: int, tol: float) -> int:
    """Ratio test for entering column ``enter``, ties to the smallest basic index (Bland);
    -1 if no row qualifies."""
    rows, cols = basis.shape[0], tab.shape[1] - 1
    leave = -1
    best = np.inf
    for i in range(rows):
        if tab[i, enter] > tol:
            ratio = tab[i, cols] / tab[i, enter]
            if ratio < best - 1e-15 or (abs(ratio - best) <= 1e-15 and leave >= 0
                                        and basis[i] < basis[leave]):
                best = ratio
                leave = i
    return leave


@jit.kernel(_nrt=False)
def _pivot(tab: np.ndarray, leave: int, enter: int) -> None:
    """Gauss-Jordan pivot of the tableau on (leave, enter)."""
    piv = tab[leave, enter]
    for j in range(tab.shape[1]):
        tab[leave, j] /= piv
    for i in range(tab.shape[0]):
        if i != leave:
            f = tab[i, enter]
            if f != 0.0:
                for j in range(tab.shape[1]):
                    tab[i, j] -= f * tab[leave, j]


@jit.kernel
def _separates(w: np.ndarray, tab: np.ndarray) -> bool:
    """True when the final phase-1 tableau (8, N + 8) certifies that the origin is outside
    conv(W): its duals y_i = 1 - tab[7, N + i] give u = y[:6] with u . w_j < 0 for every
    wrench w_j (N, 6), by more than rounding (a separating hyperplane). False when rounding
    (a tiny pivot) has spoiled the tableau: the answer is then left undecided."""
    support, size = _dual_support(w, tab)
    return support < -1e-9 * size * _wrench_scale(w)


@jit.kernel
def _dual_support(w: np.ndarray, tab: np.ndarray) -> tuple[float, float]:
    """(max_j u . w_j, |u|) for the duals u (6,) of the phase-1 tableau (8, N + 8) (see
    :func:`_separates`) and the wrenches w (N, 6); NaN products are skipped."""
    n = w.shape[0]
    u = np.empty(6)
    size = 0.0
    for c in range(6):
        u[c] = 1.0 - tab[7, n + c]
        size += u[c] * u[c]
    support = -np.inf
    for j in range(n):
        d = 0.0
        for c in range(6):
            d += u[c] * w[j, c]
        if d > support:
            support = d
    return support, np.sqrt(size)


@jit.kernel
def _on_boundary(w: np.ndarray, tab: np.ndarray) -> bool:
    """True when the phase-1 duals u (see :func:`_dual_support`) bound Q: every wrench
    within FC_TOL / 2 of the wrench scale of the hyperplane u . x = 0 on one side, so the
    origin is outside conv(W) or at most that far inside it (Q <= max_j u . w_j / |u|):
    Q = 0 under the force-closure threshold. Typical of an equilibrium that is not force
    closure (a degenerate phase-1 basis, the origin on the hull)."""
    support, size = _dual_support(w, tab)
    return size > 0.0 and support <= 0.5 * FC_TOL * size * _wrench_scale(w)


@jit.kernel
def _initial_simplex(w: np.ndarray, tol: float) -> np.ndarray:
    """Indices (7,) of wrenches whose simplex contains the origin, [-1] if the origin is
    outside conv(W), [-3] if it is on the hull to FC_TOL (:func:`_on_boundary`: Q = 0), [-2]
    if undecided (degenerate basis)."""
    n = w.shape[0]
    rows, cols = 7, n + 7
    tab = _phase_one_tableau(w)
    basis = np.empty(rows, np.int64)
    for i in range(rows):
        basis[i] = n + i
    for it in range(200):
        enter = -1
        if it < DANTZIG_PIVOTS:  # the most negative reduced cost: few pivots
            lowest = -tol
            for j in range(cols):
                if tab[rows, j] < lowest:
                    lowest = tab[rows, j]
                    enter = j
        else:  # then Bland's rule (the first negative one), which cannot cycle
            for j in range(cols):
                if tab[rows, j] < -tol:
                    enter = j
                    break
        if enter < 0:
            break
        leave = _leaving_row(tab, basis, enter, tol)
        if leave < 0:
            return np.array([-2])
        _pivot(tab, leave, enter)
        basis[leave] = enter
    else:
        return np.array([-2])
    if -tab[rows, cols] > 1e-9 and _separates(w, tab):  # infeasible: the duals certify it
        return np.array([-1])
    degenerate = -tab[rows, cols] > 1e-9
    for i in range(rows):
        degenerate = degenerate or basis[i] >= n
    if degenerate:
        return np.array([-3]) if _on_boundary(w, tab) else np.array([-2])
    return basis


@jit.kernel(_nrt=False)
def _hyperplane(w: np.ndarray, verts: np.ndarray, interior: np.ndarray,
                out: np.ndarray, scale: float, basis: np.ndarray) -> float:
    """Unit normal of the hyperplane through w[verts] (6,) into ``out`` (6,), oriented away
    from ``interior``; returns the offset b (a . x = b), or NaN if degenerate. basis: (5, 6)
    scratch (every entry written before it is read)."""
    for r in range(5):
        for c in range(6):
            basis[r, c] = w[verts[r + 1], c] - w[verts[0], c]
        for _ in range(2):  # modified Gram-Schmidt, twice
            for q in range(r):
                d = 0.0
                for c in range(6):
                    d += basis[r, c] * basis[q, c]
                for c in range(6):
                    basis[r, c] -= d * basis[q, c]
        norm = 0.0
        for c in range(6):
            norm += basis[r, c] * basis[r, c]
        norm = np.sqrt(norm)
        if norm < 1e-9 * scale:
            return np.nan
        for c in range(6):
            basis[r, c] /= norm
    # the normal: the coordinate axis with the largest residual off the (orthonormal) basis,
    # 1 - sum_q basis[q, e]^2 (>= 1/6 for the best e), projected off it twice
    best = -1.0
    axis = 0
    for e in range(6):
        residual = 1.0
        for q in range(5):
            residual -= basis[q, e] * basis[q, e]
        if residual > best:
            best = residual
            axis = e
    for c in range(6):
        out[c] = 1.0 if c == axis else 0.0
    for _ in range(2):
        for q in range(5):
            d = 0.0
            for c in range(6):
                d += out[c] * basis[q, c]
            for c in range(6):
                out[c] -= d * basis[q, c]
    norm = 0.0
    for c in range(6):
        norm += out[c] * out[c]
    norm = np.sqrt(norm)
    for c in range(6):
        out[c] /= norm
    return _oriented_offset(out, w[verts[0]], interior)


@jit.kernel(_nrt=False)
def _oriented_offset(normal: np.ndarray, vertex: np.ndarray, interior: np.ndarray) -> float:
    """Offset b (a . x = b) of the hyperplane with unit normal ``normal`` (6,) through
    ``vertex`` (6,), the normal flipped in place (and b with it) where it points towards
    ``interior`` (6,)."""
    b = 0.0
    inner = 0.0
    for c in range(6):
        b += normal[c] * vertex[c]
        inner += normal[c] * interior[c]
    if inner > b:
        for c in range(6):
            normal[c] = -normal[c]
        b = -b
    return b


@jit.kernel(_nrt=False)
def _set_facet(w, verts, normal, offset, alive, f, interior, scale, basis) -> bool:
    """Hyperplane of facet f (vertices already in ``verts[f]``); False if degenerate.
    basis: :func:`_hyperplane`'s scratch."""
    b = _hyperplane(w, verts[f], interior, normal[f], scale, basis)
    if np.isnan(b):
        return False
    offset[f] = b
    alive[f] = True
    return True


@jit.kernel(_nrt=False)
def _wrench_scale(w: np.ndarray) -> float:
    """Largest |entry| of the wrenches w (N, 6)."""
    scale = 0.0
    for i in range(w.shape[0]):
        for c in range(6):
            scale = max(scale, abs(w[i, c]))
    return scale


@jit.kernel
def new_polytope():
    """Tables of a polytope of up to :data:`MAX_POINTS` wrenches: (verts (F, 6) vertex ids,
    normal (F, 6) unit outward normals, offset (F,) (a . x = b), alive (F,), interior (6,) a
    point inside, used (MAX_POINTS,) wrenches that are vertices, visible (F,) scratch, basis
    (5, 6) scratch of :func:`_hyperplane`, neighbour (F, 6): the facet across the ridge
    opposite each vertex, height (F,) scratch: how far the wrench being added lies beyond
    each visible facet, planes (7, F) scratch of :func:`_is_convex`), F = :data:`MAX_FACETS`;
    :func:`_clear_polytope` empties them for the next wrench set."""
    return (np.empty((MAX_FACETS, 6), np.int64), np.empty((MAX_FACETS, 6)),
            np.empty(MAX_FACETS), np.zeros(MAX_FACETS, np.bool_), np.zeros(6),
            np.zeros(MAX_POINTS, np.bool_), np.zeros(MAX_FACETS, np.bool_),
            np.zeros((5, 6)), np.empty((MAX_FACETS, 6), np.int64), np.empty(MAX_FACETS),
            np.empty((7, MAX_FACETS)))


@jit.kernel(_nrt=False)
def _clear_polytope(poly) -> None:
    """No wrench used and the interior point at 0 (both read before they are written). The
    facet tables need no clearing: every loop over facets stops at the set's own count, and
    each facet below it is written (made alive, or the set is abandoned) before it is read,
    its ``visible`` flag in the step that reads it (clearing the 4,096 rows cost ~3 us of a
    45 us set)."""
    interior, used = poly[4], poly[5]
    for c in range(6):
        interior[c] = 0.0
    for i in range(used.shape[0]):
        used[i] = False


@jit.kernel(_nrt=False)
def _start_polytope(w, start, poly, scale) -> bool:
    """The 7 facets of the simplex w[start] (start (7,)) and their neighbours into ``poly``
    (see :func:`new_polytope`); False if one is degenerate."""
    verts, normal, offset, alive, interior = poly[0], poly[1], poly[2], poly[3], poly[4]
    neighbour = poly[8]
    for skip in range(7):
        k = 0
        for i in range(7):
            if i != skip:
                verts[skip, k] = start[i]
                neighbour[skip, k] = i  # the ridge without start[i] is also facet i's
                k += 1
        if not _set_facet(w, verts, normal, offset, alive, skip, interior, scale, poly[7]):
            return False
    return True


@jit.kernel(_nrt=False)
def _nearest_facet(offset: np.ndarray, alive: np.ndarray, count: int) -> int:
    """The live facet of smallest offset among the first ``count``."""
    near = -1
    for f in range(count):
        if alive[f] and (near < 0 or offset[f] < offset[near]):
            near = f
    return near


@jit.kernel(_nrt=False)
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


@jit.kernel
def new_ridges():
    """The hash table of :func:`_link_new_facets`: keys and values (each (T,), T = 2^16 >=
    10 F, F = :data:`MAX_FACETS`)."""
    table = 64
    while table < 10 * MAX_FACETS:
        table *= 2
    return np.empty(table, np.int64), np.empty(table, np.int64)


@jit.kernel(_nrt=False)
def _mark_visible(w, far, poly, count, tol) -> None:
    """Mark the live facets that see wrench ``far`` (more than tol beyond them: poly's
    ``visible``) and how far beyond (``height``)."""
    normal, offset, alive, visible, height = poly[1], poly[2], poly[3], poly[6], poly[9]
    for f in range(count):
        visible[f] = False
        if alive[f]:
            d = -offset[f]
            for c in range(6):
                d += normal[f, c] * w[far, c]
            if d > tol:
                visible[f] = True
                height[f] = d


@jit.kernel(_nrt=False)
def _pencil_facet(w, poly, g, f, h, scale) -> bool:
    """Hyperplane of new facet g from those of the facets f (visible from its apex, the
    wrench ``verts[g, 5]``) and h (not) that share its ridge: every hyperplane through that
    ridge is a combination of theirs, and the one through the apex p is
    ``-d_h H_f + d_f H_h`` (d_*: the heights of p above them; a few multiplications where
    Gram-Schmidt takes hundreds). Accepted (False: use :func:`_set_facet`) only where every
    vertex of g lies within :data:`PENCIL_TOL` x the wrench scale of it, so the rounding it
    inherits from f and h cannot pile up over generations of facets; oriented as
    :func:`_hyperplane` orients, away from the interior point."""
    verts, normal, offset, alive, interior, height = (poly[0], poly[1], poly[2], poly[3],
                                                      poly[4], poly[9])
    apex = verts[g, 5]
    d_h = -offset[h]
    for c in range(6):
        d_h += normal[h, c] * w[apex, c]
    a, b = -d_h, height[f]
    norm = 0.0
    for c in range(6):
        x = a * normal[f, c] + b * normal[h, c]
        normal[g, c] = x
        norm += x * x
    norm = np.sqrt(norm)
    if not norm > PENCIL_MIN * (abs(a) + abs(b)):
        return False
    for c in range(6):
        normal[g, c] /= norm
    off = _oriented_offset(normal[g], w[verts[g, 0]], interior)
    limit = PENCIL_TOL * scale
    for v in range(1, 6):
        r = -off
        for c in range(6):
            r += normal[g, c] * w[verts[g, v], c]
        if abs(r) > limit:
            return False
    offset[g] = off
    alive[g] = True
    return True


@jit.kernel(_nrt=False)
def _vertex_set(verts: np.ndarray) -> np.int64:
    """The 6 vertex ids (each < :data:`MAX_POINTS` = 64) of a facet as the bits of one
    integer: a set, whatever their order, so that a ridge's key needs no sorting."""
    bits = np.int64(0)
    for v in range(6):
        bits |= np.int64(1) << np.int64(verts[v])
    return bits


@jit.kernel(_nrt=False)
def _slot(key: np.int64, mask: np.int64) -> np.int64:
    """Hash slot of a ridge key in a table of mask + 1 (a power of two <= 2^16) slots:
    Fibonacci hashing, the key times 2^64 / golden ratio modulo 2^64 (the product wraps, as
    intended; run interpreted, numpy warns of the overflow), bits 40 and up. (A product of
    32-bit halves that cannot overflow probed longer: 5 x 8 sets 4-7% slower.)"""
    return np.int64((np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)) & mask


@jit.kernel(_nrt=False)
def _link_new_facets(poly, first: int, count: int, ridges) -> bool:
    """Neighbours of the new facets first..count-1 across their ridges through the apex:
    each such ridge is held by exactly two new facets, found by its key in an
    open-addressing table (ridges: :func:`new_ridges`, keys and the facet and slot). False
    when a ridge is held once or more than twice (broken structure)."""
    verts, neighbour = poly[0], poly[8]
    table, value = ridges
    size = 64
    while size < 10 * (count - first):
        size *= 2
    mask = size - 1
    for s in range(size):
        table[s] = -1
    pending = 0
    for g in range(first, count):
        # the ridge without vertex k, less the apex (verts[g, 5]), shared by all of them
        base = _vertex_set(verts[g]) ^ (np.int64(1) << np.int64(verts[g, 5]))
        for k in range(5):
            key = base ^ (np.int64(1) << np.int64(verts[g, k]))
            s = _slot(key, mask)
            while table[s] != -1 and table[s] != key:
                s = (s + 1) & mask
            if table[s] == -1:
                table[s] = key
                value[s] = 8 * g + k
                pending += 1
            else:
                other = value[s]
                if other < 0:
                    return False
                neighbour[g, k] = other // 8
                neighbour[other // 8, other % 8] = g
                value[s] = -1
                pending -= 1
    return pending == 0


@jit.kernel(_nrt=False)
def _cone_horizon(w, far, poly, count, ridges, scale) -> int:
    """Cone the horizon (the ridges between a visible facet and a facet that is not) to
    wrench ``far``, link the new facets to their neighbours and retire the visible ones;
    returns the new facet count, -1 on a full table, a degenerate facet or broken structure.
    New facets are made in the order of their visible facet, then of its ridges."""
    verts, normal, offset, alive = poly[0], poly[1], poly[2], poly[3]
    interior, visible, neighbour = poly[4], poly[6], poly[8]
    first = count
    for f in range(first):
        if not visible[f]:
            continue
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
            if not _pencil_facet(w, poly, g, f, h, scale):
                if not _set_facet(w, verts, normal, offset, alive, g, interior, scale,
                                  poly[7]):
                    return -1
            count += 1
    if not _link_new_facets(poly, first, count, ridges):
        return -1
    for f in range(first):
        if visible[f]:
            alive[f] = False
    return count


@jit.kernel(_nrt=False)
def _is_convex(w, poly, count, tol) -> bool:
    """Every vertex lies on the inner side (to tol) of every live facet. The live facets'
    normals and offsets are first copied column by column into poly's ``planes`` (7, F), so
    that the inner loop, over the live facets only, reads contiguous rows."""
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
            if beyond:
                return False
    return True


@jit.kernel(_nrt=False)
def _expand(w, poly, count, tol, scale, ridges) -> int:
    """Grow the polytope (``count`` facets) nearest facet first until no wrench lies beyond
    the nearest facet; returns the facet count, -1 if not certified (a wrench found beyond
    twice, a failed step, or more steps than wrenches). ridges: :func:`new_ridges`."""
    n = w.shape[0]
    normal, offset, alive, used = poly[1], poly[2], poly[3], poly[5]
    for _ in range(n + 1):
        near = _nearest_facet(offset, alive, count)
        if near < 0:  # no live facet (impossible for consistent planes): not certified
            return -1
        far = _furthest_beyond(w, normal[near], offset[near] + tol)
        if far < 0:
            return count
        if used[far]:
            return -1
        _mark_visible(w, far, poly, count, tol)
        count = _cone_horizon(w, far, poly, count, ridges, scale)
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
    :func:`_initial_simplex`; [-2] past :data:`MAX_POINTS` wrenches), and where it is a code,
    the answer (Q, certified): Q = 0, certified unless undecided)."""
    if w.shape[0] > MAX_POINTS:
        return np.array([-2]), 0.0, False
    start = _initial_simplex(w, 1e-12)
    return start, 0.0, start[0] == -1 or start[0] == -3


@jit.kernel(_nrt=False)
def expand_from(w: np.ndarray, start: np.ndarray, poly, ridges) -> tuple[float, bool]:
    """:func:`epsilon_epa` from the initial simplex ``start`` (:func:`screen`), in the
    polytope and ridge tables given (:func:`new_polytope`, :func:`new_ridges`: ~2 MB, so a
    batch allocates them once, and a set that phase 1 settles needs none)."""
    scale = _wrench_scale(w)
    tol = REL_TOL * scale
    _clear_polytope(poly)
    interior, used = poly[4], poly[5]
    for i in range(7):
        for c in range(6):
            interior[c] += w[start[i], c] / 7.0
    if not _start_polytope(w, start, poly, scale):
        return 0.0, False
    for i in range(7):
        used[start[i]] = True
    count = _expand(w, poly, 7, tol, scale, ridges)
    # certify: closed (by construction, see the module docstring) and convex
    if count < 0:
        return 0.0, False
    if not _is_convex(w, poly, count, tol):
        return 0.0, False
    return _exact_nearest(w, poly, count, tol, scale)


@jit.kernel(_nrt=False)
def _exact_nearest(w, poly, count, tol, scale) -> tuple[float, bool]:
    """(Q, certified) of a closed, convex polytope of ``count`` facets: the smallest offset
    of its facets within :data:`NEAREST_BAND` x the wrench scale of the nearest, their
    hyperplanes computed afresh from their vertices (:func:`_hyperplane`: the numbers the
    facets of :func:`_pencil_facet` approximate), certified where that nearest facet
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
            b = _hyperplane(w, verts[f], interior, normal[f], scale, poly[7])
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
    on every exact path. A few microseconds per grasp: a screen before a costlier path."""
    out = np.zeros(w.shape[0], np.bool_)
    for b in range(w.shape[0]):
        out[b] = _initial_simplex(w[b], 1e-12)[0] == -1
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
