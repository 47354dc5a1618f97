"""The closing of fingers of two capsule phalanxes as one compiled loop
(:mod:`~kinegrasp_env.closing.capsule_fingers` hands it any description's fingers of that
kind, the default robot's among them).

Each (draw, finger) closing problem runs its whole state machine in one compiled loop
(:func:`close_finger`; its two branches, :func:`touch_down` and :func:`step_or_bisect`):
conservative steps on the distance grid's capsule gaps
(:func:`kinegrasp_env.closing.capsule_gap` ``gap_one``), the exact capsule-object pair
within the band of contact (:mod:`kinegrasp_env.closing.segment_distance`
``segment_one``), the capsule axes posed by :func:`kinegrasp_env.closing.finger_axes.axes_one`,
bisection once a step penetrates, the touch polished to a zero gap. Array operations over a
batch pay a fixed cost per iteration (~35 iterations x 3 fingers of a few dozen numpy calls)
that dominates small batches (the environment's 64 draws); here there is none.

Three savings that change no result: an exact gap the state machine cannot use is not
computed (a link that can be neither the smaller gap nor in contact, by a lower bound:
:func:`bounded_pair`), the closest pairs where the polish ends are those it computed
there (:func:`closest_pairs`), not computed again, and each exact query starts from the
object point the same link's last query found (this draw's, or the previous draw's: the
draws are nearby configurations), which prunes most of its search
(:func:`kinegrasp_env.closing.segment_distance.segment_search_near`; it saves more on the
spray flask's closing than on the mug's). Kernels that allocate nothing are
compiled without numba's reference counting (``_nrt=False``): with it, every call that
passes arrays (these pass tuples of ~20) paid an atomic increment and decrement per array,
a sizeable share of the closing time.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.closing import capsule_gap, close_rules, segment_distance
from kinegrasp_env.closing.capsule_gap import gap_one
from kinegrasp_env.closing.finger_axes import axes_one
from kinegrasp_env.closing.segment_distance import (
    PRUNE_MARGIN,
    segment_bound,
    segment_buffers,
    segment_search_near,
)
from kinegrasp_env.world.objects import GraspObject

#: Entries of a stored closest pair: distance, point on the object (3), point on the
#: segment (3), part index.
PAIR_SIZE = 8


@jit.kernel(_nrt=False)
def store_pair(out, d, ox, oy, oz, sx, sy, sz, part):
    """A closest pair (:func:`segment_one`'s result) into out (PAIR_SIZE,)."""
    out[0], out[1], out[2], out[3], out[4], out[5], out[6] = d, ox, oy, oz, sx, sy, sz
    out[7] = part

@jit.kernel(_nrt=False)
def store_near(near, d, ox, oy, oz):
    """The object point of a closest pair into near (3,), where one was found."""
    if d < np.inf:
        near[0], near[1], near[2] = ox, oy, oz

@jit.kernel(_nrt=False)
def exact_pair(geo, a, e, sort, out, near):
    """Exact closest pair of segment [a, e] (3,) and the object into out (PAIR_SIZE,);
    sort: the buffers of :func:`segment_one`; near (3,): the object point the link's last
    query found (NaN: none), replaced by this one's (it only speeds the search up:
    :func:`kinegrasp_env.closing.segment_distance.segment_search_near`)."""
    d, ox, oy, oz, sx, sy, sz, part = segment_search_near(geo, a[0], a[1], a[2], e[0], e[1],
                                                          e[2], sort, near[0], near[1],
                                                          near[2], False)
    store_pair(out, d, ox, oy, oz, sx, sy, sz, part)
    store_near(near, d, ox, oy, oz)
    return d

@jit.kernel(_nrt=False)
def bounded_pair(geo, a, e, sort, out, limit, near):
    """:func:`exact_pair` where the distance can be below ``limit`` (metres): skipped (out's
    distance set to inf, inf returned) where a lower bound of it (:func:`segment_bound`)
    is at least ``limit`` + PRUNE_MARGIN."""
    if segment_bound(geo, a[0], a[1], a[2], e[0], e[1], e[2], sort) - PRUNE_MARGIN >= limit:
        out[0] = np.inf
        return np.inf
    d, ox, oy, oz, sx, sy, sz, part = segment_search_near(geo, a[0], a[1], a[2], e[0], e[1],
                                                          e[2], sort, near[0], near[1],
                                                          near[2], True)
    store_pair(out, d, ox, oy, oz, sx, sy, sz, part)
    store_near(near, d, ox, oy, oz)
    return d

@jit.kernel(_nrt=False)
def link_gap(grid, geo, a, e, radius, sample, sort, pair, last):
    """Gap of a capsule: the grid's, exact within the band of contact (last: the link's
    last object point, ``near`` of :func:`exact_pair`)."""
    values, shape, origin, spacing, samples, near, refine, gold, band = grid
    gap, _ = gap_one(values, shape, origin, spacing, a[0], a[1], a[2], e[0], e[1], e[2],
                     radius, samples, near, refine, gold, sample)
    if abs(gap) <= band:
        gap = exact_pair(geo, a, e, sort, pair, last) - radius
    return gap

@jit.kernel(_nrt=False)
def flexions(finger, phase, start_p, start_d, t):
    """(proximal, distal) flexion at closing parameter t."""
    up_p, up_d = finger[8], finger[9]
    prox = min(start_p + (t if phase == 1 else 0.0), up_p)
    return prox, min(start_d + t, up_d)

@jit.kernel(_nrt=False)
def t_limit(finger, phase, start_p, start_d):
    """Largest closing parameter before the moving joints reach their limits."""
    up_p, up_d = finger[8], finger[9]
    if phase == 1:
        return max(max(up_p - start_p, up_d - start_d), 0.0)
    return max(up_d - start_d, 0.0)

@jit.kernel(_nrt=False)
def place_axes(finger, prox, dist, work):
    """The finger's capsule axes at flexions prox, dist into work's ends (4, 3) (work[4])."""
    joint_frame, axis_p, distal_origin, axis_d, ends_p, ends_d = finger[:6]
    rot, frame_p, frame_d, tmp, ends = work[:5]
    axes_one(joint_frame, axis_p, prox, distal_origin, axis_d, dist, ends_p, ends_d, rot,
             frame_p, frame_d, tmp, ends)

@jit.kernel(_nrt=False)
def both_links(geo, finger, ends, sort, pair, need, near):
    """Smallest exact gap of both links of a finger with capsule axes ``ends`` (4, 3); their
    closest pairs into pair (2, PAIR_SIZE). The distal link first; the proximal one is
    skipped (row 0's distance inf) where it can be neither the smallest gap nor within
    ``need`` (metres) (:func:`bounded_pair`), so the result, and which links are within
    ``need``, are those of both computed. near (2, 3): see :func:`exact_pair`."""
    r_p, r_d = finger[6], finger[7]
    gap = exact_pair(geo, ends[2], ends[3], sort, pair[1], near[1]) - r_d
    return min(gap, bounded_pair(geo, ends[0], ends[1], sort, pair[0],
                                 max(gap, need) + r_p, near[0]) - r_p)

@jit.kernel(_nrt=False)
def exact_gap(geo, finger, phase, start_p, start_d, t, work, need):
    """Smallest exact gap of the finger's moving links at parameter t; their closest
    pairs in work's pair (2, PAIR_SIZE) (row 0 untouched in phase 2; in phase 1 a link that
    cannot matter may be skipped, see :func:`both_links`)."""
    sort, pair = work[5], work[6]
    prox, dist = flexions(finger, phase, start_p, start_d, t)
    place_axes(finger, prox, dist, work)
    ends = work[4]
    if phase == 1:
        return both_links(geo, finger, ends, sort, pair, need, finger[10])
    return exact_pair(geo, ends[2], ends[3], sort, pair[1], finger[10][1]) - finger[7]

@jit.kernel(_nrt=False)
def polish(geo, rules, finger, phase, start_p, start_d, t, gap, work):
    """The t where the exact gap crosses zero (see
    :func:`kinegrasp_env.closing.close_rules.secant_root`), and whether it was evaluated
    there (its closest pairs, as :func:`exact_gap` left them, are then in work[7])."""
    polish_tol, probe, reach, iterations = rules[3], rules[4], rules[5], rules[6]
    pair, best_pair = work[6], work[7]
    t_max = t_limit(finger, phase, start_p, start_d)
    t_min = max(t - reach, 0.0)
    t0 = max(t - probe, t_min)
    active = t0 < t and abs(gap) > polish_tol
    g0 = 0.0
    if active:
        g0 = exact_gap(geo, finger, phase, start_p, start_d, t0, work, -np.inf)
    t1, g1 = t, gap
    best_t, best_g = t1, abs(g1)
    evaluated = False
    for _ in range(iterations):
        active = active and g1 != g0
        if not active:
            break
        t2 = min(max(t1 - g1 * (t1 - t0) / (g1 - g0), t_min), t_max)
        g2 = exact_gap(geo, finger, phase, start_p, start_d, t2, work, -np.inf)
        t0, g0, t1, g1 = t1, g1, t2, g2
        if abs(g2) < best_g:
            best_t, best_g = t2, abs(g2)
            evaluated = True
            for link in range(2):
                for k in range(PAIR_SIZE):
                    best_pair[link, k] = pair[link, k]
        active = active and best_g > polish_tol
    return best_t, evaluated

@jit.kernel(_nrt=False)
def closest_pairs(geo, contact_tol, finger, phase, start_p, start_d, t, evaluated, work):
    """The closest pairs of the finger's moving links at parameter t into work's pair, as
    :func:`exact_gap` with ``need = contact_tol`` leaves them: taken from
    :func:`polish`'s best evaluation there (work[7]) where it made one, a link it skipped
    completed."""
    pair = work[6]
    if not evaluated:
        exact_gap(geo, finger, phase, start_p, start_d, t, work, contact_tol)
        return
    best_pair = work[7]
    for link in range(2):
        for k in range(PAIR_SIZE):
            pair[link, k] = best_pair[link, k]
    if phase != 1:
        return
    radius = (finger[6], finger[7])
    for link in range(2):
        if pair[link, 0] == np.inf:
            prox, dist = flexions(finger, phase, start_p, start_d, t)
            place_axes(finger, prox, dist, work)
            ends = work[4]
            limit = max(pair[1 - link, 0] - radius[1 - link], contact_tol) + radius[link]
            bounded_pair(geo, ends[2 * link], ends[2 * link + 1], work[5], pair[link], limit,
                         finger[10][link])

@jit.kernel(_nrt=False)
def touch_down(geo, rules, finger, state, gap, work, found, pairs):
    """A touching finger: t polished to the root of the exact gap, the links touching there
    recorded (found (2,) set, their closest pairs into pairs (2, PAIR_SIZE)). A distal
    contact ends the finger; a proximal one alone freezes the proximal joint and the distal
    one goes on (phase 2). Returns the new state."""
    contact_tol, step_min = rules[0], rules[1]
    r_p, r_d = finger[6], finger[7]
    phase, start_p, start_d, t, t_lo, t_hi = state[:6]
    has_contact = state[7]
    pair = work[6]
    t, evaluated = polish(geo, rules, finger, phase, start_p, start_d, t, gap, work)
    # the links touching there, and their closest pairs
    prox_t, dist_t = flexions(finger, phase, start_p, start_d, t)
    closest_pairs(geo, contact_tol, finger, phase, start_p, start_d, t, evaluated, work)
    link_gaps = (pair[0, 0] - r_p if phase == 1 else np.inf, pair[1, 0] - r_d)
    for link in range(2):
        if link_gaps[link] <= contact_tol:
            found[link] = True
            for k in range(PAIR_SIZE):  # (a slice assignment would allocate)
                pairs[link, k] = pair[link, k]
            has_contact = True
    if link_gaps[1] <= contact_tol:
        return (phase, start_p, start_d, t, t_lo, t_hi, False, has_contact)
    # proximal contact only: freeze it, the distal joint goes on
    t_max = t_limit(finger, 2, prox_t, dist_t)
    if t_max <= 0.0:
        return (2, prox_t, dist_t, 0.0, 0.0, np.nan, False, has_contact)
    return (2, prox_t, dist_t, min(step_min, t_max), 0.0, np.nan, True, has_contact)

@jit.kernel(_nrt=False)
def step_or_bisect(rules, finger, state, gap, step_free):
    """A finger not touching: a conservative step towards contact (``step_free``: see
    :func:`kinegrasp_env.closing.close_rules.closing_travel`) while no penetration is
    bracketed, else bisection of the bracket [t_lo, t_hi]. Returns (new state, missed: the
    joints reached their limits without any contact)."""
    contact_tol, step_min = rules[0], rules[1]
    phase, start_p, start_d, t, t_lo, t_hi, active, has_contact = state
    missed = False
    if gap > contact_tol:
        if np.isnan(t_hi):  # conservative step towards contact
            t_max = t_limit(finger, phase, start_p, start_d)
            t_lo = t
            if t >= t_max:
                active = False
                missed = not has_contact
            else:
                step = max(step_free, step_min)
                t = min(t + step, t_max)
        else:  # bisection, below the bracket
            t_lo = t
            t = 0.5 * (t + t_hi)
    else:  # penetrating: bisection, above the bracket
        t_hi = t
        t = 0.5 * (t_lo + t)
    return (phase, start_p, start_d, t, t_lo, t_hi, active, has_contact), missed

@jit.kernel(_nrt=False)
def close_finger(grid, geo, rules, finger, speed, prox0, dist0, buffers, found, pairs,
                 flexion):
    """Close one finger of one draw from flexions prox0, dist0 (radians): one (draw, finger)
    closing problem. Writes found (2,) and pairs (2, PAIR_SIZE) of its links and the
    (proximal, distal) flexion where it stopped into flexion (2,); returns (iterations,
    missed).

    The state is (phase, start_p, start_d, t, t_lo, t_hi, active, has_contact): phase 1
    moves both joints, phase 2 (after a proximal contact) the distal one; the flexions are
    start + t (to the joint limits); [t_lo, t_hi] brackets contact (t_hi NaN until a
    penetration is seen). buffers: (sample, work, scratch) of :func:`close_all`; finger[10]
    (2, 3): an object point near each link (``near`` of :func:`exact_pair`: NaN for none; it
    changes the speed of the exact queries, not their results), updated as it closes.
    """
    contact_tol, query_distance, max_iterations = rules[0], rules[2], rules[7]
    r_p, r_d = finger[6], finger[7]
    sample, work, scratch = buffers
    sort, near = work[5], finger[10]
    state = (1, min(prox0, finger[8]), min(dist0, finger[9]), 0.0, 0.0, np.nan, True, False)
    missed = False
    it = 0
    while state[6] and it < max_iterations:
        it += 1
        # the gap of the moving links (the grid's, exact within the band), at most the
        # query distance
        phase, start_p, start_d, t, t_lo, t_hi = state[:6]
        prox, dist = flexions(finger, phase, start_p, start_d, t)
        place_axes(finger, prox, dist, work)
        ends = work[4]
        gap_d = link_gap(grid, geo, ends[2], ends[3], r_d, sample, sort, scratch, near[1])
        gap_p = np.inf
        if phase == 1:
            gap_p = link_gap(grid, geo, ends[0], ends[1], r_p, sample, sort, scratch,
                             near[0])
        gap_p = min(gap_p, query_distance)
        gap_d = min(gap_d, query_distance)
        if phase != 1:
            gap_p = np.inf
        gap = min(gap_p, gap_d)
        bracket_closed = not np.isnan(t_hi) and t_hi - t_lo < 1e-9
        if (-contact_tol <= gap <= contact_tol) or (bracket_closed and gap <= contact_tol):
            state = touch_down(geo, rules, finger, state, gap, work, found, pairs)
        else:
            state, missed = step_or_bisect(rules, finger, state, gap,
                                           close_rules.closing_travel(gap_p, gap_d, phase, speed))
    flexion[0], flexion[1] = flexions(finger, state[0], state[1], state[2], state[3])
    return it, missed

@jit.kernel
def close_all(grid, geo, rules, joint_frames, prox0, dist0, axis_p, axis_d, distal_origin,
              ends_p, ends_d, radius, upper, speed, found, pairs, missed, flexion):
    """Close every finger of every draw (:func:`close_finger` for each).

    rules: :func:`closing_rules`; joint_frames (m, F, 4, 4), prox0 / dist0 (m, F): per
    draw and finger; the finger constants are stacked over the F fingers (``speed``
    (F, 3): each finger's :class:`~kinegrasp_env.closing.close_rules.LinkSpeeds`). Writes
    found (m, F, 2), pairs (m, F, 2, PAIR_SIZE), missed (m, F) and the closed flexions
    (m, F, 2) (proximal, distal; radians); returns the most iterations any problem took.
    """
    # work buffers: rotation, proximal and distal frames, product, axis ends, those of
    # segment_one, the closest pairs of both links, and those of polish's best evaluation
    work = (np.empty((3, 3)), np.empty((3, 4)), np.empty((3, 4)), np.empty((3, 3)),
            np.empty((4, 3)), segment_buffers(geo[0], geo[1]), np.empty((2, PAIR_SIZE)),
            np.empty((2, PAIR_SIZE)))
    buffers = (np.empty(grid[4]), work, np.empty(PAIR_SIZE))
    # per finger and link, the object point its last exact query found: the draws are
    # nearby configurations, so the previous draw's points start the next one's queries
    near = np.full((prox0.shape[1], 2, 3), np.nan)
    most = 0
    for i in range(prox0.shape[0]):
        for f in range(prox0.shape[1]):
            finger = (joint_frames[i, f], axis_p[f], distal_origin[f], axis_d[f],
                      ends_p[f], ends_d[f], radius[f, 0], radius[f, 1], upper[f, 0],
                      upper[f, 1], near[f])
            it, missed[i, f] = close_finger(grid, geo, rules, finger, speed[f], prox0[i, f],
                                            dist0[i, f], buffers, found[i, f], pairs[i, f],
                                            flexion[i, f])
            most = max(most, it)
    return most

def closing_rules() -> tuple:
    """The auto-close constants of :mod:`kinegrasp_env.closing.close_rules` (CONTACT_TOL, STEP,
    QUERY_DISTANCE, POLISH_TOL, POLISH_PROBE, POLISH_RANGE, POLISH_ITERATIONS,
    MAX_ITERATIONS), passed to the kernel as an argument (numba's disk cache would keep the
    values of module globals of another file even after they change)."""
    return (float(close_rules.CONTACT_TOL), float(close_rules.STEP),
            float(close_rules.QUERY_DISTANCE), float(close_rules.POLISH_TOL),
            float(close_rules.POLISH_PROBE), float(close_rules.POLISH_RANGE),
            int(close_rules.POLISH_ITERATIONS), int(close_rules.MAX_ITERATIONS))


def grid_args(grid, band: float, refine: int = capsule_gap.REFINE) -> tuple:
    """The distance grid, the capsule-gap constants (``refine`` golden-section steps per
    gap) and the band (metres) within which gaps are computed exactly, as the kernel's
    ``grid`` tuple."""
    return (*capsule_gap.grid_arrays(grid), capsule_gap.SAMPLES, capsule_gap.NEAR,
            int(refine), float(capsule_gap.GOLD), float(band))


def geometry_args(obj: GraspObject) -> tuple:
    """The object's packed parts as the kernel's ``geo`` tuple."""
    return segment_distance.geometry_tuple(obj)
