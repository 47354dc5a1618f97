"""Distance between two convex polytopes given by their vertices, compiled: the
Gilbert-Johnson-Keerthi iteration (GJK) on the Minkowski difference A - B, with the closest
point of each simplex to the origin found by its Voronoi regions.

What it returns is a *certified lower bound* of the distance: every support point w of A - B
in the direction -v gives the separating plane bound v . w / |v| <= distance (each support
exact: searched over all of a part's points, or walked along a superset of its hull's edges,
:func:`stacked_points`), and the
iteration stops once |v|^2 - v . w <= :data:`GAP_REL` |v|^2 (then the bound is within that
relative amount of the distance, from below) or when it makes no progress. Where the origin
lies inside the simplex (the polytopes touch or overlap) the bound is -inf: the caller
decides such cases by an exact signed distance
(:func:`~kinegrasp_env.closing.hull_edges.edges_against_hull` and
:func:`~kinegrasp_env.closing.hull_edges.vertices_against_parts`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.world.polytope import plane_keys

#: Relative gap |v|^2 - v . w <= GAP_REL |v|^2 at which the iteration stops.
GAP_REL = 1e-10
#: Iterations at most (a polytope pair of a few hundred vertices needs a dozen).
MAX_ITER = 64
#: Parts of more points than this are searched by walking their hull's faces' vertices.
WALK_MIN = 16

__all__ = ["GAP_REL", "MAX_ITER", "WALK_MIN", "hint_shape", "hull_distance_bounds",
           "hull_spheres", "new_hints", "new_simplex", "stacked_faces", "stacked_points",
           "stacked_vertices"]


def stacked_vertices(parts) -> tuple[np.ndarray, ...]:
    """Convex parts' (:class:`~kinegrasp_env.world.polytope.ConvexPart`) vertices in the
    layout :func:`hull_distance_bounds` reads (:func:`stacked_points`)."""
    return stacked_points([p.vertices for p in parts])


def stacked_points(point_sets: list[np.ndarray]) -> tuple[np.ndarray, ...]:
    """Point sets ((V_p, 3) each, metres), each standing for its convex hull, laid out for
    :func:`hull_distance_bounds`: (vertices (V, 3), each part's first row (P + 1,) int64,
    each part's bounding sphere (P, 4) (:func:`hull_spheres`), each vertex's first
    neighbour row (V + 1,) int64 and the neighbours (K,) int64).

    A part of more than :data:`WALK_MIN` points whose hull qhull can take keeps only its
    hull's vertices, each with its neighbours: every other vertex of each face it lies on
    (a superset of the polytope's edges): the support search walks them (a vertex no
    neighbour of which lies further along a direction is the hull's furthest, as in the
    simplex method). A smaller or flat part keeps every point and no neighbours: its
    support is searched over all of them."""
    parts, links = [], []
    for points in point_sets:
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        kept, neighbours = _hull_graph(points)
        parts.append(kept)
        links.append(neighbours)
    vertices = np.ascontiguousarray(np.vstack(parts), dtype=float)
    starts = np.cumsum([0] + [len(p) for p in parts]).astype(np.int64)
    counts, flat = [], []
    for first, neighbours in zip(starts[:-1], links, strict=True):
        for row in neighbours:
            counts.append(len(row))
            flat.extend(int(first) + k for k in row)
    first_neighbour = np.cumsum([0, *counts]).astype(np.int64)
    return (vertices, starts, hull_spheres(vertices, starts), first_neighbour,
            np.asarray(flat, dtype=np.int64))


def _hull_graph(points: np.ndarray) -> tuple[np.ndarray, list[list[int]]]:
    """(the points kept (V', 3), each kept point's neighbours (indices into the kept)):
    the hull's vertices and edges, or every point without neighbours (see
    :func:`stacked_points`)."""
    none: list[list[int]] = [[] for _ in points]
    if len(points) <= WALK_MIN:
        return points, none
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(points)
    except QhullError:  # flat or degenerate: searched whole
        return points, none
    order = np.sort(hull.vertices)
    index = {int(v): k for k, v in enumerate(order)}
    neighbours: list[set[int]] = [set() for _ in order]
    # every vertex of a face joined to every other: qhull merges nearly coplanar facets and
    # splits a merged one into triangles that may overlap, so its triangles' edges alone can
    # leave a vertex inside the face with no higher neighbour (faces: triangles of one plane)
    _, face = np.unique(plane_keys(hull.equations), axis=0, return_inverse=True)
    for f in range(int(face.max()) + 1):
        members = [index[int(v)] for v in np.unique(hull.simplices[face.ravel() == f])]
        for a in members:
            neighbours[a].update(members)
            neighbours[a].discard(a)
    return points[order], [sorted(row) for row in neighbours]


def hull_spheres(vertices: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(P, 4) a bounding sphere (centre (3,), radius; metres) of each part of stacked
    vertices (V, 3) split by starts (P + 1,): the centre of the part's bounding box."""
    spheres = np.empty((len(starts) - 1, 4))
    for p in range(len(starts) - 1):
        part = vertices[starts[p]:starts[p + 1]]
        spheres[p, :3] = 0.5 * (part.min(axis=0) + part.max(axis=0))
        spheres[p, 3] = np.linalg.norm(part - spheres[p, :3], axis=1).max()
    return spheres


def stacked_faces(parts) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Convex parts' face planes stacked (F, 4) with each part's first row (P + 1,) int64,
    and their edges stacked (E, 2, 3) with each part's first row (P + 1,) int64: the layout
    the compiled exact distances read."""
    return (np.ascontiguousarray(np.vstack([p.planes for p in parts]), dtype=float),
            np.cumsum([0] + [len(p.planes) for p in parts]).astype(np.int64),
            np.ascontiguousarray(np.concatenate([p.edges for p in parts]), dtype=float),
            np.cumsum([0] + [len(p.edges) for p in parts]).astype(np.int64))


def hint_shape(n: int, a_stack: tuple, b_stack: tuple) -> tuple[int, int, int]:
    """(n, P Q, 2): the shape of :func:`new_hints`' array for A's P parts and B's Q
    (stacked: :func:`stacked_points`) at n draws."""
    return n, (len(a_stack[1]) - 1) * (len(b_stack[1]) - 1), 2


def new_hints(n: int, a_stack: tuple, b_stack: tuple) -> np.ndarray:
    """(n, P Q, 2) int64 of -1: no start known for any pair of A's P parts and B's Q
    (stacked: :func:`stacked_points`) at n draws (:func:`hull_distance_bounds`)."""
    return np.full(hint_shape(n, a_stack, b_stack), -1, dtype=np.int64)


def new_simplex() -> np.ndarray:
    """(4, 3) scratch for :func:`hull_distance_bounds` (the simplex's points)."""
    return np.empty((4, 3))


@jit.kernel(_nrt=False, inline="always")
def _keep(w, m, a, b, c):
    """Keep the simplex points with indices a, b, c (-1: none) in that order; their count."""
    ax, ay, az = w[a, 0], w[a, 1], w[a, 2]
    bx, by, bz = w[max(b, 0), 0], w[max(b, 0), 1], w[max(b, 0), 2]
    cx, cy, cz = w[max(c, 0), 0], w[max(c, 0), 1], w[max(c, 0), 2]
    w[0, 0], w[0, 1], w[0, 2] = ax, ay, az
    if b < 0:
        return 1
    w[1, 0], w[1, 1], w[1, 2] = bx, by, bz
    if c < 0:
        return 2
    w[2, 0], w[2, 1], w[2, 2] = cx, cy, cz
    return 3


@jit.kernel(_nrt=False, inline="always")
def _segment(w, a, b):
    """Closest point to the origin on segment w[a] w[b]: (x, y, z, index a or -1 for a
    dropped, index b or -1)."""
    ex, ey, ez = w[b, 0] - w[a, 0], w[b, 1] - w[a, 1], w[b, 2] - w[a, 2]
    length2 = ex * ex + ey * ey + ez * ez
    t = -(w[a, 0] * ex + w[a, 1] * ey + w[a, 2] * ez) / max(length2, 1e-300)
    if t <= 0.0:
        return w[a, 0], w[a, 1], w[a, 2], a, -1
    if t >= 1.0:
        return w[b, 0], w[b, 1], w[b, 2], b, -1
    return w[a, 0] + t * ex, w[a, 1] + t * ey, w[a, 2] + t * ez, a, b


@jit.kernel(_nrt=False, inline="always")
def _triangle(w, a, b, c):
    """Closest point to the origin on triangle w[a] w[b] w[c] by its Voronoi regions:
    (x, y, z, i, j, k) with i, j, k the indices of the feature's points (-1 padded)."""
    abx, aby, abz = w[b, 0] - w[a, 0], w[b, 1] - w[a, 1], w[b, 2] - w[a, 2]
    acx, acy, acz = w[c, 0] - w[a, 0], w[c, 1] - w[a, 1], w[c, 2] - w[a, 2]
    apx, apy, apz = -w[a, 0], -w[a, 1], -w[a, 2]
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return w[a, 0], w[a, 1], w[a, 2], a, -1, -1
    bpx, bpy, bpz = -w[b, 0], -w[b, 1], -w[b, 2]
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return w[b, 0], w[b, 1], w[b, 2], b, -1, -1
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return w[a, 0] + t * abx, w[a, 1] + t * aby, w[a, 2] + t * abz, a, b, -1
    cpx, cpy, cpz = -w[c, 0], -w[c, 1], -w[c, 2]
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return w[c, 0], w[c, 1], w[c, 2], c, -1, -1
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return w[a, 0] + t * acx, w[a, 1] + t * acy, w[a, 2] + t * acz, a, c, -1
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return (w[b, 0] + t * (w[c, 0] - w[b, 0]), w[b, 1] + t * (w[c, 1] - w[b, 1]),
                w[b, 2] + t * (w[c, 2] - w[b, 2]), b, c, -1)
    total = va + vb + vc
    if not total > 0.0:  # a degenerate triangle: its best edge
        x1, y1, z1, i1, j1 = _segment(w, a, b)
        x2, y2, z2, i2, j2 = _segment(w, a, c)
        if x2 * x2 + y2 * y2 + z2 * z2 < x1 * x1 + y1 * y1 + z1 * z1:
            return x2, y2, z2, i2, j2, -1
        return x1, y1, z1, i1, j1, -1
    v, u = vb / total, vc / total
    return (w[a, 0] + v * abx + u * acx, w[a, 1] + v * aby + u * acy,
            w[a, 2] + v * abz + u * acz, a, b, c)


@jit.kernel(_nrt=False, inline="always")
def _outside(w, a, b, c, d):
    """True where the origin may lie beyond face (a, b, c) of the tetrahedron (away from
    its fourth point d; a flat tetrahedron counts every face)."""
    abx, aby, abz = w[b, 0] - w[a, 0], w[b, 1] - w[a, 1], w[b, 2] - w[a, 2]
    acx, acy, acz = w[c, 0] - w[a, 0], w[c, 1] - w[a, 1], w[c, 2] - w[a, 2]
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    origin = -(nx * w[a, 0] + ny * w[a, 1] + nz * w[a, 2])
    other = nx * (w[d, 0] - w[a, 0]) + ny * (w[d, 1] - w[a, 1]) + nz * (w[d, 2] - w[a, 2])
    return origin * other <= 0.0


@jit.kernel(_nrt=False, inline="always")
def _reduce(w, m):
    """Replace the simplex w[:m] by the least subset whose hull holds its closest point to
    the origin; (x, y, z of that point, its new size; 4 where the origin is inside)."""
    if m == 1:
        return w[0, 0], w[0, 1], w[0, 2], 1
    if m == 2:
        x, y, z, i, j = _segment(w, 0, 1)
        return x, y, z, _keep(w, m, i, j, -1)
    if m == 3:
        x, y, z, i, j, k = _triangle(w, 0, 1, 2)
        return x, y, z, _keep(w, m, i, j, k)
    best, bx, by, bz, bi, bj, bk = np.inf, 0.0, 0.0, 0.0, -1, -1, -1
    for face in range(4):  # the face opposite point `face`
        a, b, c = (1, 2, 3) if face == 0 else ((0, 2, 3) if face == 1 else
                                               ((0, 1, 3) if face == 2 else (0, 1, 2)))
        if _outside(w, a, b, c, face):
            x, y, z, i, j, k = _triangle(w, a, b, c)
            d2 = x * x + y * y + z * z
            if d2 < best:
                best, bx, by, bz, bi, bj, bk = d2, x, y, z, i, j, k
    if bi < 0:
        return 0.0, 0.0, 0.0, 4
    return bx, by, bz, _keep(w, m, bi, bj, bk)


@jit.kernel(_nrt=False, inline="always")
def _support(vertices, start, stop, first, neighbours, dx, dy, dz, at):
    """The row of vertices[start:stop] furthest along (dx, dy, dz): walked from row ``at``
    along a superset of the hull's edges (``first``, ``neighbours``: :func:`stacked_points`)
    where the part has them, else the first of the furthest of all rows."""
    if first[start] == first[stop]:
        top, pick = -np.inf, start
        for k in range(start, stop):
            s = dx * vertices[k, 0] + dy * vertices[k, 1] + dz * vertices[k, 2]
            if s > top:
                top, pick = s, k
        return pick
    pick = at
    top = dx * vertices[pick, 0] + dy * vertices[pick, 1] + dz * vertices[pick, 2]
    moved = True
    while moved:
        moved = False
        for j in range(first[pick], first[pick + 1]):
            k = neighbours[j]
            s = dx * vertices[k, 0] + dy * vertices[k, 1] + dz * vertices[k, 2]
            if s > top:
                top, pick, moved = s, k, True
    return pick


@jit.kernel(_nrt=False, inline="always")
def _pair_bound(a_vertices, a_start, a_stop, a_first, a_next, rot, trans, i, b_vertices,
                b_start, b_stop, b_first, b_next, hint, w, enough):
    """(certified lower bound of the distance between hull(a_vertices[a_start:a_stop]),
    posed by draw i's rot (3, 3) and trans (3,), and hull(b_vertices[b_start:b_stop]), and
    the unit normal (x, y, z) of the plane that gives it: every point x of A - B has
    n . x >= the bound); -inf (and a zero normal) where they touch or overlap (the module's
    iteration). ``a_first``, ``a_next``, ``b_first``, ``b_next``: the parts' hull edges
    (:func:`stacked_points`), along which each support is walked from the last. ``hint``
    (2,) int64: the rows of A and B whose difference starts the iteration (the last
    supports of the pair's previous bound; outside the parts: their first rows), set to
    this bound's last supports. The iteration stops as soon as its bound exceeds ``enough``
    (metres; inf: to full precision), the bound then only certifying that much."""
    r = rot[i]
    pick = hint[0] if a_start <= hint[0] < a_stop else a_start
    other = hint[1] if b_start <= hint[1] < b_stop else b_start
    ax, ay, az = a_vertices[pick, 0], a_vertices[pick, 1], a_vertices[pick, 2]
    vx = r[0, 0] * ax + r[0, 1] * ay + r[0, 2] * az + trans[i, 0] - b_vertices[other, 0]
    vy = r[1, 0] * ax + r[1, 1] * ay + r[1, 2] * az + trans[i, 1] - b_vertices[other, 1]
    vz = r[2, 0] * ax + r[2, 1] * ay + r[2, 2] * az + trans[i, 2] - b_vertices[other, 2]
    w[0, 0], w[0, 1], w[0, 2] = vx, vy, vz
    m = 1
    lower, nx, ny, nz = -np.inf, 0.0, 0.0, 0.0
    previous = np.inf
    for _ in range(MAX_ITER):
        vv = vx * vx + vy * vy + vz * vz
        if vv == 0.0:
            return -np.inf, 0.0, 0.0, 0.0
        # support of posed A along -v: the vertex maximising (-v) . (R a), i.e. (-R^T v) . a
        dx = -(r[0, 0] * vx + r[1, 0] * vy + r[2, 0] * vz)
        dy = -(r[0, 1] * vx + r[1, 1] * vy + r[2, 1] * vz)
        dz = -(r[0, 2] * vx + r[1, 2] * vy + r[2, 2] * vz)
        pick = _support(a_vertices, a_start, a_stop, a_first, a_next, dx, dy, dz, pick)
        ax, ay, az = a_vertices[pick, 0], a_vertices[pick, 1], a_vertices[pick, 2]
        other = _support(b_vertices, b_start, b_stop, b_first, b_next, vx, vy, vz, other)
        hint[0], hint[1] = pick, other
        wx = r[0, 0] * ax + r[0, 1] * ay + r[0, 2] * az + trans[i, 0] - b_vertices[other, 0]
        wy = r[1, 0] * ax + r[1, 1] * ay + r[1, 2] * az + trans[i, 1] - b_vertices[other, 1]
        wz = r[2, 0] * ax + r[2, 1] * ay + r[2, 2] * az + trans[i, 2] - b_vertices[other, 2]
        vw = vx * wx + vy * wy + vz * wz
        norm = np.sqrt(vv)
        if vw / norm > lower:  # the plane through w normal to v separates
            lower, nx, ny, nz = vw / norm, vx / norm, vy / norm, vz / norm
        if vv - vw <= GAP_REL * vv or not vv < previous or lower > enough:
            break
        previous = vv
        w[m, 0], w[m, 1], w[m, 2] = wx, wy, wz
        vx, vy, vz, m = _reduce(w, m + 1)
        if m == 4:
            return -np.inf, 0.0, 0.0, 0.0
    if lower > 0.0:
        return lower, nx, ny, nz
    return -np.inf, 0.0, 0.0, 0.0


@jit.kernel(_nrt=False, inline="always")
def _sphere_gap(a_spheres, p, rot, trans, i, b_spheres, q):
    """A lower bound (metres) of the distance between part p of A, posed by (rot[i],
    trans[i]), and part q of B: their bounding spheres' gap."""
    r = rot[i]
    cx, cy, cz = a_spheres[p, 0], a_spheres[p, 1], a_spheres[p, 2]
    dx = r[0, 0] * cx + r[0, 1] * cy + r[0, 2] * cz + trans[i, 0] - b_spheres[q, 0]
    dy = r[1, 0] * cx + r[1, 1] * cy + r[1, 2] * cz + trans[i, 1] - b_spheres[q, 1]
    dz = r[2, 0] * cx + r[2, 1] * cy + r[2, 2] * cz + trans[i, 2] - b_spheres[q, 2]
    return np.sqrt(dx * dx + dy * dy + dz * dz) - a_spheres[p, 3] - b_spheres[q, 3]


@jit.kernel(_nrt=False)
def hull_distance_bounds(a_vertices, a_starts, a_spheres, a_first, a_next, rot, trans,
                         b_vertices, b_starts, b_spheres, b_first, b_next, motion, short,
                         hints, w, out, travel, enough):
    """Per draw i: a certified lower bound out[i] (metres; -inf where some pair touches or
    overlaps) of the least distance between the convex parts of A (part p: the hull of
    a_vertices[a_starts[p]:a_starts[p + 1]] (V, 3), its frame posed by rot[i] (n, 3, 3),
    trans[i] (n, 3)) and those of B (b_vertices (U, 3) split by b_starts). Where ``motion``
    (n, 3) is given (its rows: a displacement of A per unit of a parameter, object frame;
    zero rows: none given), travel[i] is how far in that parameter A can be translated along
    motion[i] before any pair's separating plane lets it come within ``short`` (metres) of B
    (inf where no plane stands in its way; 0 where a pair is that near already), else 0
    (nothing certified). ``a_first``, ``a_next`` and ``b_first``, ``b_next``: each part's
    hull edges (:func:`stacked_points`, whose layout A and B both take). ``hints`` (n, P Q,
    2) int64: where draw i's bound of parts p, q starts (row p Q + q: :func:`new_hints`),
    left where it ended; a bound started at the last one's end (the draw a little moved)
    needs few iterations. ``w`` (4, 3) is scratch (:func:`new_simplex`). ``enough``
    (metres): a pair's iteration stops once its bound exceeds it (inf: every bound to full
    precision; a finite one for a question whose answer is settled above it, such as "do
    the parts overlap?", whose answer no earlier stop changes: a pair's bound only grows as
    its iteration goes on).

    Without a motion, a pair whose bounding spheres (``a_spheres`` (P, 4), ``b_spheres``
    (Q, 4): :func:`hull_spheres`) are farther apart than the least bound found is not
    examined (it cannot lower it), and each part of A meets its sphere-nearest part of B
    first."""
    for i in range(rot.shape[0]):
        mx, my, mz = motion[i, 0], motion[i, 1], motion[i, 2]
        moving = mx != 0.0 or my != 0.0 or mz != 0.0
        best, far = np.inf, (np.inf if moving else 0.0)
        for p in range(a_starts.shape[0] - 1):
            first, nearest = 0, np.inf
            if not moving:
                for q in range(b_starts.shape[0] - 1):
                    gap = _sphere_gap(a_spheres, p, rot, trans, i, b_spheres, q)
                    if gap < nearest:
                        first, nearest = q, gap
            for rank in range(b_starts.shape[0] - 1):
                q = first if rank == 0 else (rank - 1 if rank <= first else rank)
                if not moving and rank > 0 and not (
                        _sphere_gap(a_spheres, p, rot, trans, i, b_spheres, q) < best):
                    continue
                bound, nx, ny, nz = _pair_bound(a_vertices, a_starts[p], a_starts[p + 1],
                                                a_first, a_next, rot, trans, i, b_vertices,
                                                b_starts[q], b_starts[q + 1], b_first,
                                                b_next, hints[i, p * (b_starts.shape[0] - 1)
                                                              + q], w, enough)
                best = min(best, bound)
                if moving:  # the plane n . x >= bound moves by (n . motion) per unit
                    closing = -(nx * mx + ny * my + nz * mz)
                    if not bound > short:
                        far = 0.0
                    elif closing > 0.0:
                        far = min(far, (bound - short) / closing)
        out[i] = best
        travel[i] = far
