"""Draw-by-draw agreement of two contact computations on the same configurations.

Used by ``benchmarks/agreement.py`` and ``tests/test_agreement.py`` to compare the fast engine
with the reference engine, and either engine with the pybullet-only contacts of
:mod:`kinegrasp_env.montecarlo.bullet_contacts`. Both sides are duck-typed: anything with the
``outcome``, ``quality``, ``n_contacts``, ``points``, ``normals``, ``finger`` and ``link``
arrays of :class:`~kinegrasp_env.montecarlo.draws.DrawBatch` (and ``hand``, where both have
it, for the closed configurations).

Disagreements are counted, never dropped: draws with another outcome, draws whose touching
(finger, link) lists differ, and draws whose fingers stop elsewhere (closed hands more than
:data:`STOP_TOL` apart: the same link touching at another place, e.g. a finger that grazes
an edge within the contact tolerance and stops on its far side in one engine). Points,
normals and Q are compared on the remaining, paired, draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, START_COLLISION

#: Closed hands further apart than this (radians, any joint) stopped at different places.
#: Most draws stop within 1e-5 rad of each other, some within 1e-4 (the flexion at a polished
#: contact is ill-determined where the gap is flat in it); the other root of an edge grazed
#: within the contact tolerance lies 3e-4 to 2e-2 rad away (measured, benchmarks/agreement.py).
STOP_TOL = 1e-4
#: Two smallest |components| of a normal closer than this: the friction cone's tangent basis
#: (the axis of the smallest component, :func:`kinegrasp_env.quality.wrenches.tangent_basis`)
#: may flip between the two, which turns the linearized cone by up to half an edge and
#: changes Q by up to ~1% for a 1e-12 change of the normal (measured on the mug).
TIE_TOL = 1e-4


@dataclass
class Agreement:
    """How two computations a and b of the same n draws agree.

    Attributes:
        draws: n.
        same_outcome: draws with the same outcome.
        closed: draws where both closed the hand (neither a start collision).
        list_mismatch: of those, draws whose touching (finger, link) lists differ.
        stop_mismatch: of those with the same lists, draws whose closed hands differ by
            more than :data:`STOP_TOL`.
        contacts: contacts paired (on the other closed draws).
        point_max, point_median: distances between paired contact points (metres).
        normal_max: largest angle between paired normals (degrees).
        offset_max: largest offset of a's contact points from a closest pair in b's geometry
            (metres), offset_normal_max: largest angle between a's normals and b's normal at
            a's point (degrees); NaN when not measured (see
            ``BulletContactReference.check_contacts``).
        q_pairs: paired draws in force closure on both sides.
        q_max: largest |Q_a - Q_b| / Q_a over them.
        q_abs_max: largest |Q_a - Q_b| over them; q_abs_max_untied: the same over those
            without a tangent-basis tie (:data:`TIE_TOL`) on either side.
    """

    draws: int = 0
    same_outcome: int = 0
    closed: int = 0
    list_mismatch: int = 0
    stop_mismatch: int = 0
    contacts: int = 0
    point_max: float = 0.0
    point_median: float = 0.0
    normal_max: float = 0.0
    offset_max: float = np.nan
    offset_normal_max: float = np.nan
    q_pairs: int = 0
    q_max: float = 0.0
    q_abs_max: float = 0.0
    q_abs_max_untied: float = 0.0


def compare(a, b, checks: tuple[np.ndarray, np.ndarray] | None = None) -> Agreement:
    """Agreement of draw sets a and b (same configurations, same order); checks: a's
    contacts held to b's geometry where measured, (offsets, normal angles), each (n, 6)
    NaN padded (``BulletContactReference.check_contacts``)."""
    same_lists, closed = contact_lists_match(a, b)
    same_stop = same_stops(a, b)
    paired = same_lists & same_stop
    gaps, angles = paired_deviations(a, b, paired)
    fc = paired & (a.outcome == FORCE_CLOSURE) & (b.outcome == FORCE_CLOSURE)
    q_abs = np.abs(a.quality[fc] - b.quality[fc])
    q_rel = q_abs / a.quality[fc]
    untied = ~(basis_ties(a.normals, a.n_contacts) | basis_ties(b.normals, b.n_contacts))[fc]
    offset, offset_normal = np.nan, np.nan
    if checks is not None and np.isfinite(checks[0]).any():
        offset, offset_normal = (float(np.nanmax(c)) for c in checks)
    return Agreement(
        draws=len(a.outcome), same_outcome=int((a.outcome == b.outcome).sum()),
        closed=int(closed.sum()), list_mismatch=int((closed & ~same_lists).sum()),
        stop_mismatch=int((same_lists & ~same_stop).sum()), contacts=len(gaps),
        point_max=float(gaps.max(initial=0.0)),
        point_median=float(np.median(gaps)) if len(gaps) else 0.0,
        normal_max=float(angles.max(initial=0.0)), offset_max=offset,
        offset_normal_max=offset_normal, q_pairs=int(fc.sum()),
        q_max=float(q_rel.max(initial=0.0)), q_abs_max=float(q_abs.max(initial=0.0)),
        q_abs_max_untied=float(q_abs[untied].max(initial=0.0)))


def contact_lists_match(a, b) -> tuple[np.ndarray, np.ndarray]:
    """((n,) same touching (finger, link) lists, (n,) both closed the hand)."""
    closed = (a.outcome > START_COLLISION) & (b.outcome > START_COLLISION)
    same = closed & (a.n_contacts == b.n_contacts)
    width = a.finger.shape[1]
    valid = np.arange(width)[None, :] < a.n_contacts[:, None]
    same &= (((a.finger == b.finger) & (a.link == b.link)) | ~valid).all(axis=1)
    return same, closed


def same_stops(a, b) -> np.ndarray:
    """(n,) closed hands within :data:`STOP_TOL` (True where either side has no ``hand``)."""
    if not (hasattr(a, "hand") and hasattr(b, "hand")):
        return np.ones(len(a.outcome), dtype=bool)
    with np.errstate(invalid="ignore"):
        apart = np.abs(a.hand - b.hand) > STOP_TOL
    return ~apart.any(axis=1)


def paired_deviations(a, b, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Point distances (metres) and normal angles (degrees) of the contacts of draws
    ``rows`` (n,) bool (whose contact lists match), each (contacts,)."""
    rows = np.flatnonzero(rows)
    take = np.arange(a.points.shape[1])[None, :] < a.n_contacts[rows, None]
    pa, pb = a.points[rows][take], b.points[rows][take]
    na, nb = a.normals[rows][take], b.normals[rows][take]
    cosine = np.einsum("ij,ij->i", na, nb) / (np.linalg.norm(na, axis=1)
                                              * np.linalg.norm(nb, axis=1))
    return np.linalg.norm(pa - pb, axis=1), np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))


def basis_ties(normals: np.ndarray, n_contacts: np.ndarray, tol: float = TIE_TOL) -> np.ndarray:
    """(n,) draws with a contact normal (of normals (n, 6, 3)) whose two smallest
    |components| are within ``tol``."""
    magnitude = np.sort(np.abs(normals), axis=-1)
    tied = magnitude[..., 1] - magnitude[..., 0] < tol
    valid = np.arange(normals.shape[1])[None, :] < n_contacts[:, None]
    return (tied & valid).any(axis=1)
