"""The fast engine's closing loop as array operations (``FastHand(closing="vectorized")``).

The rule of :mod:`kinegrasp_env.closing.reference` (conservative steps of at least ``STEP``,
bisection to ``CONTACT_TOL``, a proximal contact freezes the proximal joint, a distal contact
ends the finger), run for every (draw, finger) closing problem at once: one iteration advances
all active problems of a finger with array operations. The same results as the compiled loop
(:mod:`kinegrasp_env.closing.close_kernel`), bit for bit; the hand's geometry and gaps come
from the hand that calls it (:class:`ClosingHand`, met by
:class:`~kinegrasp_env.closing.fast.FastHand`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from kinegrasp_env.closing.close_rules import (
    CONTACT_TOL,
    MAX_ITERATIONS,
    POLISH_ITERATIONS,
    POLISH_PROBE,
    POLISH_RANGE,
    POLISH_TOL,
    QUERY_DISTANCE,
    STEP,
    LinkSpeeds,
)
from kinegrasp_env.closing.hand_geometry import Shape, pair_contacts
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.world.objects import GraspObject

__all__ = ["ClosedFingers", "ClosingHand", "close_problems"]


class ClosingHand(Protocol):
    """What the closing loop reads of the hand.

    Attributes:
        obj: the object (placed at ``obj.pose``).
        capsules: per finger its (proximal, distal) capsules.
        upper: (3, 2) upper limits of each finger's (proximal, distal) joint, radians.
        speed: :func:`~kinegrasp_env.closing.close_rules.closing_speeds`.
    """

    obj: GraspObject
    capsules: list[list[Shape]]
    upper: np.ndarray
    speed: LinkSpeeds

    def link_axes(self, joint_frames: np.ndarray, finger: int, prox: np.ndarray,
                  dist: np.ndarray) -> np.ndarray:
        """Axis ends (m, 4, 3) [proximal a, b, distal a, b] for flexions prox, dist (m,)."""

    def grid_or_exact_gaps(self, a: np.ndarray, b: np.ndarray, radius: float | np.ndarray
                           ) -> np.ndarray:
        """Gaps (m,) of capsules with axis ends a, b (m, 3) and radius (a float, or (m,)
        metres): exact near contact, from the grid elsewhere."""


@dataclass
class ClosedFingers:
    """Closing results of the three fingers of m draws.

    Attributes:
        found: (m, 3, 2) bool: a contact on (finger, link).
        points, normals: (m, 3, 2, 3) contacts in the object frame (NaN where not found).
        missed: (m, 3) bool per finger.
        flexion: (m, 3, 2) closed (proximal, distal) flexion of each finger, radians.
        iterations: closing iterations used.
    """

    found: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    missed: np.ndarray
    flexion: np.ndarray
    iterations: int = 0


def close_problems(hand: ClosingHand, joint_frames: np.ndarray, prox: np.ndarray,
                   dist: np.ndarray) -> ClosedFingers:
    """Close the three fingers of m draws, one array-operation iteration at a time.

    Args:
        hand: the hand's geometry and gaps.
        joint_frames: (m, 3, 4, 4) object-frame poses of each finger's proximal joint
            (flexion zero): fixed while closing.
        prox, dist: (m, 3) each finger's pre-shape (proximal, distal) flexion, radians.
    """
    m = prox.shape[0]
    out = ClosedFingers(np.zeros((m, 3, 2), bool), np.full((m, 3, 2, 3), np.nan),
                        np.full((m, 3, 2, 3), np.nan), np.zeros((m, 3), bool),
                        np.full((m, 3, 2), np.nan))
    problems = [_Problems(joint_frames[:, f], prox[:, f], dist[:, f], hand.upper[f])
                for f in range(3)]
    iterations = 0
    while iterations < MAX_ITERATIONS and any(p.active.any() for p in problems):
        iterations += 1
        for f, prob in enumerate(problems):
            _advance(hand, f, prob, out)
    for f, prob in enumerate(problems):
        out.missed[:, f] = prob.missed
        out.flexion[:, f] = np.stack(prob.values(np.arange(m)), 1)
    out.iterations = iterations
    return out


def _advance(hand: ClosingHand, f: int, prob: _Problems, out: ClosedFingers) -> None:
    """One closing iteration of finger f for its active problems."""
    rows = np.flatnonzero(prob.active)
    if rows.size == 0:
        return
    gap_p, gap_d = _gaps_now(hand, f, prob, rows)
    gap = np.minimum(gap_p, gap_d)
    t, t_lo, t_hi = prob.t[rows], prob.t_lo[rows], prob.t_hi[rows]
    bracket_closed = ~np.isnan(t_hi) & (t_hi - t_lo < 1e-9)
    touch = ((gap >= -CONTACT_TOL) & (gap <= CONTACT_TOL)) | (bracket_closed
                                                             & (gap <= CONTACT_TOL))
    if touch.any():
        _touch_down(hand, f, prob, rows[touch], t[touch], gap[touch], out)
    apart = ~touch
    _step_or_bisect(prob, rows[apart], t[apart], t_lo[apart], t_hi[apart], gap[apart],
                    _travel(hand.speed, prob.phase[rows[apart]], gap_p[apart], gap_d[apart]))


def _travel(speed: LinkSpeeds, phase: np.ndarray, gap_p: np.ndarray, gap_d: np.ndarray
            ) -> np.ndarray:
    """:func:`~kinegrasp_env.closing.reference.closing_travel` of m problems (phase,
    gaps (m,)), the same arithmetic: radians (m,)."""
    phase1 = phase == 1
    travel = gap_d / np.where(phase1, speed.distal, speed.distal_alone)
    return np.where(phase1, np.minimum(travel, gap_p / speed.proximal), travel)


def _gaps_now(hand: ClosingHand, f: int, prob: _Problems, rows: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Gaps (m,) of finger f's proximal and distal links for problem rows at their
    current t (the grid's, exact within ``GRID_EXACT_BAND``; at most ``QUERY_DISTANCE``;
    the proximal one inf outside phase 1, where it does not move)."""
    phase1 = prob.phase[rows] == 1
    prox, dist = prob.values(rows)
    ends = hand.link_axes(prob.joint_frames[rows], f, prox, dist)
    gap_d = hand.grid_or_exact_gaps(ends[:, 2], ends[:, 3], hand.capsules[f][1].radius)
    gap_p = np.full(rows.size, np.inf)
    if phase1.any():
        sub = np.flatnonzero(phase1)
        gap_p[sub] = hand.grid_or_exact_gaps(ends[sub, 0], ends[sub, 1],
                                             hand.capsules[f][0].radius)
    gap_p = np.minimum(gap_p, QUERY_DISTANCE)
    gap_d = np.minimum(gap_d, QUERY_DISTANCE)
    gap_p[~phase1] = np.inf
    return gap_p, gap_d


def _touch_down(hand: ClosingHand, f: int, prob: _Problems, rows: np.ndarray, t: np.ndarray,
                gap: np.ndarray, out: ClosedFingers) -> None:
    """Touching problem rows (m,) at t, gap (m,): polish t to the root of the exact gap,
    record the contacts of the links touching there (exact closest pairs of their axes
    and the object). A distal contact ends the problem; a proximal one alone freezes
    the proximal joint and the distal one goes on (phase 2)."""
    t_root = _polish(hand, f, prob, rows, t, gap)
    prob.t[rows] = t_root
    prox_t, dist_t = prob.values(rows)
    link_gaps, pairs = _exact_at(hand, f, prob, rows, t_root)
    _record_contacts(hand, f, prob, rows, link_gaps, pairs, out)
    distal = link_gaps[:, 1] <= CONTACT_TOL
    prob.active[rows[distal]] = False
    switch = ~distal
    if switch.any():
        r = rows[switch]
        prob.start_p[r], prob.start_d[r] = prox_t[switch], dist_t[switch]
        prob.phase[r] = 2
        prob.t_lo[r], prob.t_hi[r] = 0.0, np.nan
        t_max = prob.t_max(r)
        prob.active[r[t_max <= 0.0]] = False
        prob.t[r] = np.where(t_max <= 0.0, 0.0, np.minimum(STEP, t_max))


def _record_contacts(hand: ClosingHand, f: int, prob: _Problems, rows: np.ndarray,
                     link_gaps: np.ndarray, pairs: tuple, out: ClosedFingers) -> None:
    """Contacts of finger f's links whose exact gap (``link_gaps`` (m, 2), ``pairs`` as
    returned by :func:`_exact_at` for problem rows (m,)) is within ``CONTACT_TOL``."""
    where, on_obj, on_seg, distance, part = pairs
    for link in (0, 1):
        sel = np.flatnonzero(link_gaps[:, link] <= CONTACT_TOL)
        if sel.size == 0:
            continue
        q = where[sel, link]
        point, normal = pair_contacts(hand.obj, on_obj[q], on_seg[q], distance[q], part[q])
        draw = rows[sel]
        out.found[draw, f, link] = True
        out.points[draw, f, link] = point
        out.normals[draw, f, link] = normal
        prob.has_contact[rows[sel]] = True


def _step_or_bisect(prob: _Problems, rows: np.ndarray, t: np.ndarray, t_lo: np.ndarray,
                    t_hi: np.ndarray, gap: np.ndarray, travel: np.ndarray) -> None:
    """Problem rows (m,) not touching at t (gap (m,), bracket [t_lo, t_hi], t_hi NaN
    until a penetration is seen): a conservative step towards contact (``travel`` (m,),
    see :func:`_travel`) while unbracketed (missed at the joint limits without a
    contact), else bisection of the bracket."""
    free = gap > CONTACT_TOL
    unbracketed = free & np.isnan(t_hi)
    if unbracketed.any():
        r = rows[unbracketed]
        t_max = prob.t_max(r)
        at_limit = t[unbracketed] >= t_max
        prob.t_lo[r] = t[unbracketed]
        prob.active[r[at_limit]] = False
        prob.missed[r[at_limit]] = ~prob.has_contact[r[at_limit]]
        step = np.maximum(travel[unbracketed], STEP)
        go = ~at_limit
        prob.t[r[go]] = np.minimum(t[unbracketed] + step, t_max)[go]
    bracketed = free & ~np.isnan(t_hi)
    if bracketed.any():
        r = rows[bracketed]
        prob.t_lo[r] = t[bracketed]
        prob.t[r] = 0.5 * (t[bracketed] + t_hi[bracketed])
    inside = ~free
    if inside.any():
        r = rows[inside]
        prob.t_hi[r] = t[inside]
        prob.t[r] = 0.5 * (t_lo[inside] + t[inside])


def _exact_at(hand: ClosingHand, f: int, prob: _Problems, rows: np.ndarray, t: np.ndarray):
    """Exact gaps (m, 2) of finger f's links at parameters t (inf for a link that does
    not move), for problem rows, and the exact closest pairs behind them: (where (m, 2),
    on_obj, on_seg, distance, part), ``where[row, link]`` indexing the pair arrays (-1
    where the link was not queried)."""
    saved = prob.t[rows].copy()
    prob.t[rows] = t
    prox, dist = prob.values(rows)
    prob.t[rows] = saved
    ends = hand.link_axes(prob.joint_frames[rows], f, prox, dist)
    gaps = np.full((rows.size, 2), np.inf)
    # one exact query for both links: the moving proximal links, then every distal one
    moving = np.flatnonzero(prob.phase[rows] == 1)
    starts = np.concatenate([ends[moving, 0], ends[:, 2]])
    stops = np.concatenate([ends[moving, 1], ends[:, 3]])
    on_obj, on_seg, distance, part = closest_to_segments(hand.obj, starts, stops)
    gaps[moving, 0] = distance[:moving.size] - hand.capsules[f][0].radius
    gaps[:, 1] = distance[moving.size:] - hand.capsules[f][1].radius
    # the closest pairs, by link: rows of the query for (row, link), -1 if not computed
    where = np.full((rows.size, 2), -1)
    where[moving, 0] = np.arange(moving.size)
    where[:, 1] = moving.size + np.arange(rows.size)
    return gaps, (where, on_obj, on_seg, distance, part)


def _polish(hand: ClosingHand, f: int, prob: _Problems, rows: np.ndarray, t: np.ndarray,
            gap: np.ndarray) -> np.ndarray:
    """Vectorized :func:`kinegrasp_env.closing.reference.secant_root` for problem rows."""
    t_min = np.maximum(t - POLISH_RANGE, 0.0)
    t_max = prob.t_max(rows)
    t0 = np.maximum(t - POLISH_PROBE, t_min)
    active = (t0 < t) & (np.abs(gap) > POLISH_TOL)
    g0 = np.zeros(rows.size)
    if active.any():
        g0[active] = _exact_at(hand, f, prob, rows[active], t0[active])[0].min(axis=1)
    t1, g1 = t.copy(), gap.copy()
    best_t, best_g = t1.copy(), np.abs(g1)
    for _ in range(POLISH_ITERATIONS):
        active &= g1 != g0
        if not active.any():
            break
        idx = np.flatnonzero(active)
        t2 = np.minimum(np.maximum(t1[idx] - g1[idx] * (t1[idx] - t0[idx])
                                   / (g1[idx] - g0[idx]), t_min[idx]), t_max[idx])
        g2 = _exact_at(hand, f, prob, rows[idx], t2)[0].min(axis=1)
        t0[idx], g0[idx], t1[idx], g1[idx] = t1[idx], g1[idx], t2, g2
        better = np.abs(g2) < best_g[idx]
        best_t[idx[better]], best_g[idx[better]] = t2[better], np.abs(g2[better])
        active &= best_g > POLISH_TOL
    return best_t


class _Problems:
    """Closing state of one finger over the draws (the per-finger state of hand._Finger)."""

    def __init__(self, joint_frames: np.ndarray, prox: np.ndarray, dist: np.ndarray,
                 upper: np.ndarray) -> None:
        m = prox.size
        self.joint_frames = np.ascontiguousarray(joint_frames)
        self.upper_p, self.upper_d = float(upper[0]), float(upper[1])
        self.start_p = np.minimum(prox, self.upper_p)
        self.start_d = np.minimum(dist, self.upper_d)
        self.phase = np.ones(m, np.int8)
        self.t = np.zeros(m)
        self.t_lo = np.zeros(m)
        self.t_hi = np.full(m, np.nan)
        self.active = np.ones(m, bool)
        self.missed = np.zeros(m, bool)
        self.has_contact = np.zeros(m, bool)

    def values(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        phase1 = self.phase[rows] == 1
        t = self.t[rows]
        prox = np.minimum(self.start_p[rows] + np.where(phase1, t, 0.0), self.upper_p)
        dist = np.minimum(self.start_d[rows] + t, self.upper_d)
        return prox, dist

    def t_max(self, rows: np.ndarray) -> np.ndarray:
        both = np.maximum(np.maximum(self.upper_p - self.start_p[rows],
                                     self.upper_d - self.start_d[rows]), 0.0)
        distal = np.maximum(self.upper_d - self.start_d[rows], 0.0)
        return np.where(self.phase[rows] == 1, both, distal)
