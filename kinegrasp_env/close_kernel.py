"""The fast engine's auto-close as one compiled loop (the twin of FastHand's vectorized one).

:meth:`kinegrasp_env.hand_fast.FastHand.close` advances every (draw, finger) closing problem
with array operations, one iteration at a time: ~35 iterations x 3 fingers of a few dozen
numpy calls each, a fixed cost that dominates small batches (the environment's 64 draws).
Here each problem runs its whole state machine in one compiled loop, calling the same
per-row kernels (:func:`kinegrasp_env.capsule_gap` ``gap_one``,
:mod:`kinegrasp_env.segment_distance` ``segment_one``,
:func:`kinegrasp_env.finger_axes.axes_one`) with the same arithmetic in the same order, so
the closing state, the contacts found and their closest pairs are bit-identical to the
vectorized loop with numba kernels (tested). ``benchmarks/bench_env.py`` times both.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import capsule_gap, hand, segment_distance
from kinegrasp_env.finger_axes import axes_one
from kinegrasp_env.polytope import INSIDE_TOL

#: Entries of a stored closest pair: distance, point on the object (3), point on the
#: segment (3), part index.
PAIR_SIZE = 8


def _compile():
    import numba

    gap_one = capsule_gap._kernels()[2]
    segment_one = segment_distance.kernels()[1]

    @numba.njit(cache=True)
    def exact_pair(geo, a, e, bounds, out):
        """Exact closest pair of segment [a, e] (3,) and the object into out (PAIR_SIZE,)."""
        planes, plane_start, edges, edge_start, scale, mid, half, tol = geo
        d, ox, oy, oz, sx, sy, sz, part = segment_one(planes, plane_start, edges, edge_start,
                                                      scale, mid, half, a[0], a[1], a[2], e[0],
                                                      e[1], e[2], bounds, tol)
        out[0], out[1], out[2], out[3], out[4], out[5], out[6] = d, ox, oy, oz, sx, sy, sz
        out[7] = part
        return d

    @numba.njit(cache=True)
    def link_gap(grid, geo, a, e, radius, sample, bounds, pair):
        """Gap of a capsule: the grid's, exact within the band of contact."""
        values, shape, origin, spacing, samples, near, refine, gold, band = grid
        gap, _ = gap_one(values, shape, origin, spacing, a[0], a[1], a[2], e[0], e[1], e[2],
                         radius, samples, near, refine, gold, sample)
        if abs(gap) <= band:
            gap = exact_pair(geo, a, e, bounds, pair) - radius
        return gap

    @numba.njit(cache=True)
    def flexions(phase, t, start_p, start_d, upper_p, upper_d):
        prox = min(start_p + (t if phase == 1 else 0.0), upper_p)
        return prox, min(start_d + t, upper_d)

    @numba.njit(cache=True)
    def t_limit(phase, start_p, start_d, upper_p, upper_d):
        if phase == 1:
            return max(max(upper_p - start_p, upper_d - start_d), 0.0)
        return max(upper_d - start_d, 0.0)

    @numba.njit(cache=True)
    def exact_gap(geo, phase, t, start_p, start_d, up_p, up_d, joint_frame, axis_p,
                  distal_origin, axis_d, ends_p, ends_d, r_p, r_d, rot, frame_p, frame_d, tmp,
                  ends, bounds, pair):
        """Smallest exact gap of the finger's moving links at parameter t; their closest
        pairs in pair (2, PAIR_SIZE) (row 0 untouched in phase 2)."""
        prox, dist = flexions(phase, t, start_p, start_d, up_p, up_d)
        axes_one(joint_frame, axis_p, prox, distal_origin, axis_d, dist, ends_p, ends_d, rot,
                 frame_p, frame_d, tmp, ends)
        gap_p = np.inf
        if phase == 1:
            gap_p = exact_pair(geo, ends[0], ends[1], bounds, pair[0]) - r_p
        gap_d = exact_pair(geo, ends[2], ends[3], bounds, pair[1]) - r_d
        return min(gap_p, gap_d)

    @numba.njit(cache=True)
    def close_all(grid, geo, rules, joint_frames, prox0, dist0, axis_p, axis_d, distal_origin,
                  ends_p, ends_d, radius, upper, speed, found, pairs, missed):
        """Close every finger of every draw.

        rules: :func:`closing_rules`; joint_frames (m, 3, 4, 4), prox0 / dist0 (m, 3): per
        draw and finger; the finger constants are stacked over fingers. Writes found (m, 3,
        2), pairs (m, 3, 2, PAIR_SIZE), missed (m, 3); returns the most iterations any
        problem took.
        """
        (CONTACT_TOL, STEP, QUERY_DISTANCE, POLISH_TOL, POLISH_PROBE, POLISH_RANGE,
         POLISH_ITERATIONS, MAX_ITERATIONS) = rules
        sample = np.empty(grid[4])
        bounds = np.empty(geo[1].shape[0] - 1)
        rot, tmp = np.empty((3, 3)), np.empty((3, 3))
        frame_p, frame_d = np.empty((3, 4)), np.empty((3, 4))
        ends = np.empty((4, 3))
        pair = np.empty((2, PAIR_SIZE))
        scratch = np.empty(PAIR_SIZE)
        most = 0
        for i in range(prox0.shape[0]):
            for f in range(3):
                up_p, up_d = upper[f, 0], upper[f, 1]
                r_p, r_d = radius[f, 0], radius[f, 1]
                start_p, start_d = min(prox0[i, f], up_p), min(dist0[i, f], up_d)
                phase = 1
                t, t_lo, t_hi = 0.0, 0.0, np.nan
                active, has_contact = True, False
                it = 0
                while active and it < MAX_ITERATIONS:
                    it += 1
                    prox, dist = flexions(phase, t, start_p, start_d, up_p, up_d)
                    axes_one(joint_frames[i, f], axis_p[f], prox, distal_origin[f], axis_d[f],
                             dist, ends_p[f], ends_d[f], rot, frame_p, frame_d, tmp, ends)
                    gap_d = link_gap(grid, geo, ends[2], ends[3], r_d, sample, bounds, scratch)
                    gap_p = np.inf
                    if phase == 1:
                        gap_p = link_gap(grid, geo, ends[0], ends[1], r_p, sample, bounds,
                                         scratch)
                    gap_p = min(gap_p, QUERY_DISTANCE)
                    gap_d = min(gap_d, QUERY_DISTANCE)
                    if phase != 1:
                        gap_p = np.inf
                    gap = min(gap_p, gap_d)
                    bracket_closed = not np.isnan(t_hi) and t_hi - t_lo < 1e-9
                    touch = ((-CONTACT_TOL <= gap <= CONTACT_TOL)
                             or (bracket_closed and gap <= CONTACT_TOL))
                    if touch:
                        # polish to the root of the exact gap (hand.secant_root)
                        t_max = t_limit(phase, start_p, start_d, up_p, up_d)
                        t_min = max(t - POLISH_RANGE, 0.0)
                        t0 = max(t - POLISH_PROBE, t_min)
                        polishing = t0 < t and abs(gap) > POLISH_TOL
                        g0 = 0.0
                        if polishing:
                            g0 = exact_gap(geo, phase, t0, start_p, start_d, up_p, up_d,
                                           joint_frames[i, f], axis_p[f], distal_origin[f],
                                           axis_d[f], ends_p[f], ends_d[f], r_p, r_d, rot,
                                           frame_p, frame_d, tmp, ends, bounds, pair)
                        t1, g1 = t, gap
                        best_t, best_g = t1, abs(g1)
                        for _ in range(POLISH_ITERATIONS):
                            polishing = polishing and g1 != g0
                            if not polishing:
                                break
                            t2 = min(max(t1 - g1 * (t1 - t0) / (g1 - g0), t_min), t_max)
                            g2 = exact_gap(geo, phase, t2, start_p, start_d, up_p, up_d,
                                           joint_frames[i, f], axis_p[f], distal_origin[f],
                                           axis_d[f], ends_p[f], ends_d[f], r_p, r_d, rot,
                                           frame_p, frame_d, tmp, ends, bounds, pair)
                            t0, g0, t1, g1 = t1, g1, t2, g2
                            if abs(g2) < best_g:
                                best_t, best_g = t2, abs(g2)
                            polishing = polishing and best_g > POLISH_TOL
                        t = best_t
                        # the links touching there, and their closest pairs
                        prox_t, dist_t = flexions(phase, t, start_p, start_d, up_p, up_d)
                        exact_gap(geo, phase, t, start_p, start_d, up_p, up_d,
                                  joint_frames[i, f], axis_p[f], distal_origin[f], axis_d[f],
                                  ends_p[f], ends_d[f], r_p, r_d, rot, frame_p, frame_d, tmp,
                                  ends, bounds, pair)
                        link_gaps = (pair[0, 0] - r_p if phase == 1 else np.inf,
                                     pair[1, 0] - r_d)
                        for link in range(2):
                            if link_gaps[link] <= CONTACT_TOL:
                                found[i, f, link] = True
                                pairs[i, f, link] = pair[link]
                                has_contact = True
                        if link_gaps[1] <= CONTACT_TOL:
                            active = False
                        else:  # proximal contact only: freeze it, the distal joint goes on
                            start_p, start_d = prox_t, dist_t
                            phase = 2
                            t_lo, t_hi = 0.0, np.nan
                            t_max = t_limit(phase, start_p, start_d, up_p, up_d)
                            if t_max <= 0.0:
                                active = False
                                t = 0.0
                            else:
                                t = min(STEP, t_max)
                    elif gap > CONTACT_TOL:
                        if np.isnan(t_hi):  # conservative step towards contact
                            t_max = t_limit(phase, start_p, start_d, up_p, up_d)
                            t_lo = t
                            if t >= t_max:
                                active = False
                                missed[i, f] = not has_contact
                            else:
                                step = max(gap / (speed[0] if phase == 1 else speed[1]), STEP)
                                t = min(t + step, t_max)
                        else:  # bisection, below the bracket
                            t_lo = t
                            t = 0.5 * (t + t_hi)
                    else:  # penetrating: bisection, above the bracket
                        t_hi = t
                        t = 0.5 * (t_lo + t)
                most = max(most, it)
        return most

    return close_all


_KERNEL = None


def close_kernel():
    """The compiled closing loop, built on first use (cached on disk by numba)."""
    global _KERNEL
    if _KERNEL is None:
        _KERNEL = _compile()
    return _KERNEL


def closing_rules() -> tuple:
    """The auto-close constants of :mod:`kinegrasp_env.hand`, passed to the kernel as an
    argument (numba's disk cache would keep the values of module globals of another file
    even after they change)."""
    return (float(hand.CONTACT_TOL), float(hand.STEP), float(hand.QUERY_DISTANCE),
            float(hand.POLISH_TOL), float(hand.POLISH_PROBE), float(hand.POLISH_RANGE),
            int(hand.POLISH_ITERATIONS), int(hand.MAX_ITERATIONS))


def grid_args(grid, band: float) -> tuple:
    """The distance grid, the capsule-gap constants and the band (metres) within which gaps
    are computed exactly, as the kernel's ``grid`` tuple."""
    return (grid.values.reshape(-1), np.array(grid.shape, dtype=np.int64), grid.origin,
            float(grid.spacing), capsule_gap.SAMPLES, capsule_gap.NEAR, capsule_gap.REFINE,
            float(capsule_gap._GOLD), float(band))


def geometry_args(name: str) -> tuple:
    """The object's packed parts as the kernel's ``geo`` tuple."""
    geo = segment_distance.packed(name)
    return (geo.planes, geo.plane_start, geo.edges, geo.edge_start, geo.scale, geo.edge_mid,
            geo.edge_half, INSIDE_TOL)
