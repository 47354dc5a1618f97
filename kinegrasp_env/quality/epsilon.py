"""Ferrari-Canny quality and force closure (conventions: docs/conventions.md).

Cones and wrenches are built by :mod:`kinegrasp_env.quality.wrenches`.

* Q (L1, "epsilon") = distance from the origin to the nearest facet of the convex hull of
  all edge wrenches if the origin is strictly inside it (force closure), else 0; a
  rank-deficient wrench set is not in force closure.

Three exact paths compute Q: ``method="qhull"`` (the reference: ``scipy.spatial.ConvexHull``,
:mod:`kinegrasp_env.quality.qhull_quality`);
with the L1 norm and at most ``expansion.MAX_POINTS`` wrenches, first a certified
nearest-facet-first expansion (:mod:`kinegrasp_env.quality.expansion`, the fastest exact
path: far cheaper than qhull, as it builds only the facets needed to certify the nearest one;
timings in benchmarks/bench_quality.py); for 3 contacts with
:data:`TABLES_MIN_EDGES` <= m <= :data:`TABLES_MAX_EDGES` cone edges, the grasps the expansion
does not certify (or all of them, past its size) go to the batched facet enumeration of
:mod:`kinegrasp_env.quality.three_contacts`, after a phase-1 screen that settles those
certified out of force closure (Q = 0 on every path; the screen is cheap next to the
tables). ``"auto"``
and ``"fast"`` (3 contacts only) fall back to qhull wherever an exact path cannot certify its
answer, after a second try of the expansion on the set with every wrench moved by at most
:data:`JOGGLE` of its scale (:func:`joggled_quality`: a certified Q of the moved set is the
set's to within sqrt(6) x JOGGLE of the wrench scale); ``"auto"`` also for the L-infinity
hull. The cone edges are bounded by
``wrenches.MAX_EDGES``.
"""

from __future__ import annotations

import threading
from functools import lru_cache
from typing import Literal

import numpy as np

from kinegrasp_env.quality.qhull_quality import (
    linf_points,
    qhull_epsilon,
    qhull_hull,
    rank_deficient,
)
from kinegrasp_env.quality.wrenches import (
    BARELY_CLOSED,
    FC_TOL,
    MAX_EDGES,
    NOT_CLOSED,
    check_contacts,
    check_parameters,
    check_wrenches,
    closure_class,
    closure_classes,
    cone_angles,
    edge_wrenches,
    scale_center,
    wrench_matrix,
)

Method = Literal["auto", "fast", "qhull"]
Norm = Literal["l1", "linf"]
#: Cone edges m the three-contact tables serve: where they were the cheapest batched path
#: against the expansion with its qhull fallback and against qhull (at m = 3 the expansion
#: was cheaper; at 4 and 16 the two tied; at 24, 3 m beyond the expansion, only the tables
#: and qhull apply; timings in benchmarks/bench_quality_edges.py). Their constant tables and
#: work arrays grow as m^3 (numpy peak 30 MB at m = 8, 96 MB at 24, 217 MB at 32), so above
#: 24 qhull serves (~10 MB per grasp at m = 32). Since its per-facet work was cut the
#: expansion is the cheaper one at every m (same benchmark, sphere contacts and engine
#: draws), so it serves first and the tables take what it cannot certify and the 3-contact
#: sets past its size (m = 22-24).
TABLES_MIN_EDGES = 4
TABLES_MAX_EDGES = 24
#: The expansion's second try at a set it could not certify (the wrenches of flat pads lie
#: by fours on common planes, whose thin facets a step can fail to cone): every wrench moved
#: by at most this fraction of the wrench scale in each coordinate, by a fixed pattern
#: (:func:`joggled_quality`). The hulls of the two sets lie within sqrt(6) x JOGGLE x the
#: scale of each other, and so do their Q.
JOGGLE = 1e-9
#: ... whose certified Q is taken where it is above this fraction of the wrench scale (the
#: force-closure verdict then that of the set itself); else qhull decides.
JOGGLE_FLOOR = 1e-6
def uses_tables(num_contacts: int, num_edges: int, friction: float, norm: str) -> bool:
    """True when ``auto``/``fast`` give these grasps to the three-contact tables when the
    expansion does not certify them (every one, past the expansion's size).

    Not for friction <= FC_TOL: three contacts with a cone that narrow are within FC_TOL of
    three points, Q = 0 however it is computed, and the tables' basis is singular (0 / 0
    for a subnormal mu)."""
    return (norm == "l1" and num_contacts == 3 and friction > FC_TOL
            and TABLES_MIN_EDGES <= num_edges <= TABLES_MAX_EDGES)


# ----------------------------------------------------------------------------- public API
def ferrari_canny_batch(points, normals, *, friction: float | np.ndarray = 0.5,
                        num_edges: int = 8,
                        torque_scale=1.0, center=(0.0, 0.0, 0.0), method: Method = "auto",
                        norm: Norm = "l1") -> np.ndarray:
    """Ferrari-Canny quality of B grasps.

    Args:
        points: (B, k, 3) contact points (metres, object frame); B may be 0.
        normals: (B, k, 3) inward contact normals.
        friction: Coulomb friction coefficient mu >= 0: a scalar, or (B,) one per grasp
            (the exact paths take it through the wrenches; the three-contact tables serve
            when every mu > 0).
        num_edges: edges m of the linearized friction cone, 3 <= m <= ``MAX_EDGES`` (32).
        torque_scale: scalar or (B,) torque scale s (1 / metres), > 0.
        center: (3,) or (B, 3) centre of mass the torques are taken about.
        method: ``auto``, ``fast`` (3 contacts, L1 only) or ``qhull`` (the reference).
        norm: ``l1`` (convex hull of the edge wrenches) or ``linf`` (Minkowski sum).

    Returns:
        (B,) Q >= 0; 0 where the grasp is not in force closure.
    """
    points, normals = check_contacts(points, normals, batched=True)
    rows_mu = None
    if np.ndim(friction) > 0:  # one mu per grasp; the checks below see the smallest
        rows_mu = row_friction(friction, points.shape[0])
        friction = float(rows_mu.min()) if rows_mu.size else 0.5
    friction, num_edges = check_parameters(friction, num_edges)
    if method not in ("auto", "fast", "qhull"):
        raise ValueError(f"unknown method {method!r}; choose auto, fast or qhull")
    if norm not in ("l1", "linf"):
        raise ValueError(f"unknown norm {norm!r}; choose l1 or linf")
    batch, k = points.shape[:2]
    scale, ctr = scale_center(torque_scale, center, batch)
    if method == "fast" and not (norm == "l1" and k == 3 and friction > 0):
        raise ValueError("the fast path needs 3 contacts, friction > 0 and the L1 norm; "
                         f"got {k} contacts, friction {friction}, norm {norm}")
    out = np.empty(batch)
    if batch == 0:
        return out
    cone = friction if rows_mu is None else rows_mu[:, None, None, None]
    w = check_wrenches(edge_wrenches(points, normals, cone, num_edges, scale, ctr))
    return exact_quality(w, k, num_edges, friction, norm, method)


def exact_quality(w: np.ndarray, k: int, num_edges: int, friction: float, norm: Norm,
                  method: Method) -> np.ndarray:
    """(B,) Q of B grasps' edge wrenches w (B, k m, 6) through the exact paths in their order
    (the expansion, the three-contact tables, the expansion on the moved sets, qhull; see the
    module docstring); ``friction``: the smallest mu of the batch."""
    from kinegrasp_env.quality.expansion import MAX_POINTS, epsilon_epa_batch

    out = np.empty(w.shape[0])
    todo = np.arange(w.shape[0])
    if norm == "l1" and method != "qhull" and w.shape[1] <= MAX_POINTS:
        # the certified expansion first: the fastest exact path wherever it fits (3 x 8:
        # 39 us per engine draw, the tables 72)
        q, certified = epsilon_epa_batch(np.ascontiguousarray(w))
        rows = np.flatnonzero(certified)
        out[rows] = thresholded_batch(q[rows], w[rows])
        todo = todo[~certified]
    if method != "qhull" and todo.size and uses_tables(k, num_edges, friction, norm):
        from kinegrasp_env.quality.expansion import outside_batch
        from kinegrasp_env.quality.three_contacts import epsilon_three_contacts

        # grasps certified out of force closure (3-8 us each) have Q = 0 on the tables too:
        # only the rest pay for them (~100 us per grasp at m = 8)
        outside = outside_batch(np.ascontiguousarray(w[todo]))
        out[todo[outside]] = 0.0
        todo = todo[~outside]
        q, certified = epsilon_three_contacts(w[todo], num_edges)
        out[todo[certified]] = q[certified]
        todo = todo[~certified]
    if todo.size and norm == "l1" and method != "qhull" and w.shape[1] <= MAX_POINTS:
        # what is left for qhull (~20 ms a set of 64): the expansion once more on the sets
        # moved by a hair
        q, taken = joggled_quality(w[todo])
        out[todo[taken]] = q[taken]
        todo = todo[~taken]
    for b in todo:
        out[b] = qhull_epsilon(w[b], k, norm)
    return out


@lru_cache(maxsize=1)
def _joggle_pattern() -> np.ndarray:
    """(MAX_POINTS, 6) the fixed moves of :func:`joggled_quality`, in [-1, 1]."""
    from kinegrasp_env.quality.expansion import MAX_POINTS

    pattern = np.random.default_rng(0x10661E).uniform(-1.0, 1.0, (MAX_POINTS, 6))
    pattern.setflags(write=False)
    return pattern


def joggled_quality(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Q (B,), taken (B,) bool) of wrench sets w (B, N, 6), N <= ``MAX_POINTS``, by the
    certified expansion on the sets with every wrench moved by at most :data:`JOGGLE` x its
    set's scale (max |w|) per coordinate (a fixed pattern, the same for every set). A set's
    Q is within e = sqrt(6) x JOGGLE x scale of the moved set's (the hulls are within that
    Hausdorff distance), so a certified Q of the moved set above :data:`JOGGLE_FLOOR` x
    scale (>> e) is taken: the set is in force closure, its Q that one to within e (the
    qhull path's own merging tolerance is of that order). Elsewhere ``taken`` is False."""
    from kinegrasp_env.quality.expansion import epsilon_epa_batch

    scale = np.abs(w).max(axis=(1, 2))
    moved = w + JOGGLE * scale[:, None, None] * _joggle_pattern()[:w.shape[1]]
    q, certified = epsilon_epa_batch(np.ascontiguousarray(moved))
    return q, certified & (q > JOGGLE_FLOOR * scale)


@lru_cache(maxsize=8)
def prepare_exact_paths(num_edges: int) -> None:
    """Build the three-contact tables of ``num_edges``-edge cones and load the compiled
    kernels of :func:`exact_quality`'s rarer paths, once per process: what a scorer that is
    kept (an engine a worker holds) would otherwise pay on the first grasp that needs them
    (~30 ms), in the middle of a run."""
    from kinegrasp_env.quality.expansion import outside_batch
    from kinegrasp_env.quality.three_contacts import epsilon_three_contacts

    w = np.random.default_rng(0).standard_normal((1, 3 * num_edges, 6))
    outside_batch(w)
    epsilon_three_contacts(w, num_edges)


def thresholded(q: float, w: np.ndarray) -> float:
    """An exact path's Q of wrenches w (N, 6) under the force-closure rule
    (:func:`~kinegrasp_env.quality.wrenches.closure_class` on the wrench scale max |w|): 0
    below FC_TOL of the scale, and 0 for a barely positive Q of a (numerically)
    rank-deficient set."""
    closure = closure_class(q, float(np.abs(w).max()))
    if closure == NOT_CLOSED or (closure == BARELY_CLOSED and rank_deficient(w)):
        return 0.0
    return float(q)


def thresholded_batch(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """:func:`thresholded` of B grasps at once (the rule in one compiled pass, so a batch pays
    no Python loop over its draws): Q (B,) of wrenches w (B, N, 6) -> (B,)."""
    scale = np.abs(w).max(axis=(1, 2)) if w.shape[0] else np.empty(0)
    closure = closure_classes(np.ascontiguousarray(q, dtype=float), scale)
    out = np.where(closure == NOT_CLOSED, 0.0, q)
    for i in np.flatnonzero(closure == BARELY_CLOSED):  # rare: barely positive
        if rank_deficient(w[i]):
            out[i] = 0.0
    return out


_TABLES = threading.local()


def _expansion_tables() -> tuple:
    """This thread's polytope and ridge tables for the expansion and its wrench scratch
    (~2 MB, allocated on its first single-grasp call and reused: allocating them per call
    was a sizeable share of a single-grasp call)."""
    tables = getattr(_TABLES, "value", None)
    if tables is None:
        from kinegrasp_env.quality.expansion import new_polytope, new_ridges
        from kinegrasp_env.quality.single import new_wrench_buffer

        tables = _TABLES.value = (new_polytope(), new_ridges(), new_wrench_buffer())
    return tables


def single_l1(w: np.ndarray, num_contacts: int) -> float:
    """Q of one grasp's wrenches w (N, 6), L1: the certified expansion (cheap for one grasp,
    where the three-contact tables pay their whole batch set-up), else qhull."""
    from kinegrasp_env.quality.expansion import MAX_POINTS, expand_from, screen

    if num_contacts <= 2:  # every wrench has zero moment about the line through the points
        return 0.0
    if w.shape[0] <= MAX_POINTS:
        w = np.ascontiguousarray(w)
        # phase 1 alone where it settles the set (no tables passed), else the expansion in
        # this thread's tables
        start, q, certified = screen(w)
        if start[0] >= 0:
            poly, ridges, _ = _expansion_tables()
            q, certified = expand_from(w, start, poly, ridges)
        if certified:
            return thresholded(q, w)
    return qhull_epsilon(w, num_contacts, "l1")


#: Python number types the one-call path takes as they are (bool is not one of them).
_PLAIN_NUMBERS = (float, int, np.float64)


@lru_cache(maxsize=1)
def _single_module():
    """:mod:`kinegrasp_env.quality.single`, imported on first use (as the other compiled
    paths are)."""
    from kinegrasp_env.quality import single

    return single


def compiled_single(points, normals, friction, num_edges, torque_scale, center,
                    gamma: float = 0.0) -> float | None:
    """Q of one grasp through :func:`~kinegrasp_env.quality.single.single_epsilon` (one
    compiled call: the checks, the wrenches, the expansion) for the common input: float64
    C-ordered (k, 3) arrays, numbers (float, int, numpy float64), a centre of 3 numbers or a
    float64 (3,) array, k m <= the expansion's size; qhull where the expansion cannot
    certify; ``gamma`` > 0 (metres): soft fingers with that torsional coefficient. None for
    anything else, or an input its checks reject: the step-by-step path then computes it,
    or words the error. (Its checks are a few type and shape tests: the step-by-step path's
    call overhead was a large share of a 3-contact call.)"""
    if type(center) is np.ndarray:
        if center.shape != (3,) or center.dtype != np.float64:
            return None
    elif type(center) not in (tuple, list) or len(center) != 3:
        return None
    center_x, center_y, center_z = center
    single = _single_module()
    torsion_rows = 2 if gamma > 0.0 else 0  # a soft contact's two torsional primitives
    if not (type(points) is np.ndarray and type(normals) is np.ndarray
            and points.dtype == np.float64 and normals.dtype == np.float64
            and points.ndim == 2 and points.shape == normals.shape and points.shape[1] == 3
            and points.shape[0] >= 1 and points.flags.c_contiguous
            and normals.flags.c_contiguous
            and type(num_edges) is int and 3 <= num_edges <= MAX_EDGES
            and points.shape[0] * (num_edges + torsion_rows) <= single.MAX_POINTS
            and type(friction) in _PLAIN_NUMBERS and type(torque_scale) in _PLAIN_NUMBERS
            and type(center_x) in _PLAIN_NUMBERS and type(center_y) in _PLAIN_NUMBERS
            and type(center_z) in _PLAIN_NUMBERS):
        return None
    try:  # an int beyond a float's range: the step-by-step checks word the error
        mu, scale = float(friction), float(torque_scale)
        center = (float(center_x), float(center_y), float(center_z))
    except OverflowError:
        return None
    poly, ridges, w = _expansion_tables()
    cos_t, sin_t = cone_angles(num_edges)
    status, q = single.single_epsilon(points, normals, mu, cos_t, sin_t, scale, *center,
                                       float(gamma), w, poly, ridges)
    if status == single.DONE:
        return q
    rows = w[:points.shape[0] * (num_edges + torsion_rows)]
    if status == single.CHECK_RANK:
        return 0.0 if rank_deficient(rows) else q
    if status == single.NOT_CERTIFIED:
        return qhull_epsilon(rows.copy(), points.shape[0], "l1")
    return None


def row_friction(friction, batch: int) -> np.ndarray:
    """A per-grasp friction as a float (B,) array (ValueError for another shape)."""
    mu = np.asarray(friction, dtype=float)
    if mu.shape != (batch,):
        raise ValueError(f"friction must be a scalar or have shape ({batch},) (one per "
                         f"grasp), got shape {mu.shape}")
    if not np.all(np.isfinite(mu)) or np.any(mu < 0):
        bad = int(np.flatnonzero(~(np.isfinite(mu) & (mu >= 0)))[0])
        raise ValueError(f"friction must be finite and >= 0, got friction[{bad}] = {mu[bad]}")
    return mu


def ferrari_canny(points, normals, *, friction: float = 0.5, num_edges: int = 8,
                  torque_scale: float = 1.0, center=(0.0, 0.0, 0.0), method: Method = "auto",
                  norm: Norm = "l1") -> float:
    """Ferrari-Canny quality Q of one grasp; points and normals are (k, 3).

    See :func:`ferrari_canny_batch` for the arguments. With ``method="auto"`` and the L1 norm
    one grasp goes straight to the certified expansion (qhull where it cannot certify): for
    plain input (float64 arrays, numbers, a centre of 3 numbers) in one compiled call
    (:mod:`kinegrasp_env.quality.single`; timings in benchmarks/bench_quality.py), not
    through the batch path's three-contact tables, whose set-up a batch of one pays whole (far
    slower for one grasp): for 3 contacts it may differ from ``ferrari_canny_batch`` in the
    last digits (both equal qhull to 1e-10). Raises ValueError for non-finite input,
    mismatched shapes or zero-length normals.
    """
    if method == "auto" and norm == "l1":
        q = compiled_single(points, normals, friction, num_edges, torque_scale, center)
        if q is not None:
            return q
    points, normals = check_contacts(points, normals, batched=False)
    if method != "auto" or norm != "l1" or np.ndim(friction) > 0:
        return float(ferrari_canny_batch(points[None], normals[None], friction=friction,
                                         num_edges=num_edges, torque_scale=torque_scale,
                                         center=center, method=method, norm=norm)[0])
    friction, num_edges = check_parameters(friction, num_edges)
    scale, ctr = scale_center(torque_scale, center, 1)
    w = check_wrenches(edge_wrenches(points[None], normals[None], friction, num_edges, scale,
                                     ctr))[0]
    return single_l1(w, points.shape[0])


def is_force_closure_batch(points, normals, **kwargs) -> np.ndarray:
    """(B,) bool: origin strictly inside the grasp wrench space (Q > 0)."""
    return ferrari_canny_batch(points, normals, **kwargs) > 0.0


def is_force_closure(points, normals, **kwargs) -> bool:
    """True when the grasp (k, 3) is in force closure."""
    return ferrari_canny(points, normals, **kwargs) > 0.0


def grasp_wrench_space_volume(points, normals, *, friction: float = 0.5, num_edges: int = 8,
                              torque_scale: float = 1.0, center=(0.0, 0.0, 0.0),
                              norm: Norm = "l1") -> float:
    """6-D volume of the grasp wrench space (0 when rank-deficient), as GraspIt reports."""
    w = wrench_matrix(points, normals, friction=friction, num_edges=num_edges,
                      torque_scale=torque_scale, center=center)
    pts = linf_points(w, np.shape(points)[0]) if norm == "linf" else w
    hull = qhull_hull(pts)
    return 0.0 if hull is None else float(hull.volume)
