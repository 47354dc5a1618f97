"""GraspIt-style kinematic auto-close of the three-finger hand, and contact extraction.

From the pre-grasp hand configuration the proximal and distal flexion joints of every finger
close together at the same rate (each stops at its own upper limit). When a link touches the
object, the joints proximal to it stop and the joints distal to it keep closing: a proximal
contact freezes the proximal joint while the distal joint goes on; a distal contact ends the
finger. Each contact is located by stepping (conservative advancement: a step never exceeds
the one that could close the current gap, but is at least ``STEP`` radians) and then bisection
until the gap is within ``CONTACT_TOL`` (0.2 mm); the contact is then polished by secant
steps on the exact gap to where it is zero (:func:`secant_root`, to 1e-9 m), so the result
does not depend on how the bracket was reached. A finger whose joints all reach their limits
without touching has missed. The coupled spread keeps its pre-shape value.

pybullet measures the gaps; within ``EXACT_BAND`` of contact a finger capsule's gap is
recomputed exactly from its axis and the object's convex parts (pybullet's convex-hull
distances were measured up to 1 mm off at edges), so contact decisions are exact. The contact
itself is the exact closest pair (:mod:`kinegrasp_env.closing.hand_geometry`): the point on the
object and, as normal, the face's inward normal or, at an edge or corner, the exact
separating direction (pybullet's own normal is off by degrees there).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from kinegrasp_env.closing.hand_geometry import Shape, capsule_contacts, hand_shapes
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.robot.model import FINGERS, HAND_JOINTS, kuka_sdh
from kinegrasp_env.world.sim import GraspWorld

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
#: Radius of the finger capsules plus margin, for the speed bound (metres).
_RADIUS_BOUND = 0.02
MAX_ITERATIONS = 400


@dataclass(frozen=True)
class Contact:
    """One finger-object contact (object frame).

    Attributes:
        finger: 0, 1, 2 (fingers f1, f2, f3).
        link: 0 proximal, 1 distal.
        point: (3,) on the object's surface, metres.
        normal: (3,) inward unit surface normal.
    """

    finger: int
    link: int
    point: np.ndarray
    normal: np.ndarray


@dataclass
class CloseResult:
    """Outcome of one auto-close.

    Attributes:
        start_collision: the hand penetrated the object before closing.
        contacts: contacts found (at most one per link).
        missed: per finger, True if it closed to its limits without touching.
        joints: final hand DOF (7,) in ``HAND_JOINTS`` order.
        iterations: collision queries used.
    """

    start_collision: bool
    contacts: list[Contact] = field(default_factory=list)
    missed: tuple[bool, bool, bool] = (False, False, False)
    joints: np.ndarray | None = None
    iterations: int = 0


def hand_joint_values(preshape: np.ndarray) -> dict[str, float]:
    """Every hand joint's value (coupled spread expanded) from the 7 hand DOF."""
    model = kuka_sdh()
    q = np.zeros(model.dof)
    q[model.index(HAND_JOINTS)] = preshape
    values = model.expand(q)
    return {name: float(values[name]) for name in values if not name.startswith("lbr_")}


@lru_cache(maxsize=1)
def _finger_geometry() -> tuple[float, float, float, float]:
    """(proximal length, distal length, upper limit proximal, upper limit distal)."""
    model = kuka_sdh()
    distal = model.joint("f1_distal").origin[:3, 3]
    tip = model.joint("f1_distal_to_tip").origin[:3, 3]
    return (float(np.linalg.norm(distal)), float(np.linalg.norm(tip)),
            model.joint("f1_proximal").upper, model.joint("f1_distal").upper)


def closing_speeds() -> tuple[float, float]:
    """Bounds on how fast any finger surface point moves per radian of closing (metres/rad):
    (phase 1, both joints closing; phase 2, the distal joint only)."""
    length_p, length_d, _, _ = _finger_geometry()
    reach_p = length_p + length_d + _RADIUS_BOUND
    reach_d = length_d + _RADIUS_BOUND
    return (length_p + _RADIUS_BOUND) + (reach_p + reach_d), reach_d


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


class _Finger:
    """Closing state of one finger: a 1-D path per phase, bisection bracket [t_lo, t_hi]."""

    def __init__(self, index: int, prox: float, dist: float, geometry) -> None:
        _, _, self.upper_p, self.upper_d = geometry
        self.index = index
        self.joints, self.links = FINGERS[index][:2], FINGERS[index][2:]
        self.start = [min(prox, self.upper_p), min(dist, self.upper_d)]
        self.phase = 1  # 1: both joints close, 2: only the distal joint closes
        self.t = 0.0
        self.t_lo, self.t_hi = 0.0, None
        self.done = False
        self.missed = False
        self.contacts: list[Contact] = []
        self.speed = dict(zip((1, 2), closing_speeds(), strict=True))

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

    def _exact_gaps(self, world: GraspWorld, t: float) -> dict[int, float]:
        """Exact gaps of the moving links with the finger at parameter t."""
        self.t = t
        world.set_joints(self.values())
        capsules = finger_capsules()[self.index]
        return {link: exact_gap(world, capsules[link]) for link in self.moving_links}

    def _polish(self, world: GraspWorld, gap: float) -> dict[int, float]:
        """Move t to the root of the exact gap (see :func:`secant_root`); gaps there."""
        t_min = max(self.t - POLISH_RANGE, 0.0)
        root = secant_root(lambda t: min(self._exact_gaps(world, t).values()), self.t, gap,
                           t_min, self.t_max)
        return self._exact_gaps(world, root)

    def update(self, gaps: dict[str, tuple[float, tuple | None]], world: GraspWorld) -> None:
        """Advance from the gaps measured at the current t."""
        moving = [(link, *gaps.get(self.links[link], (QUERY_DISTANCE, None)))
                  for link in self.moving_links]
        gap = min(g for _, g, _ in moving)
        bracket_closed = self.t_hi is not None and self.t_hi - self.t_lo < 1e-9
        if -CONTACT_TOL <= gap <= CONTACT_TOL or (bracket_closed and gap <= CONTACT_TOL):
            link_gaps = self._polish(world, gap)
            touching = [link for link in self.moving_links if link_gaps[link] <= CONTACT_TOL]
            for link in touching:
                self.contacts.append(_contact(world, self.index, link))
            if 1 in touching:
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
            return
        if gap > CONTACT_TOL:
            self.t_lo = self.t
            if self.t_hi is None:
                if self.t >= self.t_max:  # every joint at its limit, no contact
                    self.done = True
                    self.missed = not self.contacts
                    return
                self.t = min(self.t + max(gap / self.speed[self.phase], STEP), self.t_max)
                return
        else:
            self.t_hi = self.t
        self.t = 0.5 * (self.t_lo + self.t_hi)


def _axis(world: GraspWorld, shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    """(1, 3) end points of a capsule's axis in the object frame, at the current pose."""
    pose = world.obj.pose_inverse @ world.link_pose(shape.link)
    a, b = (pose[:3, :3] @ p + pose[:3, 3] for p in shape.axis_points())
    return a[None], b[None]


def exact_gap(world: GraspWorld, shape: Shape) -> float:
    """Exact gap (metres) of a finger capsule that does not cross the object."""
    return float(closest_to_segments(world.obj, *_axis(world, shape))[2][0] - shape.radius)


def _contact(world: GraspWorld, finger: int, link: int) -> Contact:
    """The exact contact of a touching finger link (see
    :mod:`kinegrasp_env.closing.hand_geometry`)."""
    point, normal = capsule_contacts(world.obj, *_axis(world, finger_capsules()[finger][link]))
    return Contact(finger, link, point[0], normal[0])


@lru_cache(maxsize=1)
def finger_capsules() -> tuple[tuple[Shape, Shape], ...]:
    """(proximal, distal) capsule of each finger."""
    shapes = {s.link: s for s in hand_shapes()}
    return tuple((shapes[f[2]], shapes[f[3]]) for f in FINGERS)


def auto_close(world: GraspWorld, root_pose: np.ndarray, preshape: np.ndarray) -> CloseResult:
    """Close the hand placed at ``root_pose`` from ``preshape`` until contact.

    Args:
        world: the grasp world (hand and object).
        root_pose: (4, 4) world pose of the hand root (the arm's flange frame).
        preshape: (7,) hand DOF: spread, f1 proximal, f1 distal, f2 ..., f3 ... (radians).
    """
    world.set_hand(root_pose, hand_joint_values(np.asarray(preshape, dtype=float)))
    capsule_links = {world.link_index[s.link]: s for pair in finger_capsules() for s in pair}
    for rec in world.closest(EXACT_BAND):
        shape = capsule_links.get(rec[3])
        gap = rec[8] if shape is None or rec[8] < -EXACT_BAND else exact_gap(world, shape)
        if gap < -START_TOL:
            return CloseResult(start_collision=True)
    geometry = _finger_geometry()
    fingers = [_Finger(i, preshape[1 + 2 * i], preshape[2 + 2 * i], geometry) for i in range(3)]
    link_names = {world.link_index[link]: link for f in fingers for link in f.links}
    iterations = 0
    while iterations < MAX_ITERATIONS:
        active = [f for f in fingers if not f.done]
        if not active:
            break
        values: dict[str, float] = {}
        for finger in active:
            values.update(finger.values())
        world.set_joints(values)
        gaps: dict[str, tuple[float, tuple | None]] = {}
        for rec in world.closest(QUERY_DISTANCE):
            name = link_names.get(rec[3])
            if name is not None and (name not in gaps or rec[8] < gaps[name][0]):
                gaps[name] = (rec[8], rec)
        for name, (gap, rec) in gaps.items():  # near contact: the exact gap decides
            if -EXACT_BAND <= gap <= EXACT_BAND:
                gaps[name] = (exact_gap(world, capsule_links[world.link_index[name]]), rec)
        iterations += 1
        for finger in active:
            finger.update(gaps, world)
    for finger in fingers:  # out of iterations: whatever was found stands
        finger.done = True
    joints = np.array(preshape, dtype=float)
    for f in fingers:
        values = f.values()
        joints[1 + 2 * f.index], joints[2 + 2 * f.index] = values[f.joints[0]], values[f.joints[1]]
    contacts = [c for f in fingers for c in f.contacts]
    return CloseResult(False, contacts, tuple(f.missed for f in fingers), joints, iterations)
