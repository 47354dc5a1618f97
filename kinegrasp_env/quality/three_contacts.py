"""Exact, batched Ferrari-Canny (L1) quality for three contacts by facet enumeration.

With 3 contacts and m cone edges the wrench set is three planar m-gons P_1, P_2, P_3 in R^6:
edge j of contact i is w_ij = c_i + cos(theta_j) A_i + sin(theta_j) B_i (c_i the wrench of
the contact normal, A_i, B_i those of mu t1, mu t2). A facet of their convex hull meets each
polygon in a face (empty, vertex, edge or the whole polygon) and is spanned by 6 affinely
independent points, so in general position it touches the polygons in one of three
patterns: 2+2+2 (an edge of each: m^3 candidates), 3+2+1 (a whole polygon, an edge, a
vertex: 6 m^2) or 3+3+0 (two whole polygons: 3). In degenerate position a facet holds more
points but still contains one such sub-configuration, so the candidates are complete.

Every candidate hyperplane is computed for a whole batch at once without any per-candidate
linear algebra. In coordinates x in R^8 with respect to E = [A_1, B_1, A_2, B_2, A_3, B_3,
c_2 - c_1, c_3 - c_1] (w = c_1 + E x) a hyperplane n . w = d pulls back to y . x = const with
y = E^T n; y must be orthogonal to the 5 constraint vectors of the candidate (rows of a
constant 5 x 8 matrix L) and to null(E) (two vectors N). By Laplace expansion y is a fixed
linear function of the 28 2x2 minors of N^T, with coefficients (5x5 minors of L) that depend
only on m and are computed once. A candidate is kept when every wrench lies on one side of
its hyperplane (to 1e-10 relative); Q is the smallest distance from the origin to a kept
hyperplane, and 0 unless the origin is strictly inside all of them.

Grasps whose wrench set is close to rank-deficient, or for which no facet is found, are
returned as *not certified*; the caller recomputes them with qhull.
"""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations, permutations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.quality.wrenches import NOT_CLOSED, closure_classes

#: Relative tolerance of the supporting-hyperplane test.
SUPPORT_TOL = 1e-10
#: Candidates whose normal is this much shorter than the longest are treated as degenerate.
DEGENERATE_NORMAL = 1e-9
#: sigma_6 / sigma_1 of E below which the grasp is exactly rank-deficient (Q = 0) ...
RANK_ZERO = 1e-10
#: ... and below which (but above RANK_ZERO) it is left to qhull.
RANK_UNSURE = 1e-6
#: Bytes of the largest temporary array per chunk.
CHUNK_BYTES = 32 * 2**20

_PAIRS = tuple(combinations(range(8), 2))
_SUBSETS = {s: i for i, s in enumerate(combinations(range(8), 5))}


def _polygon_points(m: int) -> np.ndarray:
    """(3, m, 8) coordinates of the wrenches w_ij - c_1 in the basis E."""
    theta = 2.0 * np.pi * np.arange(m) / m
    pts = np.zeros((3, m, 8))
    for i in range(3):
        pts[i, :, 2 * i] = np.cos(theta)
        pts[i, :, 2 * i + 1] = np.sin(theta)
        if i > 0:
            pts[i, :, 5 + i] = 1.0
    return pts


def _edge(pts: np.ndarray, i: int, j: int) -> np.ndarray:
    """(8,) edge (j, j + 1) of polygon i."""
    m = pts.shape[1]
    return pts[i, (j + 1) % m] - pts[i, j]


def _edge_test(m: int, i: int, j: int) -> tuple[int, float, float]:
    """y . (vertex j - polygon centre): > 0 iff edge (j, j+1) is the polygon's maximum."""
    theta = 2.0 * np.pi * np.arange(m) / m
    return i, np.cos(theta[j]), np.sin(theta[j])


def _vertex_test(pts: np.ndarray, i: int, k: int, other: int) -> tuple[int, float, float]:
    """y . (vertex k - vertex other): >= 0 for both neighbours iff vertex k is the maximum."""
    d = pts[i, k] - pts[i, other % pts.shape[1]]
    return i, d[2 * i], d[2 * i + 1]


def _candidates(pts: np.ndarray) -> tuple[list, list, list]:
    """Every candidate facet: (constraint rows (C, 5, 8), a point on it (C, 8), its three
    tests (C - 3, 3, 3)), in the order 2+2+2, the six 3+2+1 orderings, then 3+3+0 (these
    last three have no tests)."""
    m = pts.shape[1]
    unit = np.eye(8)
    rows, refs, tests = [], [], []
    for j1 in range(m):
        for j2 in range(m):
            for j3 in range(m):
                p1 = pts[0, j1]
                rows.append([_edge(pts, 0, j1), _edge(pts, 1, j2), _edge(pts, 2, j3),
                             pts[1, j2] - p1, pts[2, j3] - p1])
                refs.append(p1)
                tests.append([_edge_test(m, 0, j1), _edge_test(m, 1, j2),
                              _edge_test(m, 2, j3)])
    for full, with_edge, with_vertex in permutations(range(3)):
        base = pts[full, 0]
        for j in range(m):
            for k in range(m):
                rows.append([unit[2 * full], unit[2 * full + 1], _edge(pts, with_edge, j),
                             pts[with_edge, j] - base, pts[with_vertex, k] - base])
                refs.append(base)
                tests.append([_edge_test(m, with_edge, j),
                              _vertex_test(pts, with_vertex, k, k - 1),
                              _vertex_test(pts, with_vertex, k, k + 1)])
    for a, b in combinations(range(3), 2):
        base = pts[a, 0]
        rows.append([unit[2 * a], unit[2 * a + 1], unit[2 * b], unit[2 * b + 1],
                     pts[b, 0] - base])
        refs.append(base)
    return rows, refs, tests


def _laplace_kernel(lmat: np.ndarray) -> np.ndarray:
    """(28, 8 * C) map from the 2x2 minors of N^T to the y vectors of the candidates with
    constraint rows lmat (C, 5, 8) (component-major: y[k, c] at column k * C + c)."""
    minors = np.zeros((lmat.shape[0], len(_SUBSETS)))
    for subset, index in _SUBSETS.items():
        minors[:, index] = np.linalg.det(lmat[:, :, list(subset)])
    # y_k = (-1)^k det(M without column k), M = [L; N^T]; Laplace along the N^T rows (5, 6):
    # det = sum over column pairs (a, b) of (-1)^(5 + 6 + pos_a + pos_b) minor(N^T) minor(L)
    kernel = np.zeros((len(_PAIRS), lmat.shape[0], 8))
    for t, (a, b) in enumerate(_PAIRS):
        for k in range(8):
            if k in (a, b):
                continue
            reduced = [c for c in range(8) if c != k]
            pos_a, pos_b = reduced.index(a), reduced.index(b)
            subset = tuple(c for c in reduced if c not in (a, b))
            sign = (-1) ** (k + 11 + pos_a + pos_b)
            kernel[t, :, k] = sign * minors[:, _SUBSETS[subset]]
    return np.ascontiguousarray(kernel.transpose(0, 2, 1)).reshape(len(_PAIRS), -1)


def _test_blocks(tests: np.ndarray, m: int) -> tuple:
    """Blocks of candidates whose three tests use the same polygons (2+2+2, then the six
    3+2+1 orderings), from tests (C - 3, 3, 3) (polygon, coefficient of y_A, of y_B)."""
    blocks = []
    for start, stop in [(0, m**3)] + [(m**3 + i * m * m, m**3 + (i + 1) * m * m)
                                      for i in range(6)]:
        polys = tuple(int(p) for p in tests[start, :, 0])
        if not np.all(tests[start:stop, :, 0] == polys):  # pragma: no cover - table bug
            raise RuntimeError("candidate table: mixed polygons within a block")
        blocks.append((start, stop, polys, tests[start:stop, :, 1].T.copy(),
                       tests[start:stop, :, 2].T.copy()))
    return tuple(blocks)


@lru_cache(maxsize=8)
def candidate_tables(num_edges: int) -> tuple:
    """Constant tables for m = ``num_edges``.

    Returns:
        points: (3 m, 8) coordinates of the wrenches w_ij - c_1 in the basis E.
        ref: (C, 8) coordinates of one point on each candidate hyperplane.
        kernel: (28, 8 * C) map from the 2x2 minors of N^T to the candidates' y vectors
            (component-major: y[k, c] at column k * C + c).
        blocks: (start, stop, polygons (3,), a (3, n), b (3, n)) per block of candidates:
            test t of candidate c is y[2 p_t, c] a[t] + y[2 p_t + 1, c] b[t]; a candidate
            supports the hull iff its three tests share a sign. The last three candidates
            (two whole polygons) are tested against every point of the third polygon.
    """
    m = num_edges
    pts = _polygon_points(m)
    rows, refs, tests = _candidates(pts)
    kernel = _laplace_kernel(np.array(rows))
    return pts.reshape(3 * m, 8), np.array(refs), kernel, _test_blocks(np.array(tests), m)


def _polygon_basis(wrenches: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(centre (B, 3, 6) the polygons' centres c_i, basis E (B, 6, 8): columns A_1, B_1,
    A_2, B_2, A_3, B_3, c_2 - c_1, c_3 - c_1) of edge wrenches (B, 3 m, 6)."""
    batch = wrenches.shape[0]
    w = wrenches.reshape(batch, 3, m, 6)
    theta = 2.0 * np.pi * np.arange(m) / m
    centre = w.mean(axis=2)  # c_i: regular polygon's centroid
    rel = w - centre[:, :, None, :]
    # least squares for A_i, B_i: rel_j = cos(theta_j) A + sin(theta_j) B (exact fit)
    cs = np.stack([np.cos(theta), np.sin(theta)], axis=1)  # (m, 2)
    coef = np.linalg.pinv(cs)  # (2, m)
    ab = np.einsum("tj,bijk->bitk", coef, rel)  # (B, 3, 2, 6)
    basis = np.concatenate([ab.reshape(batch, 6, 6), (centre[:, 1:] - centre[:, :1])], axis=1)
    return centre, np.swapaxes(basis, 1, 2)  # (B, 6, 8): columns are the basis vectors


@lru_cache(maxsize=8)
def _test_arrays(num_edges: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The blocks of :func:`candidate_tables` per tested candidate: polygons (C - 3, 3) and
    the coefficients a, b (3, C - 3) of its three tests."""
    blocks = candidate_tables(num_edges)[3]
    polys = np.concatenate([np.tile(np.array(p, dtype=np.int64), (hi - lo, 1))
                            for lo, hi, p, _, _ in blocks])
    coef_a = np.ascontiguousarray(np.concatenate([blk[3] for blk in blocks], axis=1))
    coef_b = np.ascontiguousarray(np.concatenate([blk[4] for blk in blocks], axis=1))
    return polys, coef_a, coef_b


@jit.kernel
def _run_tests(y, tol, polys, coef_a, coef_b, up, down) -> None:
    """up/down (b, C - 3) of the tested candidates (see :func:`_supporting`): test t of
    candidate c is y[2 p, c] a[t, c] + y[2 p + 1, c] b[t, c] (p = polys[c, t]), the same
    products and sum as numpy forms them, so the same decisions."""
    for r in range(y.shape[0]):
        for c in range(coef_a.shape[1]):
            above = True
            below = True
            for t in range(3):
                p = polys[c, t]
                test = y[r, 2 * p, c] * coef_a[t, c] + y[r, 2 * p + 1, c] * coef_b[t, c]
                above = above and test >= -tol[r, c]
                below = below and test <= tol[r, c]
            up[r, c] = above
            down[r, c] = below


def _supporting(y: np.ndarray, tol: np.ndarray, tables: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(up, down) (b, C) bool: every wrench on the candidate's positive (negative) side, to
    tol (b, C), for the candidates' y vectors (b, 8, C)."""
    pts, ref = tables[0], tables[1]
    nb, n_cand = y.shape[0], y.shape[2]
    n_tested = n_cand - 3
    up = np.empty((nb, n_cand), dtype=bool)
    down = np.empty((nb, n_cand), dtype=bool)
    polys, coef_a, coef_b = _test_arrays(pts.shape[0] // 3)
    _run_tests(np.ascontiguousarray(y), np.ascontiguousarray(tol), polys, coef_a, coef_b,
               up[:, :n_tested], down[:, :n_tested])
    last = np.swapaxes(y[:, :, n_tested:], 1, 2)  # (b, 3, 8)
    values = last @ pts.T - np.einsum("bck,ck->bc", last, ref[n_tested:])[..., None]
    l_tol = tol[:, n_tested:, None]
    up[:, n_tested:] = np.all(values <= l_tol, axis=2)
    down[:, n_tested:] = np.all(values >= -l_tol, axis=2)
    return up, down


def _nearest_facets(idx: np.ndarray, tables: tuple, centre: np.ndarray, svd: tuple,
                    col_norm: np.ndarray, with_normal: bool
                    ) -> tuple[np.ndarray, np.ndarray | None]:
    """For grasps idx (b,): (distance (b,) from the origin to the nearest supporting
    candidate, inf if none; its unit outward normal (b, 6) if ``with_normal``, else None).
    svd: (U, sigma, Vh) of the bases E (:func:`_polygon_basis`), centre and col_norm (the
    longest basis vector), all of every grasp (indexed here by idx)."""
    u_mat, sing, vh = svd
    ref, kernel = tables[1], tables[2]
    nb, n_cand = idx.size, ref.shape[0]
    null = vh[idx, 6:, :]  # (b, 2, 8) rows span null(E)
    outer = null[:, 0, :, None] * null[:, 1, None, :]  # (b, 8, 8)
    pair_minor = np.stack([outer[:, a, b] - outer[:, b, a] for a, b in _PAIRS], axis=1)
    y = (pair_minor @ kernel).reshape(nb, 8, n_cand)
    y_norm = np.sqrt(np.einsum("bkc,bkc->bc", y, y))
    tol = SUPPORT_TOL * y_norm * col_norm[idx, None]
    up, down = _supporting(y, tol, tables)
    good = (up ^ down) & (y_norm > DEGENERATE_NORMAL * y_norm.max(axis=1, keepdims=True))
    # hyperplane normal n = U diag(1/sigma) Vh[:6] y, and n . w at the reference point
    proj = u_mat[idx] @ (vh[idx, :6, :] / sing[idx, :, None])  # (b, 6, 8)
    normal = proj @ y  # (b, 6, C)
    norm = np.sqrt(np.einsum("bjc,bjc->bc", normal, normal))
    offset = (centre[idx, 0, None, :] @ normal)[:, 0] + np.einsum("ck,bkc->bc", ref, y)
    dist = np.where(good, np.where(up, offset, -offset) / np.where(norm > 0, norm, 1.0),
                    np.inf)
    best = dist.min(axis=1)
    if not with_normal:
        return best, None
    arg = np.argmin(dist, axis=1)
    rows = np.arange(nb)
    sign = np.where(up[rows, arg], 1.0, -1.0)
    unit = normal[rows, :, arg] * (sign / np.where(norm[rows, arg] > 0,
                                                    norm[rows, arg], 1.0))[:, None]
    return best, unit


def epsilon_three_contacts(wrenches: np.ndarray, num_edges: int, return_normal: bool = False
                           ) -> tuple[np.ndarray, ...]:
    """Q for B three-contact grasps.

    Args:
        wrenches: (B, 3 m, 6) edge wrenches (row i m + j = edge j of contact i), as built by
            :func:`kinegrasp_env.quality.wrenches.wrench_matrix` with friction > 0.
        num_edges: m.
        return_normal: also return the unit outward normal of the nearest facet.

    Returns:
        (q (B,), certified (B,) bool[, normal (B, 6)]). Rows that are not certified must be
        recomputed; the normal is NaN where no facet was found.
    """
    m = num_edges
    batch = wrenches.shape[0]
    tables = candidate_tables(m)
    centre, basis = _polygon_basis(wrenches, m)
    svd = np.linalg.svd(basis, full_matrices=True)
    ratio = svd[1][:, 5] / svd[1][:, 0]
    q = np.zeros(batch)
    certified = np.ones(batch, dtype=bool)
    nearest = np.full((batch, 6), np.nan)
    rank_zero = ratio <= RANK_ZERO
    unsure = (ratio > RANK_ZERO) & (ratio <= RANK_UNSURE)
    certified[unsure] = False
    live = np.flatnonzero(~rank_zero & ~unsure)
    scale = np.abs(wrenches).max(axis=(1, 2))
    col_norm = np.linalg.norm(basis, axis=1).max(axis=1)  # largest basis vector, (B,)
    chunk = max(1, CHUNK_BYTES // (tables[1].shape[0] * 8 * 24))
    for start in range(0, live.size, chunk):
        idx = live[start:start + chunk]
        best, unit = _nearest_facets(idx, tables, centre, svd, col_norm, return_normal)
        found = np.isfinite(best)
        certified[idx[~found]] = False
        q[idx] = np.where(found & (closure_classes(best, scale[idx]) != NOT_CLOSED), best, 0.0)
        if return_normal:
            nearest[idx[found]] = unit[found]
    if return_normal:
        return q, certified, nearest
    return q, certified
