"""The rules of the auto-close, shared by the reference and the fast closing: the tolerances
and steps, the step a two-phalanx finger's speed bounds allow (:func:`closing_travel`), the
secant polish (:func:`secant_root`). The closings that apply them:
:mod:`kinegrasp_env.closing.generic_reference` (pybullet's distances, one draw at a time) and
:mod:`kinegrasp_env.closing.generic_fast` (a batch of draws; fingers of two capsule phalanxes
by :mod:`kinegrasp_env.closing.close_kernel` against the distance grid).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kinegrasp_env import jit

#: Largest gap (or penetration) at which a link counts as touching, metres.
CONTACT_TOL = 2e-4
#: Smallest closing step, radians (bisection takes over after an overshoot).
STEP = 0.02
#: Gaps beyond this are not computed exactly (the step is then bounded by it), metres.
QUERY_DISTANCE = 0.05
#: Gaps of finger capsules within +-this are recomputed exactly (pybullet's convex-hull
#: distances are off by up to ~1 mm at edges), metres.
EXACT_BAND = 2e-3
#: Contact polish: once touching (gap within CONTACT_TOL), secant steps on the exact gap
#: move the finger to where the gap is zero (to POLISH_TOL), within POLISH_RANGE radians.
POLISH_TOL = 1e-9
POLISH_PROBE = 1e-3
POLISH_RANGE = 0.05
POLISH_ITERATIONS = 8
#: Penetration below which the pre-grasp pose counts as a start collision, metres.
START_TOL = CONTACT_TOL
#: Closing steps per finger at most (the compiled capsule loop's).
MAX_ITERATIONS = 400


class LinkSpeeds(NamedTuple):
    """Bounds on how fast any surface point of a finger link moves per radian of closing
    (metres/rad): the proximal and the distal link while both joints close (phase 1), the
    distal link while only the distal joint closes (phase 2; the proximal link is then still).
    """

    proximal: float
    distal: float
    distal_alone: float


@jit.kernel(_nrt=False)
def closing_travel(gap_p: float, gap_d: float, phase: int, speeds: np.ndarray) -> float:
    """Largest closing step (radians) before a moving link could touch: each link's gap
    (metres) over its speed bound, the smaller; the proximal link counts in phase 1 only.
    speeds: (3,) the :class:`LinkSpeeds` as an array. Compiled: the fast engine's closing
    loop calls it too.
    (One bound for the whole finger, the sum of the three reaches, took smaller steps, hence
    more closing iterations in the fast engine.)"""
    if phase != 1:
        return gap_d / speeds[2]
    return min(gap_d / speeds[1], gap_p / speeds[0])


def polish_window(t, t_end):
    """(lowest, highest) parameter a touch found at t may be polished to: up to
    ``POLISH_RANGE`` behind it (not below 0) and on to the end of the joints' travel
    ``t_end`` (not below t); scalars, or arrays (n,) of draws alike."""
    return np.maximum(t - POLISH_RANGE, 0.0), np.maximum(t_end, t)


def secant_root(gap_at, t: float, gap: float, t_min: float, t_max: float) -> float:
    """Polish a contact: the t in [t_min, t_max] where the exact gap crosses zero.

    Secant steps from (t - ``POLISH_PROBE``, t) until the gap is within ``POLISH_TOL``
    (at most ``POLISH_ITERATIONS``); the best t seen is returned (the start t when nothing
    improves it, e.g. a grazing touch).
    """
    t0 = max(t - POLISH_PROBE, t_min)
    if t0 >= t or abs(gap) <= POLISH_TOL:
        return t
    g0, t1, g1 = gap_at(t0), t, gap
    best_t, best_g = t1, abs(g1)
    for _ in range(POLISH_ITERATIONS):
        if g1 == g0:
            break
        t2 = min(max(t1 - g1 * (t1 - t0) / (g1 - g0), t_min), t_max)
        g2 = gap_at(t2)
        t0, g0, t1, g1 = t1, g1, t2, g2
        if abs(g2) < best_g:
            best_t, best_g = t2, abs(g2)
        if best_g <= POLISH_TOL:
            break
    return best_t
