"""The rules of the auto-close, shared by the reference and the fast closing: the tolerances
and steps, the step a two-phalanx finger's speed bounds allow (:func:`closing_travel`), the
secant polish (:func:`secant_root`), and what the default robot's physics closing returns
(:class:`Contact`, :class:`CloseResult`). The closings that apply them:
:mod:`kinegrasp_env.closing.generic_reference` (pybullet's distances, one draw at a time) and
:mod:`kinegrasp_env.closing.generic_fast` (a batch of draws; fingers of two capsule phalanxes
by :mod:`kinegrasp_env.closing.close_kernel` against the distance grid).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.closing.close_result import RobotCloseResult, RobotContact
from kinegrasp_env.robot.default_robot import HAND_JOINTS

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

    def robot_result(self) -> RobotCloseResult:
        """The same closing as a closing of the default robot's description (what every
        robot's engine scores: :func:`~kinegrasp_env.montecarlo.description_engine.score_batch`):
        the contacts in their order (each finger's links as the description lists them,
        proximal then distal), the final hand joints by name."""
        fingers = len(self.missed)
        joints = {} if self.joints is None else dict(zip(HAND_JOINTS, self.joints.tolist(),
                                                         strict=True))
        return RobotCloseResult(
            self.start_collision,
            [RobotContact(c.finger, c.link, c.point, c.normal, 0.0) for c in self.contacts],
            tuple(self.missed), np.full(fingers, np.nan), np.zeros(fingers), joints,
            self.iterations)


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
