"""Friction cones and grasp wrenches (the pinned conventions of docs/conventions.md).

* contact normals point into the object, unit length (other lengths are normalized; zero
  length is an error);
* tangent basis of normal n: a = the coordinate axis with the smallest |n_i| (lowest index on
  ties), t1 = normalize(n x a), t2 = n x t1;
* friction cone edges f_j = n + mu (cos(2 pi j / m) t1 + sin(2 pi j / m) t2), j = 0..m-1;
* wrench of an edge at contact point p: w = (f, s (p - c) x f), s the torque scale (1 / r_max,
  1/metres), c the centre of mass (metres).

Also the rules every quality path shares, each defined once as a compiled function that the
kernels call and the numpy side calls too: the input checks (:func:`all_finite`,
:func:`normal_long_enough`, :func:`wrench_size_ok`) and the force-closure threshold on Q
(:func:`closure_class`).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from kinegrasp_env import jit

#: Relative tolerance (to the wrench scale) below which Q counts as zero (origin on the hull).
FC_TOL = 1e-12
#: Singular-value ratio below which a wrench set counts as rank-deficient.
RANK_TOL = 1e-10
#: Most cone edges m accepted. Every grasp can fall back to qhull, whose time and memory
#: grow steeply with the number of wrenches (one grasp of 6 contacts: 26 MB at m = 24, 50 MB
#: at m = 32, 127 MB at m = 48; timings in benchmarks/bench_quality_edges.py): 32 keeps one
#: grasp's fallback affordable.
MAX_EDGES = 32
#: The library's friction coefficient mu and cone edges m where none is given
#: (docs/conventions.md).
DEFAULT_FRICTION, DEFAULT_NUM_EDGES = 0.5, 8
#: Largest |wrench coordinate| accepted (torques are torque_scale * |p - c| * |f|; the hull
#: computations square coordinates, and 1e154 squared overflows).
MAX_WRENCH = 1e100
#: Shortest contact normal accepted (its length before normalization).
MIN_NORMAL_LENGTH = 1e-12
#: Relative Q (to the wrench scale) below which a positive Q is "barely positive": the grasp
#: is in force closure only if its wrenches span 6-D (the caller's rank check decides).
BARELY_POSITIVE = 1e-8

#: :func:`closure_class` results: Q counts as 0 (not in force closure) ...
NOT_CLOSED = 0
#: ... Q is barely positive: 0 if the wrench set is rank-deficient, else Q ...
BARELY_CLOSED = 1
#: ... Q stands (force closure).
CLOSED = 2


# ----------------------------------------------------------------------------- the rules
@jit.kernel
def closure_class(q, scale):
    """The force-closure rule on a Q (float) of wrenches whose largest |coordinate| is scale:
    :data:`NOT_CLOSED` unless q > FC_TOL * scale (also for NaN), :data:`BARELY_CLOSED` for
    q < BARELY_POSITIVE * scale, else :data:`CLOSED`. Every quality path applies it."""
    if not q > FC_TOL * scale:
        return NOT_CLOSED
    if q < BARELY_POSITIVE * scale:
        return BARELY_CLOSED
    return CLOSED


@jit.kernel
def closure_classes(q, scale):
    """:func:`closure_class` of B values: q, scale (B,) -> (B,) int8."""
    out = np.empty(q.shape[0], dtype=np.int8)
    for i in range(q.shape[0]):
        out[i] = closure_class(q[i], scale[i])
    return out


@jit.kernel(_nrt=False)
def all_finite(values):
    """Whether every entry of an array (any shape) is finite (the contact and parameter
    checks' rule)."""
    for v in values.flat:
        if not np.isfinite(v):
            return False
    return True


@jit.kernel
def normal_long_enough(length):
    """Whether a contact normal of this length (metres-free, before normalization) is
    accepted: length >= :data:`MIN_NORMAL_LENGTH` (False for NaN)."""
    return length >= MIN_NORMAL_LENGTH


@jit.kernel(_nrt=False)
def first_short_normal(lengths):
    """Index of the first normal length (N,) that :func:`normal_long_enough` rejects, or -1."""
    for i in range(lengths.shape[0]):
        if not normal_long_enough(lengths[i]):
            return i
    return -1


@jit.kernel
def wrench_size_ok(size):
    """Whether a |wrench coordinate| is accepted: size <= :data:`MAX_WRENCH` (False for NaN
    and inf)."""
    return size <= MAX_WRENCH


# ----------------------------------------------------------------------------- validation
def finite_array(value, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except OverflowError:  # a Python int beyond a float's range
        raise ValueError(f"{name} contains a number beyond a float's range") from None
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers, got {value!r}") from None
    if not all_finite(arr.reshape(-1)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return arr


def normal_lengths(normals: np.ndarray) -> np.ndarray:
    """Euclidean lengths (...,) of vectors (..., 3), also where squaring would overflow."""
    with np.errstate(over="ignore"):
        lengths = np.linalg.norm(normals, axis=-1)
    huge = np.isinf(lengths)  # finite entries above ~1e154
    if huge.any():
        peak = np.abs(normals[huge]).max(axis=-1)
        with np.errstate(over="ignore"):  # inf where the length itself exceeds ~1.8e308
            lengths[huge] = peak * np.linalg.norm(normals[huge] / peak[:, None], axis=-1)
    return lengths


@jit.kernel(_nrt=False)
def unit_normals_into(points, normals, out):
    """Whether every entry of points (N, 3) is finite (:func:`all_finite`) and every normal's
    length (N normals (N, 3); np.linalg.norm's arithmetic: sqrt((x x + y y) + z z)) is finite
    and :func:`normal_long_enough` (a NaN entry gives a NaN length); where so, the unit
    normals (normals / lengths) are in out (N, 3)."""
    if not all_finite(points):
        return False
    for i in range(normals.shape[0]):
        x, y, z = normals[i, 0], normals[i, 1], normals[i, 2]
        length = np.sqrt(x * x + y * y + z * z)
        if not np.isfinite(length) or not normal_long_enough(length):
            return False
        out[i, 0], out[i, 1], out[i, 2] = x / length, y / length, z / length
    return True


def _plain_contacts(points, normals, batched: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`check_contacts`'s result in one compiled pass for the common input (float64
    C-ordered arrays of the right shapes, finite, normals neither tiny nor huge); None for
    anything else, which the full checks then handle (and word the error of)."""
    want = 3 if batched else 2
    if not (type(points) is np.ndarray and type(normals) is np.ndarray
            and points.dtype == np.float64 and normals.dtype == np.float64
            and points.ndim == want and points.shape == normals.shape
            and points.shape[-1] == 3 and points.shape[-2] >= 1
            and points.flags.c_contiguous and normals.flags.c_contiguous):
        return None
    unit = np.empty_like(normals)
    if not unit_normals_into(points.reshape(-1, 3), normals.reshape(-1, 3),
                             unit.reshape(-1, 3)):
        return None
    return points, unit


def check_contacts(points, normals, batched: bool) -> tuple[np.ndarray, np.ndarray]:
    plain = _plain_contacts(points, normals, batched)
    if plain is not None:
        return plain
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
    first = first_short_normal(lengths.reshape(-1))
    if first >= 0:
        bad = np.unravel_index(first, lengths.shape)
        raise ValueError(f"normals: contact {tuple(int(i) for i in bad)} has zero length "
                         f"(below {MIN_NORMAL_LENGTH:g}: {lengths[bad]:.3g})")
    unit = normals / lengths[..., None]
    huge = np.isinf(lengths)  # a length beyond a float's range (entries near 1.8e308)
    if huge.any():
        scaled = normals[huge] / np.abs(normals[huge]).max(axis=-1, keepdims=True)
        unit[huge] = scaled / np.linalg.norm(scaled, axis=-1, keepdims=True)
    return points, unit


def check_wrenches(w: np.ndarray) -> np.ndarray:
    """w unchanged; ValueError when a torque overflows or exceeds :data:`MAX_WRENCH` (the
    hull computations square coordinates), i.e. torque_scale * |p - c| is absurdly large."""
    peak = float(np.abs(w).max()) if w.size else 0.0
    if not wrench_size_ok(peak):
        raise ValueError(f"the torques reach {peak:.3g} (torque_scale * |points - center|); "
                         f"at most {MAX_WRENCH:g} is supported: use metres and "
                         "torque_scale = 1 / r_max")
    return w


def check_parameters(friction: float, num_edges: int) -> tuple[float, int]:
    """(friction, num_edges) as (float, int); ValueError unless friction is a finite number
    >= 0 and num_edges an integer in [3, MAX_EDGES] (integral floats are accepted)."""
    try:
        value = float(friction)
    except OverflowError:  # a Python int beyond a float's range
        raise ValueError("friction must be finite and >= 0, got an integer beyond a float's "
                         "range") from None
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
    if arr.shape == shape:  # one grasp: a reshaped view (broadcast_to costs 5 us)
        return arr.reshape(1, *shape) if batch == 1 else np.broadcast_to(arr, (batch, *shape))
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


def edge_wrenches(points: np.ndarray, normals: np.ndarray, friction, num_edges: int,
                  torque_scale: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(B, k * m, 6) wrenches; points/normals (B, k, 3) (unit normals), friction a scalar
    or one mu per grasp ((B,) or (B, 1, 1, 1)), torque_scale (B,), center (B, 3). The same
    numbers as :func:`friction_cone_edges` and ``np.cross`` give, in one compiled pass.
    Torques that overflow come out non-finite, silently: see :func:`check_wrenches`."""
    batch, k = points.shape[:2]
    mu = np.asarray(friction, dtype=float).reshape(-1)
    if mu.shape[0] != batch:  # one scalar for every grasp
        mu = np.repeat(mu, batch)
    cos_t, sin_t = cone_angles(num_edges)
    out = np.empty((batch, k * num_edges, 6))
    wrenches_into(np.ascontiguousarray(points, dtype=float),
                  np.ascontiguousarray(normals, dtype=float), mu, cos_t, sin_t,
                  np.ascontiguousarray(torque_scale, dtype=float),
                  np.ascontiguousarray(center, dtype=float), out)
    return out


@lru_cache(maxsize=64)  # m <= MAX_EDGES
def cone_angles(num_edges: int) -> tuple[np.ndarray, np.ndarray]:
    """(cos, sin) (m,) of the edge angles 2 pi j / m, as :func:`friction_cone_edges` takes
    them (read-only; cached, so a one-grasp call does not pay for the trigonometry)."""
    theta = 2.0 * np.pi * np.arange(num_edges) / num_edges
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    cos_t.flags.writeable = sin_t.flags.writeable = False
    return cos_t, sin_t


@jit.kernel
def _cross(a0, a1, a2, b0, b1, b2):
    """a x b, term by term as ``np.cross`` computes it."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@jit.kernel
def wrenches_into(points, normals, mu, cos_t, sin_t, torque_scale, center, out) -> None:
    """Edge wrenches into out (B, k m, 6) (see :func:`edge_wrenches`: points, unit normals
    (B, k, 3), mu and torque_scale (B,), center (B, 3); cos_t, sin_t (m,) from
    :func:`cone_angles`)."""
    m = cos_t.shape[0]
    for b in range(points.shape[0]):
        for i in range(points.shape[1]):
            n0, n1, n2 = normals[b, i, 0], normals[b, i, 1], normals[b, i, 2]
            h = np.zeros(3)  # the axis of the smallest |n_c|, lowest index on ties
            axis = 0
            for c in range(1, 3):
                if abs(normals[b, i, c]) < abs(normals[b, i, axis]):
                    axis = c
            h[axis] = 1.0
            u0, u1, u2 = _cross(n0, n1, n2, h[0], h[1], h[2])
            length = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
            u0, u1, u2 = u0 / length, u1 / length, u2 / length
            v0, v1, v2 = _cross(n0, n1, n2, u0, u1, u2)
            s = torque_scale[b]
            l0 = (points[b, i, 0] - center[b, 0]) * s
            l1 = (points[b, i, 1] - center[b, 1]) * s
            l2 = (points[b, i, 2] - center[b, 2]) * s
            for j in range(m):
                c, t = cos_t[j], sin_t[j]
                f0 = n0 + mu[b] * (c * u0 + t * v0)
                f1 = n1 + mu[b] * (c * u1 + t * v1)
                f2 = n2 + mu[b] * (c * u2 + t * v2)
                row = out[b, i * m + j]
                row[0], row[1], row[2] = f0, f1, f2
                row[3], row[4], row[5] = _cross(l0, l1, l2, f0, f1, f2)


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
    if type(torque_scale) is float and math.isfinite(torque_scale) and torque_scale > 0 \
            and type(center) in (tuple, list) and len(center) == 3 \
            and all(type(c) is float and math.isfinite(c) for c in center):
        # the common call (a float and a 3-tuple of floats), without numpy's checks: the
        # arrays per_row makes of them (3 us of a single grasp's ~30)
        row = np.array(center).reshape(1, 3)
        return (np.full(batch, torque_scale),
                row if batch == 1 else np.broadcast_to(row, (batch, 3)))
    scale = per_row(torque_scale, batch, (), "torque_scale")
    if (scale <= 0).any():
        raise ValueError(f"torque_scale must be > 0, got {np.min(scale)!r}")
    return scale, per_row(center, batch, (3,), "center")
