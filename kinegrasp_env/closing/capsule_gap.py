"""Gap between capsules and an object, from its distance grid: the fast engine's hot loop.

gap(capsule) = min over the axis segment [a, b] of sdf(x) - radius. The distance is sampled
at :data:`SAMPLES` evenly spaced points; since sdf is 1-Lipschitz, the minimum over the
segment is at least (smallest sample) - (half the sample spacing). When that bound exceeds
:data:`NEAR` it is returned (a lower bound: all that conservative advancement needs);
otherwise the minimum is refined by golden-section search over the two sample intervals
around the smallest sample, then over every other interval whose Lipschitz bound
(v_j + v_j+1 - spacing) / 2 is still below the best value found (:data:`REFINE` steps each:
the minimum located to 0.5 mm of a 10 cm link, its value within 0.27 mm where the distance
has a kink and far closer where it is flat at its minimum). The value only sizes the
conservative steps and decides whether a gap is within the band where the exact distance
is computed (1 mm, against a contact tolerance of 0.2 mm): every contact decision is exact.
14 steps (0.03 mm) gave the same contacts found on 9,600 draws of the four objects, points
within 7.4e-10 m, at more closing time for no gain (measured when the constant was chosen).

One compiled loop over the capsules (:func:`capsule_gaps`); the grid is read by
:func:`trilinear`, also behind a link's bounding-ball screen (:func:`posed_min_distance`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.world.sdf import DistanceGrid

#: Samples along a capsule's axis.
SAMPLES = 9
#: Gaps (lower bounds) above this are not refined (metres).
NEAR = 2e-3
#: Golden-section steps of the refinement.
REFINE = 8
GOLD = 0.5 * (np.sqrt(5.0) - 1.0)


@jit.kernel(_nrt=False, inline="always")
def trilinear(values, shape, origin, spacing, x, y, z):
    nx, ny, nz = shape[0], shape[1], shape[2]
    inv = 1.0 / spacing  # one division, hoisted out of the callers' loops once inlined
    rx = (x - origin[0]) * inv
    ry = (y - origin[1]) * inv
    rz = (z - origin[2]) * inv
    cx = min(max(rx, 0.0), nx - 1.0)
    cy = min(max(ry, 0.0), ny - 1.0)
    cz = min(max(rz, 0.0), nz - 1.0)
    dx, dy, dz = rx - cx, ry - cy, rz - cz
    outside = 0.0  # what the square root gives inside the grid, without computing it
    if dx != 0.0 or dy != 0.0 or dz != 0.0:
        outside = np.sqrt(dx * dx + dy * dy + dz * dz) * spacing
    ix = min(int(cx), nx - 2)
    iy = min(int(cy), ny - 2)
    iz = min(int(cz), nz - 2)
    fx, fy, fz = cx - ix, cy - iy, cz - iz
    flat = (ix * ny + iy) * nz + iz
    step = ny * nz
    c000 = values[flat]
    c001 = values[flat + 1]
    c010 = values[flat + nz]
    c011 = values[flat + nz + 1]
    c100 = values[flat + step]
    c101 = values[flat + step + 1]
    c110 = values[flat + step + nz]
    c111 = values[flat + step + nz + 1]
    c00 = c000 + (c001 - c000) * fz
    c01 = c010 + (c011 - c010) * fz
    c10 = c100 + (c101 - c100) * fz
    c11 = c110 + (c111 - c110) * fz
    c0 = c00 + (c01 - c00) * fy
    c1 = c10 + (c11 - c10) * fy
    return c0 + (c1 - c0) * fx + outside

@jit.kernel(_nrt=False, inline="always")
def golden(values, shape, origin, spacing, ax, ay, az, bx, by, bz, lo, hi, best, s,
           refine, gold):
    x1 = hi - gold * (hi - lo)
    x2 = lo + gold * (hi - lo)
    f1 = trilinear(values, shape, origin, spacing, ax + x1 * bx, ay + x1 * by, az + x1 * bz)
    f2 = trilinear(values, shape, origin, spacing, ax + x2 * bx, ay + x2 * by, az + x2 * bz)
    for _ in range(refine):
        if f1 < f2:
            hi = x2
            x2, f2 = x1, f1
            x1 = hi - gold * (hi - lo)
            f1 = trilinear(values, shape, origin, spacing, ax + x1 * bx, ay + x1 * by,
                           az + x1 * bz)
        else:
            lo = x1
            x1, f1 = x2, f2
            x2 = lo + gold * (hi - lo)
            f2 = trilinear(values, shape, origin, spacing, ax + x2 * bx, ay + x2 * by,
                           az + x2 * bz)
    refined = min(f1, f2)
    where = x1 if f1 < f2 else x2
    if refined < best:
        return refined, where
    return best, s

@jit.kernel(_nrt=False)
def gap_one(values, shape, origin, spacing, ax, ay, az, ex, ey, ez, radius, samples, near,
            refine, gold, sample):
    """(gap, s) of one capsule with axis [a, e] and radius; sample: (samples,) buffer."""
    bx, by, bz = ex - ax, ey - ay, ez - az
    best = np.inf
    kbest = 0
    for k in range(samples):
        f = k / (samples - 1)
        v = trilinear(values, shape, origin, spacing, ax + f * bx, ay + f * by, az + f * bz)
        sample[k] = v
        if v < best:
            best = v
            kbest = k
    s = kbest / (samples - 1)
    half = 0.5 * np.sqrt(bx * bx + by * by + bz * bz) / (samples - 1)
    gap = best - half - radius
    if gap <= near:
        step = 1.0 / (samples - 1)
        best, s = golden(values, shape, origin, spacing, ax, ay, az, bx, by, bz,
                         max(s - step, 0.0), min(s + step, 1.0), best, s, refine, gold)
        for j in range(samples - 1):
            bound = 0.5 * (sample[j] + sample[j + 1] - 2.0 * half)
            if bound < best:
                best, s = golden(values, shape, origin, spacing, ax, ay, az, bx, by, bz,
                                 j * step, (j + 1) * step, best, s, refine, gold)
        gap = best - radius
    return gap, s

@jit.kernel
def gaps(values, shape, origin, spacing, a, b, radius, samples, near, refine, gold,
         out_gap, out_s):
    sample = np.empty(samples)
    for i in range(a.shape[0]):
        out_gap[i], out_s[i] = gap_one(values, shape, origin, spacing, a[i, 0], a[i, 1],
                                       a[i, 2], b[i, 0], b[i, 1], b[i, 2], radius[i],
                                       samples, near, refine, gold, sample)

@jit.kernel(_nrt=False, inline="always")
def posed_min_one(values, shape, origin, spacing, rot, trans, local, low, high):
    """Smallest grid distance over points local[low:high] (3,) placed by rot (3, 3) and
    trans (3,)."""
    best = np.inf
    for p in range(low, high):
        lx, ly, lz = local[p, 0], local[p, 1], local[p, 2]
        x = rot[0, 0] * lx + rot[0, 1] * ly + rot[0, 2] * lz + trans[0]
        y = rot[1, 0] * lx + rot[1, 1] * ly + rot[1, 2] * lz + trans[1]
        z = rot[2, 0] * lx + rot[2, 1] * ly + rot[2, 2] * lz + trans[2]
        v = trilinear(values, shape, origin, spacing, x, y, z)
        if v < best:
            best = v
    return best

@jit.kernel(_nrt=False)
def posed_min(values, shape, origin, spacing, rot, trans, local, out):
    for i in range(rot.shape[0]):
        out[i] = posed_min_one(values, shape, origin, spacing, rot[i], trans[i], local, 0,
                               local.shape[0])

@jit.kernel(_nrt=False)
def posed_centres(values, shape, origin, spacing, rot, trans, centres, out):
    for k in range(rot.shape[0]):
        for i in range(rot.shape[1]):
            out[k, i] = posed_min_one(values, shape, origin, spacing, rot[k, i], trans[k, i],
                                      centres, k, k + 1)

def grid_arrays(grid: DistanceGrid) -> tuple:
    """The grid as the kernels take it: flat values, shape, origin, spacing."""
    return (grid.values.reshape(-1), np.array(grid.shape, dtype=np.int64), grid.origin,
            float(grid.spacing))


def posed_min_distance(grid: DistanceGrid, poses: np.ndarray, local: np.ndarray) -> np.ndarray:
    """Smallest grid distance (n,) over points ``local`` (P, 3) placed by each pose (n, 4, 4)
    (metres, object frame)."""
    poses = np.asarray(poses, dtype=float)
    out = np.empty(poses.shape[0])
    posed_min(*grid_arrays(grid), np.ascontiguousarray(poses[:, :3, :3]),
              np.ascontiguousarray(poses[:, :3, 3]), np.ascontiguousarray(local, dtype=float),
              out)
    return out


def centre_distances(grid: DistanceGrid, poses: np.ndarray, centres: np.ndarray
                     ) -> np.ndarray:
    """(L, n) grid distance of each of L links' points ``centres`` (L, 3) (link frames)
    placed by that link's poses (L, n, 4, 4) (metres, object frame): the distance of every
    draw's bounding-ball centre of every link in one call."""
    poses = np.asarray(poses, dtype=float)
    out = np.empty(poses.shape[:2])
    posed_centres(*grid_arrays(grid), np.ascontiguousarray(poses[..., :3, :3]),
                  np.ascontiguousarray(poses[..., :3, 3]),
                  np.ascontiguousarray(centres, dtype=float), out)
    return out


def capsule_gaps(grid: DistanceGrid, a: np.ndarray, b: np.ndarray, radius: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Gaps of m capsules (first call compiles, then cached).

    Args:
        grid: the object's distance grid (object frame).
        a, b: (m, 3) axis end points, object frame, metres.
        radius: (m,) capsule radii, metres.

    Returns:
        (gap (m,), s (m,)): the gap (metres; a lower bound when above ``NEAR``) and where on
        the axis it is attained (0 at a, 1 at b).
    """
    m = a.shape[0]
    gap, s = np.empty(m), np.empty(m)
    gaps(*grid_arrays(grid), np.ascontiguousarray(a, dtype=float),
         np.ascontiguousarray(b, dtype=float), np.ascontiguousarray(radius, dtype=float),
         SAMPLES, NEAR, REFINE, GOLD, gap, s)
    return gap, s


def sampled_bounds(grid: DistanceGrid, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(m,) the smallest grid distance over :data:`SAMPLES` points of each segment [a, b]
    ((m, 3) each, object frame) less half their spacing, unrefined: a lower bound of the
    grid's distance along the whole segment (the exact distance's, less the grid's own
    error: :func:`~kinegrasp_env.closing.link_geometry.grid_error`)."""
    m = a.shape[0]
    gap, s = np.empty(m), np.empty(m)
    gaps(*grid_arrays(grid), np.ascontiguousarray(a, dtype=float),
         np.ascontiguousarray(b, dtype=float), np.zeros(m), SAMPLES, -np.inf, REFINE, GOLD,
         gap, s)
    return gap
