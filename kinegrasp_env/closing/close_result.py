"""What one closing of a description robot's hand gives: its contacts
(:class:`RobotContact`) and the closing's result (:class:`RobotCloseResult`), whichever
engine closed it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class RobotContact:
    """One finger-object contact (object frame).

    Attributes:
        finger: index into the description's ``fingers``.
        link: index into that finger's ``links``.
        point: (3,) on the object's surface, metres.
        normal: (3,) unit normal into the object.
        distance: pybullet's gap of the pair, metres (<= CONTACT_TOL).
    """

    finger: int
    link: int
    point: np.ndarray
    normal: np.ndarray
    distance: float


@dataclass
class RobotCloseResult:
    """One closing.

    Attributes:
        start_collision: a robot link penetrated the object at q.
        contacts: the contacts (at most one per finger link).
        missed: per finger, True when it closed to its limits without touching.
        gaps: (fingers,) final gap of each finger, metres (NaN after a start collision).
        travel: (fingers,) final closing parameter t of each finger.
        joints: final value of every closing joint (name -> value).
        queries: link distances measured (pybullet's closest points or exact pairs).
    """

    start_collision: bool
    contacts: list[RobotContact] = field(default_factory=list)
    missed: tuple[bool, ...] = ()
    gaps: np.ndarray = field(default_factory=lambda: np.empty(0))
    travel: np.ndarray = field(default_factory=lambda: np.empty(0))
    joints: dict[str, float] = field(default_factory=dict)
    queries: int = 0

    @classmethod
    def collided(cls, fingers: int, queries: int = 0) -> RobotCloseResult:
        """A closing of a hand of ``fingers`` fingers that starts in collision."""
        return cls(True, queries=queries, missed=(False,) * fingers,
                   gaps=np.full(fingers, np.nan), travel=np.zeros(fingers))
