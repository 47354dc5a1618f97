"""One finger of a description robot closed over a batch of draws: the loop of the fast
generic closing (:class:`~kinegrasp_env.closing.generic_fast.FastRobotHand`), the model of
:mod:`~kinegrasp_env.closing.generic_reference` step for step.

The finger's closing joints move with its parameter t; a link that touches stops the
joints it holds (:func:`~kinegrasp_env.robot.touch_rule.touch_stops`), the others go on,
and a link whose joints have all stopped is not measured again. A step is the least over
the moving links of each one's gap lower bound over its speed bound by the joints still
turning (:attr:`~kinegrasp_env.closing.finger_paths.FingerPath.speeds`). A finger of
several revolute degrees of freedom, whose touches can leave joints closing, steps at least
:data:`~kinegrasp_env.closing.close_rules.STEP` (a step that leaves a link deeper than the
contact tolerance is halved and tried again) and its touches are polished to where the
touching links' exact gap is zero (:data:`~kinegrasp_env.closing.close_rules.POLISH_TOL`:
secant steps, as the default robot's closing does), so that where a phalanx stops, which
moves where the next one touches, does not depend on the steps that led there. Any other
finger stops where it first comes within the tolerance; one whose closing joints are all
prismatic (its links translate) steps at least the travel its links' separating planes
allow, up to the first joint's limit (the translation's direction is fixed until then).

Every draw of the batch closes on its own: the loop steps the draws still closing together,
and the touches found over several steps wait to be polished together (a polish's cost is
mostly per call); no draw's result depends on the others'.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_rules import (
    POLISH_ITERATIONS,
    POLISH_PROBE,
    POLISH_TOL,
    STEP,
    polish_window,
)
from kinegrasp_env.closing.finger_paths import FingerPath, link_poses, tree_poses
from kinegrasp_env.closing.generic_reference import MAX_STEPS

#: Exact distances are taken below NEAR x the contact tolerance (above it the certified
#: bound, within 1e-8 of them relative, stands).
NEAR = 2.0
#: A separating plane's step ends this many contact tolerances short of the plane (a pair
#: left a little apart, whose direction is defined, as the reference's steps leave it).
SHORT = 0.5

__all__ = ["NEAR", "SHORT", "close_finger"]


class _Finger:
    """One finger's closing over m draws: its joint values at any t, its links' poses and
    exact gaps (the hand's)."""

    def __init__(self, hand, path: FingerPath, palm: np.ndarray, values0: dict) -> None:
        self.hand, self.path, self.palm = hand, path, palm
        self.v0 = np.stack([values0[name] for name in path.joints], axis=1)
        self.chains = {link: path.chains[link] for link in path.links}
        names = {j.name for chain in self.chains.values() for j in chain}
        self.fixed = {k: v for k, v in values0.items() if k in names}
        self.held = np.full(self.v0.shape, np.inf)  # the t at which each joint stopped

    def values(self, rows: np.ndarray, t: np.ndarray) -> dict:
        """Joint values of draws ``rows`` at their t (len(rows),)."""
        vals = {k: v[rows] for k, v in self.fixed.items()}
        setting = np.clip(self.v0[rows] + self.path.rates * np.minimum(t[:, None],
                                                                       self.held[rows]),
                          self.path.lower, self.path.upper)
        for j, name in enumerate(self.path.joints):
            vals[name] = setting[:, j]
        return vals

    def poses(self, rows: np.ndarray, t: np.ndarray) -> dict[str, np.ndarray]:
        """Object-frame poses (len(rows), 4, 4) of the finger's links at the draws' t
        (:func:`~kinegrasp_env.closing.finger_paths.tree_poses`)."""
        return tree_poses(self.path.tree, self.palm[rows], self.values(rows, t),
                          self.path.links)

    def gap(self, rows: np.ndarray, t: np.ndarray, links: np.ndarray) -> np.ndarray:
        """(len(rows),) the least exact distance of each draw's ``links`` (len(rows), K)
        bool at its t."""
        poses = self.poses(rows, t)
        out = np.full(rows.size, np.inf)
        for k, link in enumerate(self.path.links):
            if links[:, k].any():
                d = self.hand.exact(poses[link], link)[0]
                out = np.minimum(out, np.where(links[:, k], d, np.inf))
        return out

    def polish(self, rows: np.ndarray, t: np.ndarray, g: np.ndarray, links: np.ndarray,
               low: np.ndarray, high: np.ndarray) -> np.ndarray:
        """The t (len(rows),) in [low, high] where the exact gap of each draw's touching
        ``links`` crosses zero: secant steps from (t - POLISH_PROBE, t) until within
        POLISH_TOL (at most POLISH_ITERATIONS); the best t seen (the given one where
        nothing improves it: a grazing touch)."""
        t0 = np.maximum(t - POLISH_PROBE, low)
        todo = (t0 < t) & (np.abs(g) > POLISH_TOL)
        best_t, best_g = t.copy(), np.abs(g)
        if not todo.any():
            return best_t
        g0 = np.full(rows.size, np.nan)
        g0[todo] = self.gap(rows[todo], t0[todo], links[todo])
        t1, g1 = t.copy(), g.copy()
        for _ in range(POLISH_ITERATIONS):
            todo &= (g1 != g0) & (best_g > POLISH_TOL)
            if not todo.any():
                break
            with np.errstate(divide="ignore", invalid="ignore"):
                t2 = np.clip(t1 - g1 * (t1 - t0) / (g1 - g0), low, high)
            g2 = np.full(rows.size, np.nan)
            g2[todo] = self.gap(rows[todo], t2[todo], links[todo])
            t0, g0 = np.where(todo, t1, t0), np.where(todo, g1, g0)
            t1, g1 = np.where(todo, t2, t1), np.where(todo, g2, g1)
            better = todo & (np.abs(g2) < best_g)
            best_t[better], best_g[better] = t2[better], np.abs(g2[better])
        return best_t


class _Touches:
    """A staged finger's touches waiting to be polished (:meth:`_Finger.polish`), polished
    together: a draw's polish does not depend on the others', so the draws that touch in
    several steps share one polish, whose cost is mostly per call. A waiting draw takes no
    step until its touch is polished, so every draw's closing is the one it would have
    alone."""

    def __init__(self, hand, finger: _Finger, t: np.ndarray, gaps: np.ndarray,
                 touched: np.ndarray, last: dict, queries: np.ndarray, rows: np.ndarray) -> None:
        self.hand, self.finger, self.t, self.gaps = hand, finger, t, gaps
        self.touched, self.last, self.queries, self.rows = touched, last, queries, rows
        self._waiting: list[tuple] = []
        self.waiting = 0

    def wait(self, who: np.ndarray, hits: np.ndarray, gap: np.ndarray, low: np.ndarray,
             high: np.ndarray) -> None:
        """Draws ``who`` (n,) touch with links ``hits`` (n, K) bool at their t, their least
        exact gap ``gap`` (n,); each one's polish stays in [low, high] (n,)."""
        self._waiting.append((who, hits, gap, low, high))
        self.waiting += who.size

    def due(self, closing: int) -> bool:
        """Whether the waiting touches are polished now, ``closing`` draws still stepping:
        when at least as many wait."""
        return self.waiting > 0 and self.waiting >= closing

    def stop(self, who: np.ndarray, k: int) -> None:
        """Link k of draws ``who`` touched at their t: it stops the joints it holds
        (:attr:`FingerPath.stops`)."""
        held, path = self.finger.held, self.finger.path
        self.touched[who, k] = True
        held[who] = np.where(path.stops[k], np.minimum(held[who], self.t[who, None]),
                             held[who])

    def polish_all(self) -> np.ndarray:
        """Polish every waiting touch; the touching links' exact pairs there become their
        last ones, and they stop their joints. Returns the draws (n,)."""
        who, hits, gap, low, high = (np.concatenate(a) for a in zip(*self._waiting,
                                                                      strict=True))
        self._waiting, self.waiting = [], 0
        finger, t = self.finger, self.t
        t[who] = finger.polish(who, t[who], gap, hits, low, high)
        polished = finger.poses(who, t[who])
        for k, link in enumerate(finger.path.links):
            sel = np.flatnonzero(hits[:, k])
            if not sel.size:
                continue
            d, fp, op, rounded = self.hand.exact(polished[link][sel], link)
            self.queries[self.rows[who[sel]]] += 1
            for store, value in zip(self.last[link], (polished[link][sel], d, fp, op, rounded),
                                    strict=True):
                store[who[sel]] = value
            self.gaps[who[sel], k] = d
            self.stop(who[sel], k)
        return who


def moving_end(ends: np.ndarray, held: np.ndarray) -> np.ndarray:
    """(n,) the t at which every closing joint that has not stopped (``held`` (n, J): inf)
    reaches its limit (``ends`` (n, J)); 0 where all have stopped."""
    return np.max(np.where(np.isfinite(held), 0.0, ends), axis=1)


def close_finger(hand, path: FingerPath, palm: np.ndarray, values0: dict, contact_tol: float,
                 queries: np.ndarray, rows: np.ndarray):
    """Close one finger of ``hand`` (a :class:`~kinegrasp_env.closing.generic_fast.
    FastRobotHand`) over draws (module docstring), the palm at object-frame poses (m, 4, 4)
    and the joints at ``values0`` (name -> (m,)); ``queries`` (counts of exact distances,
    by draw) is added to at ``rows`` (m,).

    Returns:
        (t (m,), gap (m,), values, last): the final parameter, the finger's gap (its links'
        least), every joint's final values, and per finger link its (pose (m, 4, 4),
        distance (m,), link point (m, 3), object point (m, 3), rounded (m,)) where it
        touched or was last measured exactly (distance inf where never).
    """
    m = palm.shape[0]
    finger = _Finger(hand, path, palm, values0)
    v0, held = finger.v0, finger.held
    last = {link: (np.empty((m, 4, 4)), np.full(m, np.inf), np.empty((m, 3)),
                   np.empty((m, 3)), np.zeros(m, dtype=bool)) for link in path.links}
    rates = path.rates
    starts, ends = path.limit_times(v0)
    t_turn = np.where(rates != 0, ends, np.inf).min(axis=1)
    motion = {link: None for link in path.links}
    if path.translating:  # each link's displacement per unit t, object frame
        moved = dict(finger.fixed)
        for j, name in enumerate(path.joints):
            moved[name] = v0[:, j] + rates[j]
        for link in path.links:
            motion[link] = (link_poses(palm, moved, finger.chains[link])[:, :3, 3]
                            - link_poses(palm, finger.fixed, finger.chains[link])[:, :3, 3])
    # a finger whose touches can leave joints closing (where it stops then matters): at least
    # STEP a step, its touches polished; another stops where it first comes within tolerance
    staged = not path.translating and not path.stops.all()
    least = STEP if staged else 0.0
    t, gaps = np.zeros(m), np.full((m, len(path.links)), np.inf)
    clear, tried = np.zeros(m), np.zeros(m)  # the last t without penetration, its step
    touched = np.zeros((m, len(path.links)), dtype=bool)
    taken = np.zeros(m, dtype=np.int64)  # the steps each draw has taken
    touches = _Touches(hand, finger, t, gaps, touched, last, queries, rows)
    hints = {link: hand.new_hints(link, m) for link in path.links}
    active = np.arange(m)
    while active.size or touches.waiting:
        if touches.due(active.size):  # polished, they go on with the others
            active = np.sort(np.concatenate([active, touches.polish_all()]))
        active = active[taken[active] < MAX_STEPS]
        stopped = np.isfinite(held[active])
        live = ~touched[active] & np.stack(  # (a, K): the links that still move
            [(~stopped[:, path.moves[k]]).any(axis=1) for k in range(len(path.links))],
            axis=1)
        keep = live.any(axis=1)
        active, live, stopped = active[keep], live[keep], stopped[keep]
        if active.size == 0:
            continue
        taken[active] += 1
        poses = finger.poses(active, t[active])
        lower, travel = np.full(live.shape, np.inf), np.zeros(live.shape)
        for k, link in enumerate(path.links):
            hint = hints[link][active]
            bound, far = hand.distance_bound(
                poses[link], link, None if motion[link] is None else motion[link][active],
                SHORT * contact_tol, hint)
            hints[link][active] = hint
            lower[:, k] = np.where(live[:, k], bound, np.inf)
            travel[:, k] = np.where(live[:, k] & ~stopped.any(axis=1), far, 0.0)
        near = np.flatnonzero(lower.min(axis=1) <= contact_tol)
        exact = {}
        for k, link in enumerate(path.links):  # the exact distance where the bound is near
            # (a link whose own bound is farther cannot come under NEAR x the tolerance)
            took = live[near, k] & (lower[near, k] <= NEAR * contact_tol)
            if took.any():
                d, fp, op = np.full(near.size, np.inf), np.empty((near.size, 3)), \
                    np.empty((near.size, 3))
                rounded = np.zeros(near.size, dtype=bool)
                d[took], fp[took], op[took], rounded[took] = hand.exact(
                    poses[link][near[took]], link, NEAR * contact_tol)
                exact[k] = (took, d, fp, op, rounded)
                queries[rows[active[near[took]]]] += 1
        deep = np.zeros(active.size, dtype=bool)  # a step too far: halved, tried again
        hits = np.zeros(live.shape, dtype=bool)
        for k, (took, d, *_) in exact.items():
            deep[near[took & (d < -contact_tol)]] = True
            hits[near[took & (d <= contact_tol)], k] = True
            lower[near, k] = np.where(took & (d < NEAR * contact_tol), d, lower[near, k])
        deep &= tried[active] > 0
        hits &= ~deep[:, None]
        new_touch = hits.any(axis=1)
        deferred = hits if staged else np.zeros_like(hits)  # stored once polished
        if staged and new_touch.any():  # the touch waits to be polished to a zero gap
            idx = np.flatnonzero(new_touch)
            who = active[idx]
            t_end = moving_end(ends[who], held[who])
            touches.wait(who, hits[idx],
                         np.min(np.where(hits[idx], lower[idx], np.inf), axis=1),
                         *polish_window(t[who], t_end))
        for k, link in enumerate(path.links):
            if k not in exact:
                continue
            took, d, fp, op, rounded = exact[k]
            took = took & ~deep[near] & ~deferred[near, k]
            for store, value in zip(last[link], (poses[link][near], d, fp, op, rounded),
                                    strict=True):
                store[active[near[took]]] = value[took]
            touches.stop(active[hits[:, k] & ~deferred[:, k]], k)
        gaps[active] = np.where(live & ~deep[:, None], lower, gaps[active])
        back = active[deep]
        tried[back] *= 0.5
        t[back] = clear[back] + tried[back]
        t_end = moving_end(ends[active], held[active])
        go = ~new_touch & ~deep & (t[active] < t_end)
        lower[touched[active]] = np.inf  # a link that touched no longer bounds the step
        turn = np.maximum(t_turn[active] - t[active], 0.0)
        # each link's bound by the joints still turning (a, K), up to a joint's limit
        turning, room = path.turning(held[active], t[active], starts[active], ends[active])
        speed = np.maximum(path.speed_bounds(turning), 1e-9)
        step = np.minimum(np.min(np.maximum(np.maximum(lower, 0.0) / speed,
                                            np.minimum(travel, turn[:, None])), axis=1), room)
        now = active[go]
        clear[now] = t[now]
        tried[now] = np.minimum(np.maximum(step[go], least), t_end[go] - t[now])
        t[now] += tried[now]
        # a touch: the rest next (a staged one once polished); a deep step: again
        active = active[go | deep | (new_touch & (not staged))]
    values = dict(values0)
    values.update(finger.values(np.arange(m), t))
    return t, gaps.min(axis=1), values, last
