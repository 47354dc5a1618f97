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

The capsule axes of those exact gaps come from the hand URDF's kinematics in double precision
(:func:`zero_flexion_frames` once per pre-shape, then :func:`finger_axes` per evaluation), not
from pybullet's link states: ``getLinkState``'s link frame (its entries 4 and 5) carries
single-precision rounding (up to ~5e-7 per entry measured; pybullet's inertial frame, which
its collision shapes hang from, agrees with these axes to ~1e-15), which kept the secant
polish from reaching ``POLISH_TOL`` and cost two pybullet calls per evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.assets import asset_path
from kinegrasp_env.closing.finger_axes import finger_axes
from kinegrasp_env.closing.hand_geometry import Shape, hand_shapes, pair_contacts
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.model import FINGERS, HAND_JOINTS, kuka_sdh, load_urdf
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


class LinkSpeeds(NamedTuple):
    """Bounds on how fast any surface point of a finger link moves per radian of closing
    (metres/rad): the proximal and the distal link while both joints close (phase 1), the
    distal link while only the distal joint closes (phase 2; the proximal link is then still).
    """

    proximal: float
    distal: float
    distal_alone: float


def closing_speeds() -> LinkSpeeds:
    """:class:`LinkSpeeds` of the hand's fingers: a point at distance r from a joint axis
    turning at 1 rad per radian of t moves at most r per radian; the proximal link's points
    lie within length_p + R of the proximal axis, the distal link's within
    length_p + length_d + R of it and length_d + R of the distal axis (R: a bound on the
    capsule radius)."""
    length_p, length_d, _, _ = _finger_geometry()
    reach_p = length_p + length_d + _RADIUS_BOUND
    reach_d = length_d + _RADIUS_BOUND
    return LinkSpeeds(length_p + _RADIUS_BOUND, reach_p + reach_d, reach_d)


@jit.kernel(_nrt=False)
def closing_travel(gap_p: float, gap_d: float, phase: int, speeds: np.ndarray) -> float:
    """Largest closing step (radians) before a moving link could touch: each link's gap
    (metres) over its speed bound, the smaller; the proximal link counts in phase 1 only.
    speeds: (3,) the :class:`LinkSpeeds` as an array. Compiled: the fast engine's closing
    loop calls it too (its vectorized twin, ``FastHand._travel``, repeats the arithmetic).
    (One bound for the whole finger, the sum of the three reaches, took 1.4-3.5x smaller
    steps: 7-9% more closing time in the fast engine.)"""
    if phase != 1:
        return gap_d / speeds[2]
    return min(gap_d / speeds[1], gap_p / speeds[0])


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


@dataclass(frozen=True)
class FingerChain:
    """What places one finger's capsule axes, from the hand URDF (the file pybullet loads).

    Attributes:
        axis_p, axis_d: (3,) unit axes of the proximal and distal joints.
        distal_origin: (4, 4) the distal joint's origin in the proximal link frame.
        ends_p, ends_d: (2, 3) capsule axis end points in the proximal and distal link frames,
            metres.
        radii: (2,) capsule radii (proximal, distal), metres.
    """

    axis_p: np.ndarray
    axis_d: np.ndarray
    distal_origin: np.ndarray
    ends_p: np.ndarray
    ends_d: np.ndarray
    radii: np.ndarray


@lru_cache(maxsize=1)
def hand_kinematics() -> Kinematics:
    """Forward kinematics of the hand alone (``sdh_hand.urdf``, root = the flange frame)."""
    return Kinematics(load_urdf(asset_path("robots", "sdh_hand.urdf"), actuated=HAND_JOINTS))


@lru_cache(maxsize=1)
def finger_chains() -> tuple[FingerChain, ...]:
    """The :class:`FingerChain` of fingers 1, 2, 3."""
    model = hand_kinematics().model
    chains = []
    for (prox, dist, _, _), (shape_p, shape_d) in zip(FINGERS, finger_capsules(), strict=True):
        chains.append(FingerChain(
            model.joint(prox).axis, model.joint(dist).axis, model.joint(dist).origin,
            np.array(shape_p.axis_points()), np.array(shape_d.axis_points()),
            np.array([shape_p.radius, shape_d.radius])))
    return tuple(chains)


@lru_cache(maxsize=64)
def zero_flexion_frames(spread: float) -> np.ndarray:
    """(3, 4, 4) frames of the fingers' proximal links at zero flexion, in the hand root
    frame, for a spread (radians); cached: a Monte Carlo run repeats one pre-shape."""
    q = np.zeros(len(HAND_JOINTS))
    q[HAND_JOINTS.index("f1_spread")] = spread
    frames = hand_kinematics().forward(q, [f[2] for f in FINGERS])
    out = np.stack([frames[f[2]][0] for f in FINGERS])
    out.setflags(write=False)  # shared by the cache
    return out


class HandProbe:
    """The hand of one auto-close: its pybullet joints and its finger capsules' exact gaps.

    pybullet's joints are reset only where the value changed (resetting one to its current
    value leaves the state as it was). A finger capsule's exact closest pair with the object
    comes from its axis, placed by the proximal joint frame of the draw (hand root and spread,
    object frame) and the finger's two flexions (:func:`finger_axes`), not from pybullet.
    """

    def __init__(self, world: GraspWorld) -> None:
        self.world, self.obj = world, world.obj
        self.hand = world.bodies["hand"]
        self.body = world.bodies["object"]
        self.reset_joints = world.bullet.resetJointStatesMultiDof  # bound once per close
        self.closest_points = world.bullet.getClosestPoints
        self.joint_index = world.joint_index
        self.joints: dict[int, float] = {}
        self.chains = finger_chains()
        #: pybullet link index -> (finger, link 0 proximal / 1 distal)
        self.capsules = {world.link_index[f[2 + link]]: (i, link)
                         for i, f in enumerate(FINGERS) for link in (0, 1)}
        self.frames = np.empty((3, 4, 4))

    def set_hand(self, root_pose: np.ndarray, preshape: np.ndarray) -> None:
        """Place the hand root ((4, 4) world) and set every hand joint from the pre-shape."""
        joints = hand_joint_values(preshape)
        self.world.set_hand(root_pose, joints)
        self.joints = {self.joint_index[name]: float(v) for name, v in joints.items()}
        self.frames = self.obj.pose_inverse @ root_pose @ zero_flexion_frames(float(preshape[0]))

    def set_joints(self, values: dict[str, float]) -> None:
        """Set hand joints by name (radians) in pybullet, those that changed in one call."""
        joints, targets = [], []
        for name, value in values.items():
            joint, value = self.joint_index[name], float(value)
            if self.joints.get(joint) != value:
                joints.append(joint)
                targets.append([value])
                self.joints[joint] = value
        if joints:
            self.reset_joints(self.hand, joints, targets)

    def axes(self, finger: int, prox: float, dist: float, links) -> np.ndarray:
        """Capsule axes (m, 2, 3) [a, b] of a finger's links (0 proximal, 1 distal) at
        flexions prox, dist (radians), object frame."""
        chain = self.chains[finger]
        ends = finger_axes(self.frames[finger:finger + 1], chain.axis_p, np.array([prox]),
                           chain.distal_origin, chain.axis_d, np.array([dist]),
                           chain.ends_p, chain.ends_d)[0].reshape(2, 2, 3)
        return ends[list(links)]

    def pairs(self, axes: np.ndarray) -> tuple[np.ndarray, ...]:
        """Exact closest pairs of capsule axes (m, 2, 3) and the object: (on the object
        (m, 3), on the axis (m, 3), axis distance (m,), part (m,))."""
        return closest_to_segments(self.obj, axes[:, 0], axes[:, 1])

    def radii(self, finger: int, links) -> np.ndarray:
        """Capsule radii (m,) of a finger's links (0 proximal, 1 distal), metres."""
        return self.chains[finger].radii[list(links)]


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


@lru_cache(maxsize=1)
def finger_capsules() -> tuple[tuple[Shape, Shape], ...]:
    """(proximal, distal) capsule of each finger."""
    shapes = {s.link: s for s in hand_shapes()}
    return tuple((shapes[f[2]], shapes[f[3]]) for f in FINGERS)


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
    geometry = _finger_geometry()
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
