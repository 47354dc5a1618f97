"""Friction cones and grasp wrenches (the pinned conventions of docs/conventions.md).

* contact normals point into the object, unit length (other lengths are normalized; zero
  length is an error);
* tangent basis of normal n: a = the coordinate axis with the smallest |n_i| (lowest index on
  ties), t1 = normalize(n x a), t2 = n x t1;
* friction cone edges f_j = n + mu (cos(2 pi j / m) t1 + sin(2 pi j / m) t2), j = 0..m-1;
* wrench of an edge at contact point p: w = (f, s (p - c) x f), s the torque scale (1 / r_max,
  1/metres), c the centre of mass (metres).

Also the input checks every quality path shares, and the force-closure tolerance.
"""

from __future__ import annotations

import math

import numpy as np

#: Relative tolerance (to the wrench scale) below which Q counts as zero (origin on the hull).
FC_TOL = 1e-12
#: Singular-value ratio below which a wrench set counts as rank-deficient.
RANK_TOL = 1e-10
#: Most cone edges m accepted. Every grasp can fall back to qhull, whose cost grows steeply
#: with the number of wrenches: one grasp of 6 contacts (benchmarks/bench_quality_edges.py,
#: CPU time of one core, two runs) takes 0.20 s and 26 MB at m = 24, 0.55-0.68 s and 50 MB
#: at m = 32, 1.2-1.6 s at m = 40, 2.4-3.0 s and 127 MB at m = 48; 32 keeps it under ~1 s.
MAX_EDGES = 32
#: Largest |wrench coordinate| accepted (torques are torque_scale * |p - c| * |f|; the hull
#: computations square coordinates, and 1e154 squared overflows).
MAX_WRENCH = 1e100


# ----------------------------------------------------------------------------- validation
def finite_array(value, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers, got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return arr


def normal_lengths(normals: np.ndarray) -> np.ndarray:
    """Euclidean lengths (...,) of vectors (..., 3), also where squaring would overflow."""
    with np.errstate(over="ignore"):
        lengths = np.linalg.norm(normals, axis=-1)
    huge = np.isinf(lengths)  # finite entries above ~1e154
    if np.any(huge):
        peak = np.abs(normals[huge]).max(axis=-1)
        lengths[huge] = peak * np.linalg.norm(normals[huge] / peak[:, None], axis=-1)
    return lengths


def check_contacts(points, normals, batched: bool) -> tuple[np.ndarray, np.ndarray]:
    points = finite_array(points, "points")
    normals = finite_array(normals, "normals")
    want = 3 if batched else 2
    shape_text = "(B, k, 3)" if batched else "(k, 3)"
    for name, arr in (("points", points), ("normals", normals)):
        if arr.ndim != want or arr.shape[-1] != 3:
            raise ValueError(f"{name} must have shape {shape_text}, got {arr.shape}")
    if points.shape != normals.shape:
        raise ValueError(f"points {points.shape} and normals {normals.shape} differ in shape")
    if points.shape[-2] < 1:
        raise ValueError("need at least one contact, got 0")
    lengths = normal_lengths(normals)
    if np.any(lengths < 1e-12):
        bad = np.argwhere(lengths < 1e-12)[0]
        raise ValueError(f"normals: contact {tuple(int(i) for i in bad)} has zero length "
                         f"(below 1e-12: {lengths[tuple(bad)]:.3g})")
    return points, normals / lengths[..., None]


def check_wrenches(w: np.ndarray) -> np.ndarray:
    """w unchanged; ValueError when a torque overflows or exceeds :data:`MAX_WRENCH` (the
    hull computations square coordinates), i.e. torque_scale * |p - c| is absurdly large."""
    peak = float(np.abs(w).max()) if w.size else 0.0
    if not peak <= MAX_WRENCH:  # also NaN / inf
        raise ValueError(f"the torques reach {peak:.3g} (torque_scale * |points - center|); "
                         f"at most {MAX_WRENCH:g} is supported: use metres and "
                         "torque_scale = 1 / r_max")
    return w


def check_parameters(friction: float, num_edges: int) -> tuple[float, int]:
    """(friction, num_edges) as (float, int); ValueError unless friction is a finite number
    >= 0 and num_edges an integer in [3, MAX_EDGES] (integral floats are accepted)."""
    try:
        value = float(friction)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"friction must be finite and >= 0, got {friction!r}")
    try:
        whole = bool(int(num_edges) == num_edges)
    except (TypeError, ValueError, OverflowError):
        whole = False
    if not whole or not 3 <= int(num_edges) <= MAX_EDGES:
        raise ValueError(f"num_edges must be an integer >= 3 and <= {MAX_EDGES} (the cost of "
                         f"the exact hull grows steeply with it), got {num_edges!r}")
    return value, int(num_edges)


def per_row(value, batch: int, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = finite_array(value, name)
    if arr.shape == shape:
        return np.broadcast_to(arr, (batch, *shape))
    if arr.shape == (batch, *shape):
        return arr
    raise ValueError(f"{name} must have shape {shape} or {(batch, *shape)}, got {arr.shape}")


# ----------------------------------------------------------------------------- cones, wrenches
def tangent_basis(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangents (t1, t2), each (..., 3), of unit normals (..., 3) (docs/conventions.md)."""
    n = np.asarray(normals, dtype=float)
    axis = np.argmin(np.abs(n), axis=-1)  # lowest index on ties
    helper = np.zeros_like(n)
    np.put_along_axis(helper, axis[..., None], 1.0, axis=-1)
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=-1, keepdims=True)
    return t1, np.cross(n, t1)


def friction_cone_edges(normals: np.ndarray, friction: float = 0.5,
                        num_edges: int = 8) -> np.ndarray:
    """Linearized friction cone edges (..., m, 3) of unit normals (..., 3).

    f_j = n + mu (cos(2 pi j/m) t1 + sin(2 pi j/m) t2): the normal component is 1.
    """
    n = np.asarray(normals, dtype=float)
    t1, t2 = tangent_basis(n)
    theta = 2.0 * np.pi * np.arange(num_edges) / num_edges
    return (n[..., None, :] + friction * (np.cos(theta)[:, None] * t1[..., None, :]
                                          + np.sin(theta)[:, None] * t2[..., None, :]))


def edge_wrenches(points: np.ndarray, normals: np.ndarray, friction: float, num_edges: int,
              torque_scale: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(B, k * m, 6) wrenches; points/normals (B, k, 3), torque_scale (B,), center (B, 3).
    Torques that overflow come out non-finite, silently: see :func:`check_wrenches`."""
    edges = friction_cone_edges(normals, friction, num_edges)  # (B, k, m, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        lever = (points - center[:, None, :]) * torque_scale[:, None, None]
        torques = np.cross(lever[:, :, None, :], edges)
    w = np.concatenate([edges, torques], axis=-1)
    return w.reshape(w.shape[0], w.shape[1] * num_edges, 6)  # explicit: B may be 0


def wrench_matrix(points, normals, *, friction: float = 0.5, num_edges: int = 8,
                  torque_scale=1.0, center=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Edge wrenches of a grasp: (k * m, 6) for (k, 3) inputs, (B, k * m, 6) for (B, k, 3).

    Row ``i * m + j`` is edge j of contact i: (force (3), torque_scale * (p_i - c) x force).
    """
    batched = np.ndim(points) == 3
    points, normals = check_contacts(points, normals, batched)
    friction, num_edges = check_parameters(friction, num_edges)
    p, n = (points, normals) if batched else (points[None], normals[None])
    scale, ctr = scale_center(torque_scale, center, p.shape[0])
    w = check_wrenches(edge_wrenches(p, n, friction, num_edges, scale, ctr))
    return w if batched else w[0]


def scale_center(torque_scale, center, batch: int) -> tuple[np.ndarray, np.ndarray]:
    scale = per_row(torque_scale, batch, (), "torque_scale")
    if np.any(scale <= 0):
        raise ValueError(f"torque_scale must be > 0, got {np.min(scale)!r}")
    return scale, per_row(center, batch, (3,), "center")
