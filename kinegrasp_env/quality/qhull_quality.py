"""The Ferrari-Canny quality by qhull, the reference path of :mod:`kinegrasp_env.quality.
epsilon`: the convex hull of a grasp's edge wrenches (``scipy.spatial.ConvexHull``), under
the options qhull accepts, its points merged where they nearly coincide, and the Minkowski-
sum points of the L-infinity hull.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from scipy.spatial import ConvexHull

from kinegrasp_env.quality.wrenches import NOT_CLOSED, RANK_TOL, closure_class

__all__ = ["LINF_MAX_POINTS", "MERGE_TOL", "QHULL_OPTIONS", "first_hull", "hull_epsilon",
           "linf_points", "merge_close", "qhull_epsilon", "qhull_hull", "rank_deficient"]

#: Largest number (m + 1)^k of Minkowski-sum points the L-infinity hull is built from. The
#: hull's qhull time and memory grow steeply with the points (one grasp: 50 MB for 729 points
#: (3 contacts, m = 8), 77-98 MB for 1,296-1,331, 170-190 MB for 2,197-4,096, 400 MB for
#: 4,913; timings in benchmarks/bench_quality_edges.py, section 3).
LINF_MAX_POINTS = 1500
#: Qhull options tried in turn: scipy's default, then merging pinched vertices and allowing
#: wide merges (qhull's own advice when nearly coincident wrenches make it stop with a
#: "wide merge" topology error on a set in force closure).
QHULL_OPTIONS = (None, "Qx Q12 Q14")
#: Wrenches closer than this fraction of the wrench scale (max |w|; Euclidean distance in 6-D)
#: are merged into one before qhull is tried again, where it declines a set under every
#: option (found by Hypothesis: coincident or 1e-12-apart contacts, whose identical wrenches
#: make qhull stop with a topology error on a set in force closure). Moving each point by at
#: most d changes every support value, hence Q, by at most d: the merged hull's Q is within
#: MERGE_TOL of the wrench scale of the unmerged one's.
MERGE_TOL = 1e-11


def rank_deficient(w: np.ndarray) -> bool:
    """True when the affine hull of the points (N >= 7, 6) has dimension below 6."""
    sv = np.linalg.svd(w - w.mean(axis=0), compute_uv=False)
    return bool(sv[-1] <= RANK_TOL * max(sv[0], 1e-300))


def merge_close(points: np.ndarray, tol: float) -> np.ndarray:
    """The points (N, d) with each one closer than ``tol`` (Euclidean) to an earlier kept
    point dropped: (M, d), M <= N, every dropped point within tol of a kept one."""
    kept = [0] if len(points) else []
    for i in range(1, len(points)):
        if np.min(np.linalg.norm(points[kept] - points[i], axis=1)) > tol:
            kept.append(i)
    return points[kept]


def first_hull(points: np.ndarray) -> ConvexHull | None:
    """Qhull hull of (N, 6) points under the first option of :data:`QHULL_OPTIONS` qhull
    accepts, or None when it declines them all."""
    from scipy.spatial import ConvexHull, QhullError

    for options in QHULL_OPTIONS:
        try:
            return ConvexHull(points, qhull_options=options)
        except QhullError:
            continue
    return None


def qhull_hull(points: np.ndarray) -> ConvexHull | None:
    """Qhull hull of (N, 6) points, or None when they are (numerically) rank-deficient or
    qhull declines them with every option of :data:`QHULL_OPTIONS`, also after merging the
    points within :data:`MERGE_TOL` of the wrench scale of each other."""
    if points.shape[0] < 7 or rank_deficient(points):
        return None
    hull = first_hull(points)
    if hull is None:
        merged = merge_close(points, MERGE_TOL * float(np.abs(points).max()))
        if 7 <= len(merged) < len(points):
            hull = first_hull(merged)
    return hull


def hull_epsilon(hull: ConvexHull | None, scale: float) -> float:
    """Q of a qhull hull of wrenches of scale ``scale`` (0 without a hull, or where the
    origin is not inside by the closure rule)."""
    if hull is None:
        return 0.0
    offsets = hull.equations[:, -1]  # unit outward normals: n . x + offset <= 0 inside
    q = float(-offsets.max())
    return 0.0 if closure_class(q, scale) == NOT_CLOSED else q


def linf_points(w: np.ndarray, num_contacts: int) -> np.ndarray:
    """Minkowski-sum points (P, 6) of the per-contact sets {0} U {edge wrenches}."""
    per_contact = w.reshape(num_contacts, -1, 6)
    count = (per_contact.shape[1] + 1) ** num_contacts
    if count > LINF_MAX_POINTS:
        raise ValueError(f"the L-infinity hull would need {count} points (more than "
                         f"{LINF_MAX_POINTS}); use fewer contacts or edges")
    total = np.zeros((1, 6))
    for block in per_contact:
        options = np.vstack([np.zeros((1, 6)), block])
        total = (total[:, None, :] + options[None, :, :]).reshape(-1, 6)
    return total


def qhull_epsilon(w: np.ndarray, num_contacts: int, norm: str) -> float:
    """Q of one grasp's edge wrenches w (N, 6) of ``num_contacts`` contacts by qhull, in
    the L1 norm or the L-infinity one (``norm``: ``l1`` or ``linf``)."""
    pts = linf_points(w, num_contacts) if norm == "linf" else w
    scale = float(np.abs(pts).max()) if pts.size else 1.0
    return hull_epsilon(qhull_hull(pts), scale)


