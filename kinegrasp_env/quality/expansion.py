"""Ferrari-Canny Q for 4+ contacts without the whole hull: nearest-facet-first expansion.

Q is the distance from the origin to the nearest facet of conv(W). Instead of every facet
(qhull builds ~1,000 for 32-40 wrenches in R^6), grow a polytope inside conv(W) from the
origin outwards (the expanding-polytope idea of EPA):

1. A simplex of 7 wrenches containing the origin: a basic feasible solution of
   ``W^T lam = 0, sum(lam) = 1, lam >= 0`` (phase-1 simplex, Bland's rule). No solution:
   the origin is outside conv(W), Q = 0.
2. Repeat: take the nearest facet (unit normal a, offset b); if no wrench lies beyond it,
   stop; else add the wrench furthest beyond it (facets it sees are removed, the horizon
   ridges are coned to it).
3. The answer is *certified* before it is returned: the final facet supports every wrench
   (so Q <= b: it is a facet hyperplane of conv(W)) and the polytope is closed (every ridge
   in exactly two facets) and convex (every facet has every vertex on its inner side), so
   the ball of radius b around the origin lies inside it, hence inside conv(W) (Q >= b).
   Anything that fails a check (a near-degenerate facet, a degenerate basis, a full facet
   table) returns "not certified" and the caller falls back to qhull.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit

MAX_FACETS = 4096
MAX_POINTS = 64  # ridge keys pack 5 vertex ids of 6 bits
REL_TOL = 1e-11  # beyond/visible tolerance, relative to the wrench scale


@jit.kernel
def _initial_simplex(w: np.ndarray, tol: float) -> np.ndarray:
    """Indices (7,) of wrenches whose simplex contains the origin, [-1] if the origin is
    outside conv(W), [-2] if undecided (degenerate basis)."""
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
    basis = np.empty(rows, np.int64)
    for i in range(rows):
        basis[i] = n + i
    # objective row: minimize the sum of artificials -> reduced costs
    for j in range(cols + 1):
        s = 0.0
        for i in range(rows):
            s += tab[i, j]
        tab[rows, j] = -s
    for i in range(rows):
        tab[rows, n + i] = 0.0
    for _ in range(200):
        enter = -1
        for j in range(cols):
            if tab[rows, j] < -tol:
                enter = j
                break
        if enter < 0:
            break
        leave = -1
        best = np.inf
        for i in range(rows):
            if tab[i, enter] > tol:
                ratio = tab[i, cols] / tab[i, enter]
                if ratio < best - 1e-15 or (abs(ratio - best) <= 1e-15 and leave >= 0
                                            and basis[i] < basis[leave]):
                    best = ratio
                    leave = i
        if leave < 0:
            return np.array([-2])
        piv = tab[leave, enter]
        for j in range(cols + 1):
            tab[leave, j] /= piv
        for i in range(rows + 1):
            if i != leave:
                f = tab[i, enter]
                if f != 0.0:
                    for j in range(cols + 1):
                        tab[i, j] -= f * tab[leave, j]
        basis[leave] = enter
    else:
        return np.array([-2])
    if -tab[rows, cols] > 1e-9:
        return np.array([-1])
    for i in range(rows):
        if basis[i] >= n:
            return np.array([-2])
    return basis


@jit.kernel
def _hyperplane(w: np.ndarray, verts: np.ndarray, interior: np.ndarray,
                out: np.ndarray, scale: float) -> float:
    """Unit normal of the hyperplane through w[verts] (6,) into ``out`` (6,), oriented away
    from ``interior``; returns the offset b (a . x = b), or NaN if degenerate."""
    basis = np.zeros((5, 6))
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
    best = -1.0
    cand = np.zeros(6)
    for e in range(6):
        for c in range(6):
            cand[c] = 1.0 if c == e else 0.0
        for _ in range(2):
            for q in range(5):
                d = 0.0
                for c in range(6):
                    d += cand[c] * basis[q, c]
                for c in range(6):
                    cand[c] -= d * basis[q, c]
        norm = 0.0
        for c in range(6):
            norm += cand[c] * cand[c]
        if norm > best:
            best = norm
            for c in range(6):
                out[c] = cand[c]
    norm = np.sqrt(best)
    for c in range(6):
        out[c] /= norm
    b = 0.0
    inner = 0.0
    for c in range(6):
        b += out[c] * w[verts[0], c]
        inner += out[c] * interior[c]
    if inner > b:
        for c in range(6):
            out[c] = -out[c]
        b = -b
    return b


@jit.kernel
def _set_facet(w, verts, normal, offset, alive, f, interior, scale) -> bool:
    """Hyperplane of facet f (vertices already in ``verts[f]``); False if degenerate."""
    b = _hyperplane(w, verts[f], interior, normal[f], scale)
    if np.isnan(b):
        return False
    offset[f] = b
    alive[f] = True
    return True


@jit.kernel
def _ridge_key(verts: np.ndarray, skip: int) -> np.int64:
    """Sorted 5 vertex ids (each < 64) of the ridge opposite vertex ``skip``, packed."""
    ids = np.empty(5, np.int64)
    k = 0
    for j in range(6):
        if j != skip:
            ids[k] = verts[j]
            k += 1
    ids.sort()
    key = np.int64(0)
    for j in range(5):
        key = key * 64 + ids[j]
    return key


@jit.kernel
def epsilon_epa(w: np.ndarray) -> tuple[float, bool]:
    """(Q, certified) for wrenches w (N, 6); Q = 0 if the origin is outside. More than
    :data:`MAX_POINTS` wrenches: not certified (the caller uses qhull)."""
    n = w.shape[0]
    if n > MAX_POINTS:
        return 0.0, False
    scale = 0.0
    for i in range(n):
        for c in range(6):
            scale = max(scale, abs(w[i, c]))
    tol = REL_TOL * scale
    start = _initial_simplex(w, 1e-12)
    if start[0] == -1:
        return 0.0, True
    if start[0] == -2:
        return 0.0, False
    interior = np.zeros(6)
    for i in range(7):
        for c in range(6):
            interior[c] += w[start[i], c] / 7.0
    verts = np.empty((MAX_FACETS, 6), np.int64)
    normal = np.empty((MAX_FACETS, 6))
    offset = np.empty(MAX_FACETS)
    alive = np.zeros(MAX_FACETS, np.bool_)
    used = np.zeros(n, np.bool_)
    count = 0
    for skip in range(7):
        k = 0
        for i in range(7):
            if i != skip:
                verts[count, k] = start[i]
                k += 1
        if not _set_facet(w, verts, normal, offset, alive, count, interior, scale):
            return 0.0, False
        count += 1
    for i in range(7):
        used[start[i]] = True
    visible = np.zeros(MAX_FACETS, np.bool_)
    keys = np.empty(6 * MAX_FACETS, np.int64)
    owner = np.empty(6 * MAX_FACETS, np.int64)
    skips = np.empty(6 * MAX_FACETS, np.int64)
    for _ in range(n + 1):
        near = -1
        for f in range(count):
            if alive[f] and (near < 0 or offset[f] < offset[near]):
                near = f
        a = normal[near]
        far = -1
        far_dist = offset[near] + tol
        for i in range(n):
            d = 0.0
            for c in range(6):
                d += a[c] * w[i, c]
            if d > far_dist:
                far_dist = d
                far = i
        if far < 0:
            break
        if used[far]:
            return 0.0, False
        # facets that see the new point, and their ridges
        m = 0
        for f in range(count):
            visible[f] = False
            if alive[f]:
                d = -offset[f]
                for c in range(6):
                    d += normal[f, c] * w[far, c]
                if d > tol:
                    visible[f] = True
                    for j in range(6):
                        keys[m] = _ridge_key(verts[f], j)
                        owner[m] = f
                        skips[m] = j
                        m += 1
        order = np.argsort(keys[:m])
        j = 0
        while j < m:
            r = j
            while r + 1 < m and keys[order[r + 1]] == keys[order[j]]:
                r += 1
            if r == j:  # horizon ridge: one visible facet holds it
                f = owner[order[j]]
                if count >= MAX_FACETS:
                    return 0.0, False
                k = 0
                for v in range(6):
                    if v != skips[order[j]]:
                        verts[count, k] = verts[f, v]
                        k += 1
                verts[count, 5] = far
                if not _set_facet(w, verts, normal, offset, alive, count, interior, scale):
                    return 0.0, False
                count += 1
            elif r > j + 1:
                return 0.0, False  # a ridge in three visible facets: broken structure
            j = r + 1
        for f in range(count):
            if visible[f]:
                alive[f] = False
        used[far] = True
    else:
        return 0.0, False
    # certify: closed (every ridge in exactly two facets) and convex
    m = 0
    for f in range(count):
        if alive[f]:
            for j in range(6):
                keys[m] = _ridge_key(verts[f], j)
                m += 1
    ridge_keys = np.sort(keys[:m])
    j = 0
    while j < m:
        if j + 1 >= m or ridge_keys[j + 1] != ridge_keys[j]:
            return 0.0, False
        if j + 2 < m and ridge_keys[j + 2] == ridge_keys[j]:
            return 0.0, False
        j += 2
    for f in range(count):
        if alive[f]:
            for i in range(n):
                if used[i]:
                    d = -offset[f]
                    for c in range(6):
                        d += normal[f, c] * w[i, c]
                    if d > tol:
                        return 0.0, False
    best = np.inf
    for f in range(count):
        if alive[f] and offset[f] < best:
            best = offset[f]
    return max(best, 0.0), True


@jit.kernel
def epsilon_epa_batch(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Q (B,), certified (B,)) for wrench sets w (B, N, 6)."""
    q = np.zeros(w.shape[0])
    ok = np.zeros(w.shape[0], np.bool_)
    for b in range(w.shape[0]):
        q[b], ok[b] = epsilon_epa(w[b])
    return q, ok
