"""The tables of the expansion's polytope (:mod:`kinegrasp_env.quality.expansion`): its facets,
their hyperplanes and the neighbours across their ridges.

A polytope of up to :data:`MAX_POINTS` wrenches in R^6 is held in fixed tables of
:data:`MAX_FACETS` facets (:func:`new_polytope`, allocated once per batch): each facet's six
vertex ids, unit outward normal a and offset b (a . x = b), whether it is live, and the facet
across the ridge opposite each vertex. A facet's hyperplane is computed from its vertices by
Gram-Schmidt (:func:`hyperplane`), or, for a facet coned from a horizon ridge, from its two
parents' in the pencil through that ridge (:func:`pencil_facet`: a few multiplications where
Gram-Schmidt takes hundreds, accepted only where every vertex lies within
:data:`PENCIL_TOL` of it). The new facets of a step are paired across their ridges through
the apex by an open-addressing hash table keyed by the ridge's vertex set
(:func:`new_ridges`, :func:`link_new_facets`), which also checks that each such ridge is held
by exactly two of them.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit

MAX_FACETS = 4096
MAX_POINTS = 64  # ridge keys are sets of vertex ids, the bits of an int64
#: A facet hyperplane from its neighbours' (:func:`pencil_facet`) must pass within this
#: (relative to the wrench scale) of each of its vertices, else it is computed afresh.
PENCIL_TOL = 1e-13
#: ... and its unnormalized normal must not be shorter than this relative to its weights
#: (two nearly opposite neighbour normals: cancellation).
PENCIL_MIN = 1e-3


@jit.kernel(_nrt=False)
def hyperplane(w: np.ndarray, verts: np.ndarray, interior: np.ndarray,
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


@jit.kernel(_nrt=False, inline="always")
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
def set_facet(w, verts, normal, offset, alive, f, interior, scale, basis) -> bool:
    """Hyperplane of facet f (vertices already in ``verts[f]``); False if degenerate.
    basis: :func:`hyperplane`'s scratch."""
    b = hyperplane(w, verts[f], interior, normal[f], scale, basis)
    if np.isnan(b):
        return False
    offset[f] = b
    alive[f] = True
    return True


@jit.kernel
def new_polytope():
    """Tables of a polytope of up to :data:`MAX_POINTS` wrenches: (verts (F, 6) vertex ids,
    normal (F, 6) unit outward normals, offset (F,) (a . x = b), alive (F,), interior (6,) a
    point inside, used (MAX_POINTS,) wrenches that are vertices, visible (F,) scratch, basis
    (5, 6) scratch of :func:`hyperplane`, neighbour (F, 6): the facet across the ridge
    opposite each vertex, height (F,) scratch: how far the wrench being added lies beyond
    each visible facet, planes (7, F) scratch of the expansion's ``_is_convex``, checked
    (F,) int64: the step of the expansion that last tested each facet's visibility, and
    found (F,) int64 scratch: the visible facets of a step),
    F = :data:`MAX_FACETS`; :func:`clear_polytope` empties them for the next wrench set."""
    return (np.empty((MAX_FACETS, 6), np.int64), np.empty((MAX_FACETS, 6)),
            np.empty(MAX_FACETS), np.zeros(MAX_FACETS, np.bool_), np.zeros(6),
            np.zeros(MAX_POINTS, np.bool_), np.zeros(MAX_FACETS, np.bool_),
            np.zeros((5, 6)), np.empty((MAX_FACETS, 6), np.int64), np.empty(MAX_FACETS),
            np.empty((7, MAX_FACETS)), np.empty(MAX_FACETS, np.int64),
            np.empty(MAX_FACETS, np.int64))


@jit.kernel(_nrt=False)
def clear_polytope(poly) -> None:
    """No wrench used and the interior point at 0 (both read before they are written). The
    facet tables need no clearing: every loop over facets stops at the set's own count, and
    each facet below it is written (made alive, or the set is abandoned) before it is read,
    its ``visible`` flag and ``checked`` step when it is made (clearing the 4,096 rows was a
    noticeable share of a set's work)."""
    interior, used = poly[4], poly[5]
    for c in range(6):
        interior[c] = 0.0
    for i in range(used.shape[0]):
        used[i] = False


@jit.kernel(_nrt=False)
def start_polytope(w, start, poly, scale) -> bool:
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
        if not set_facet(w, verts, normal, offset, alive, skip, interior, scale, poly[7]):
            return False
        poly[6][skip] = False  # not visible, and not yet tested in any step
        poly[11][skip] = -1
    return True


@jit.kernel
def new_ridges():
    """The hash table of :func:`link_new_facets`: keys and values (each (T,), T = 2^16 >=
    10 F, F = :data:`MAX_FACETS`)."""
    table = 64
    while table < 10 * MAX_FACETS:
        table *= 2
    return np.empty(table, np.int64), np.empty(table, np.int64)


@jit.kernel(_nrt=False, inline="always")
def pencil_facet(w, poly, g, f, h, scale) -> bool:
    """Hyperplane of new facet g from those of the facets f (visible from its apex, the
    wrench ``verts[g, 5]``) and h (not) that share its ridge: every hyperplane through that
    ridge is a combination of theirs, and the one through the apex p is
    ``-d_h H_f + d_f H_h`` (d_*: the heights of p above them; a few multiplications where
    Gram-Schmidt takes hundreds). Accepted (False: use :func:`set_facet`) only where every
    vertex of g lies within :data:`PENCIL_TOL` x the wrench scale of it, so the rounding it
    inherits from f and h cannot pile up over generations of facets; oriented as
    :func:`hyperplane` orients, away from the interior point."""
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


@jit.kernel(_nrt=False, inline="always")
def _vertex_set(verts: np.ndarray) -> np.int64:
    """The 6 vertex ids (each < :data:`MAX_POINTS` = 64) of a facet as the bits of one
    integer: a set, whatever their order, so that a ridge's key needs no sorting."""
    bits = np.int64(0)
    for v in range(6):
        bits |= np.int64(1) << np.int64(verts[v])
    return bits


@jit.kernel(_nrt=False, inline="always")
def _slot(key: np.int64, mask: np.int64) -> np.int64:
    """Hash slot of a ridge key in a table of mask + 1 (a power of two <= 2^16) slots:
    Fibonacci hashing, the key times 2^64 / golden ratio modulo 2^64 (the product wraps, as
    intended; run interpreted, numpy warns of the overflow), bits 40 and up. (A product of
    32-bit halves that cannot overflow probed longer, which made 5 x 8 sets slower.)"""
    return np.int64((np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)) & mask


@jit.kernel(_nrt=False)
def link_new_facets(poly, first: int, count: int, ridges) -> bool:
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
