"""GraspIt-style kinematic auto-close of the three-finger hand, and contact extraction.

From the pre-grasp hand configuration the proximal and distal flexion joints of every finger
close together at the same rate (each stops at its own upper limit). When a link touches the
object, the joints proximal to it stop and the joints distal to it keep closing: a proximal
contact freezes the proximal joint while the distal joint goes on; a distal contact ends the
finger. Each contact is located by stepping (conservative advancement: a step never exceeds
the one that could close the current gap: each moving link's gap over a bound on its
speed, :func:`closing_travel`; but at least ``STEP`` radians) and then bisection
until the gap is within ``CONTACT_TOL`` (0.2 mm); the contact is then polished by secant
steps on the exact gap to where it is zero (:func:`secant_root`, to 1e-9 m), so the result
does not depend on how the bracket was reached. A finger whose joints all reach their limits
without touching has missed. The coupled spread keeps its pre-shape value.

pybullet measures the gaps (one ``getClosestPoints`` per moving finger link and step: the
conservative advance, the part of this engine that is independent of the fast engine's
distance grid); within ``EXACT_BAND`` of contact a finger capsule's gap is recomputed exactly
from its axis and the object's convex parts (pybullet's convex-hull distances were measured
up to 1 mm off at edges), so contact decisions are exact. The contact itself is the exact
closest pair (:mod:`kinegrasp_env.closing.hand_geometry`): the point on the object and, as
normal, the face's inward normal or, at an edge or corner, the exact separating direction
(pybullet's own normal is off by degrees there).

The hand's joints in pybullet and the placement of its capsule axes:
:mod:`kinegrasp_env.closing.hand_probe`; the constants and rules shared with the fast closing:
:mod:`kinegrasp_env.closing.close_rules`.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_rules import (
    CONTACT_TOL,
    EXACT_BAND,
    MAX_ITERATIONS,
    POLISH_ITERATIONS,
    POLISH_PROBE,
    POLISH_RANGE,
    POLISH_TOL,
    QUERY_DISTANCE,
    START_TOL,
    STEP,
    CloseResult,
    Contact,
    LinkSpeeds,
    closing_speeds,
    closing_travel,
    finger_geometry,
    secant_root,
)
from kinegrasp_env.closing.hand_geometry import pair_contacts
from kinegrasp_env.closing.hand_probe import HandProbe, finger_capsules, hand_joint_values
from kinegrasp_env.robot.default_robot import FINGERS
from kinegrasp_env.world.sim import GraspWorld

#: Importable from here too (the reference closing's constants, result types and helpers).
__all__ = ["CONTACT_TOL", "EXACT_BAND", "MAX_ITERATIONS", "POLISH_ITERATIONS", "POLISH_PROBE",
           "POLISH_RANGE", "POLISH_TOL", "QUERY_DISTANCE", "START_TOL", "STEP", "CloseResult",
           "Contact", "HandProbe", "LinkSpeeds", "auto_close", "closing_speeds",
           "closing_travel", "finger_capsules", "hand_joint_values", "secant_root"]


class _Finger:
    """Closing state of one finger: a 1-D path per phase, bisection bracket [t_lo, t_hi]."""

    def __init__(self, index: int, prox: float, dist: float, geometry,
                 link_index: dict[str, int]) -> None:
        _, _, self.upper_p, self.upper_d = geometry
        self.index = index
        self.joints, self.links = FINGERS[index][:2], FINGERS[index][2:]
        self.link_ids = tuple(link_index[link] for link in self.links)
        self.start = [min(prox, self.upper_p), min(dist, self.upper_d)]
        self.phase = 1  # 1: both joints close, 2: only the distal joint closes
        self.t = 0.0
        self.t_lo, self.t_hi = 0.0, None
        self.done = False
        self.missed = False
        #: touching links: (link, closest pair rows of :meth:`HandProbe.pairs`), see _contacts
        self.touches: list[tuple[int, tuple]] = []
        self.speeds = np.array(closing_speeds())
        self.last: tuple | None = None  # (state key, pairs) of the last exact evaluation

    @property
    def moving_links(self) -> tuple[int, ...]:
        return (0, 1) if self.phase == 1 else (1,)

    @property
    def t_max(self) -> float:
        if self.phase == 1:
            return max(self.upper_p - self.start[0], self.upper_d - self.start[1], 0.0)
        return max(self.upper_d - self.start[1], 0.0)

    def values(self) -> dict[str, float]:
        prox = self.start[0] + (self.t if self.phase == 1 else 0.0)
        return {self.joints[0]: min(prox, self.upper_p),
                self.joints[1]: min(self.start[1] + self.t, self.upper_d)}

    def exact_at(self, probe: HandProbe, t: float) -> tuple:
        """Closest pairs (see :meth:`HandProbe.pairs`) and exact gaps (m,) of the moving links
        with the finger at parameter t (the last evaluation is reused when t is the same)."""
        self.t = t
        key = (self.phase, self.start[0], self.start[1], t)
        if self.last is None or self.last[0] != key:
            values = self.values()
            links = self.moving_links
            pairs = probe.pairs(probe.axes(self.index, values[self.joints[0]],
                                           values[self.joints[1]], links))
            self.last = (key, pairs, pairs[2] - probe.radii(self.index, links))
        return self.last[1:]

    def _polish(self, probe: HandProbe, gap: float) -> tuple:
        """Move t to the root of the exact gap (see :func:`secant_root`); pairs and gaps
        there."""
        t_min = max(self.t - POLISH_RANGE, 0.0)
        root = secant_root(lambda t: float(self.exact_at(probe, t)[1].min()), self.t, gap,
                           t_min, self.t_max)
        return self.exact_at(probe, root)

    def update(self, gaps: dict[int, float], probe: HandProbe) -> None:
        """Advance from the gaps (pybullet link index -> metres) measured at the current t."""
        gap_p, gap_d = (gaps.get(link, QUERY_DISTANCE) for link in self.link_ids)
        gap = min(gap_p, gap_d) if self.phase == 1 else gap_d
        bracket_closed = self.t_hi is not None and self.t_hi - self.t_lo < 1e-9
        if -CONTACT_TOL <= gap <= CONTACT_TOL or (bracket_closed and gap <= CONTACT_TOL):
            self._touch(probe, gap)
            return
        if gap > CONTACT_TOL:
            self.t_lo = self.t
            if self.t_hi is None:
                if self.t >= self.t_max:  # every joint at its limit, no contact
                    self.done = True
                    self.missed = not self.touches
                    return
                travel = closing_travel(gap_p, gap_d, self.phase, self.speeds)
                self.t = min(self.t + max(travel, STEP), self.t_max)
                return
        else:
            self.t_hi = self.t
        self.t = 0.5 * (self.t_lo + self.t_hi)

    def _touch(self, probe: HandProbe, gap: float) -> None:
        """A link is touching: polish, record the contacts, end the finger or go on with the
        distal joint alone."""
        pairs, link_gaps = self._polish(probe, gap)
        touching = [row for row in range(len(link_gaps)) if link_gaps[row] <= CONTACT_TOL]
        for row in touching:
            self.touches.append((self.moving_links[row], tuple(p[row] for p in pairs)))
        if any(self.moving_links[row] == 1 for row in touching):
            self.done = True
            return
        # proximal contact: freeze the proximal joint, the distal one goes on
        values = self.values()
        self.start = [values[self.joints[0]], values[self.joints[1]]]
        self.phase, self.t, self.t_lo, self.t_hi = 2, 0.0, 0.0, None
        if self.t_max <= 0.0:
            self.done = True
        else:
            self.t = min(STEP, self.t_max)


def _contacts(obj, fingers: list[_Finger]) -> list[Contact]:
    """The exact contacts of every touching finger link (see
    :mod:`kinegrasp_env.closing.hand_geometry`), from their closest pairs, in one batch."""
    found = [(f.index, link, pair) for f in fingers for link, pair in f.touches]
    if not found:
        return []
    on_obj, on_seg, dist, part = (np.array([pair[k] for _, _, pair in found]) for k in range(4))
    points, normals = pair_contacts(obj, on_obj, on_seg, dist, part)
    return [Contact(finger, link, points[i], normals[i])
            for i, (finger, link, _) in enumerate(found)]


def _exact_gaps(probe: HandProbe, links: list[int], flexion) -> list[float]:
    """Exact gaps (metres) of capsule links (pybullet link indices), each finger at
    ``flexion[finger]`` = (proximal, distal) radians."""
    owners = [probe.capsules[link] for link in links]
    axes = np.concatenate([probe.axes(finger, *flexion[finger], [link])
                           for finger, link in owners])
    radii = np.array([probe.chains[finger].radii[link] for finger, link in owners])
    return (probe.pairs(axes)[2] - radii).tolist()


def _start_collision(probe: HandProbe, preshape: np.ndarray) -> bool:
    """Whether the hand, as placed, penetrates the object by more than ``START_TOL``
    (pybullet's distance, or a finger capsule's exact gap within ``EXACT_BAND``)."""
    near: list[int] = []
    for rec in probe.world.closest(EXACT_BAND):
        if rec[3] in probe.capsules and rec[8] >= -EXACT_BAND:
            if rec[3] not in near:
                near.append(rec[3])
        elif rec[8] < -START_TOL:
            return True
    flexion = [(preshape[1 + 2 * i], preshape[2 + 2 * i]) for i in range(3)]
    return any(gap < -START_TOL for gap in _exact_gaps(probe, near, flexion)) if near else False


def _measure(probe: HandProbe, active: list[_Finger]) -> dict[int, float]:
    """Gaps (pybullet link index -> metres) of the active fingers' moving links at the
    current joint values: pybullet's distance (one query per link: a query of the whole hand
    costs as much as six), exact within ``EXACT_BAND``."""
    gaps: dict[int, float] = {}
    near = []
    for finger in active:
        for link in finger.moving_links:
            index = finger.link_ids[link]
            records = probe.closest_points(probe.hand, probe.body, QUERY_DISTANCE,
                                           linkIndexA=index)
            if records:
                gaps[index] = gap = min(rec[8] for rec in records)
                if -EXACT_BAND <= gap <= EXACT_BAND:
                    near.append(index)
    if near:  # near contact: the exact gap decides
        flexion = {}
        for f in active:
            values = f.values()
            flexion[f.index] = (values[f.joints[0]], values[f.joints[1]])
        gaps.update(zip(near, _exact_gaps(probe, near, flexion), strict=True))
    return gaps


def auto_close(world: GraspWorld, root_pose: np.ndarray, preshape: np.ndarray) -> CloseResult:
    """Close the hand placed at ``root_pose`` from ``preshape`` until contact; ``world`` is
    left with the hand at the closed configuration (or the pre-shape on a start collision).

    Args:
        world: the grasp world (hand and object).
        root_pose: (4, 4) world pose of the hand root (the arm's flange frame).
        preshape: (7,) hand DOF: spread, f1 proximal, f1 distal, f2 ..., f3 ... (radians).
    """
    preshape = np.asarray(preshape, dtype=float)
    probe = HandProbe(world)
    probe.set_hand(root_pose, preshape)
    if _start_collision(probe, preshape):
        return CloseResult(start_collision=True)
    geometry = finger_geometry()
    fingers = [_Finger(i, preshape[1 + 2 * i], preshape[2 + 2 * i], geometry,
                       world.link_index) for i in range(3)]
    iterations = 0
    while iterations < MAX_ITERATIONS:
        active = [f for f in fingers if not f.done]
        if not active:
            break
        values: dict[str, float] = {}
        for finger in active:
            values.update(finger.values())
        probe.set_joints(values)
        gaps = _measure(probe, active)
        iterations += 1
        for finger in active:
            finger.update(gaps, probe)
    joints = np.array(preshape, dtype=float)
    final: dict[str, float] = {}
    for f in fingers:  # out of iterations: whatever was found stands
        f.done = True
        final.update(f.values())
        joints[1 + 2 * f.index], joints[2 + 2 * f.index] = final[f.joints[0]], final[f.joints[1]]
    probe.set_joints(final)  # the world shows the closed hand
    missed = tuple(f.missed for f in fingers)
    return CloseResult(False, _contacts(world.obj, fingers), missed, joints, iterations)
