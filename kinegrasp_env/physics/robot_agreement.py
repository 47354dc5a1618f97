"""The physics closing as a check of the kinematic jaw-closing model, for any description
robot: the same configuration closed by the holding test's motors on the pinned object
(:meth:`~kinegrasp_env.physics.robot_hold.RobotHold.close_hand`, before any grip or
release) and by the kinematic reference closing
(:meth:`~kinegrasp_env.closing.generic_reference.RobotWorld.auto_close`), their contacts
paired by (finger, link) and compared in the object frame: the distance between the contact
points (metres) and the angle between the normals (radians).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.physics.robot_hold import RobotHold


@dataclass(frozen=True)
class ContactPair:
    """One finger link's contact in both closings (object frame).

    Attributes:
        finger, link: the finger (index into the description's ``fingers``) and its link.
        distance: between the two contact points, metres.
        angle: between the two normals, radians.
    """

    finger: int
    link: int
    distance: float
    angle: float


@dataclass(frozen=True)
class ClosingAgreement:
    """One configuration's two closings.

    Attributes:
        pairs: the contacts found by both, paired.
        physics_only, kinematic_only: (finger, link) of contacts found by one closing only.
        start_collision: (physics, kinematic) start collisions.
    """

    pairs: tuple[ContactPair, ...]
    physics_only: tuple[tuple[int, int], ...]
    kinematic_only: tuple[tuple[int, int], ...]
    start_collision: tuple[bool, bool]

    @property
    def max_distance(self) -> float:
        """The largest point distance of the pairs, metres (NaN: no pair)."""
        return max((p.distance for p in self.pairs), default=float("nan"))

    @property
    def max_angle(self) -> float:
        """The largest normal angle of the pairs, radians (NaN: no pair)."""
        return max((p.angle for p in self.pairs), default=float("nan"))


def compare(physics: RobotCloseResult, kinematic: RobotCloseResult) -> ClosingAgreement:
    """Pair two closings' contacts (object frame) by (finger, link) and compare them."""
    ours = {(c.finger, c.link): c for c in physics.contacts}
    theirs = {(c.finger, c.link): c for c in kinematic.contacts}
    pairs = []
    for key in sorted(set(ours) & set(theirs)):
        a, b = ours[key], theirs[key]
        cosine = float(np.clip(np.dot(a.normal, b.normal), -1.0, 1.0))
        pairs.append(ContactPair(*key, float(np.linalg.norm(a.point - b.point)),
                                 float(np.arccos(cosine))))
    return ClosingAgreement(tuple(pairs), tuple(sorted(set(ours) - set(theirs))),
                            tuple(sorted(set(theirs) - set(ours))),
                            (physics.start_collision, kinematic.start_collision))


def closing_agreement(simulator: RobotHold, kinematic: RobotWorld,
                      q: np.ndarray) -> ClosingAgreement:
    """Close configuration q (dof,) both ways (module docstring) and compare; the two worlds
    must hold the same robot and object."""
    if (simulator.description.name != kinematic.description.name
            or simulator.world.obj.name != kinematic.obj.name):
        raise ValueError("the physics and the kinematic world hold different robots or objects")
    physics, _ = simulator.close_hand(q)
    return compare(physics, kinematic.auto_close(q))
