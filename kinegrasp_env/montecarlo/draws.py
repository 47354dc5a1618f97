"""Per-draw results of any engine of any robot (:class:`DrawBatch`).

Every engine (reference, fast, physics; the default robot's and a description robot's)
returns its draws in this one format, so what reads draws (statistics, hold checks, plots,
reports) reads them alike whichever engine and robot made them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from kinegrasp_env.physics.protocol import GRAVITY_PHASES

#: What a draw ends in (:attr:`DrawBatch.outcome` indexes it).
OUTCOMES: tuple[str, ...] = ("start_collision", "missed", "no_force_closure", "force_closure")
START_COLLISION, MISSED, NO_FORCE_CLOSURE, FORCE_CLOSURE = range(4)


def provisional_outcomes(start_collision: np.ndarray, missed: np.ndarray,
                         contact_counts: np.ndarray) -> np.ndarray:
    """(n,) int8 outcomes of n closings before scoring (start_collision (n,) bool, missed
    (n, F) bool, contact_counts (n,)): start collision, missed (a finger missed, or fewer than
    two contacts) or no force closure (a candidate)."""
    out = np.full(len(start_collision), NO_FORCE_CLOSURE, dtype=np.int8)
    out[np.any(missed, axis=1) | (np.asarray(contact_counts) < 2)] = MISSED
    out[np.asarray(start_collision, dtype=bool)] = START_COLLISION
    return out


@dataclass
class DrawBatch:
    """Per-draw results of n draws with k contact slots and H hand joints.

    Attributes:
        outcome: (n,) int8 index into :data:`OUTCOMES`.
        quality: (n,) Q (0 unless force closure).
        n_contacts: (n,) contacts found (at most k are kept).
        points, normals: (n, k, 3) contacts in the object frame (normals inward), NaN-padded.
        finger, link: (n, k) int8 finger index and link index within it, -1 padded.
        hand: (n, H) the closed hand: each actuated hand joint (the description's
            ``hand_joints`` order; radians, metres for a prismatic joint) where the closing
            left it, the pre-shape's joints as they were; NaN where the hand did not close
            (start collision) or the engine does not report it. With the draw's arm joints it
            is the final configuration.
        held: (n, 6) bool, the static hold check's verdict per load (each gravity
            direction of :data:`~kinegrasp_env.physics.protocol.GRAVITY_PHASES`)
            (:class:`~kinegrasp_env.montecarlo.hold_check.StaticHoldCheck`; all False where
            the engine does not check it).
        push: (n,) metres a coupled pair of jaws would push the object before both touch
            (:func:`~kinegrasp_env.closing.coupled_jaws.jaw_push`; NaN for other hands, and
            where a jaw missed).
    """

    outcome: np.ndarray
    quality: np.ndarray
    n_contacts: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    finger: np.ndarray
    link: np.ndarray
    hand: np.ndarray
    held: np.ndarray
    push: np.ndarray

    @classmethod
    def empty(cls, n: int, k: int, hand_joints: int) -> DrawBatch:
        """n draws of k contact slots and ``hand_joints`` hand joints, none closed yet."""
        return cls(np.zeros(n, np.int8), np.zeros(n), np.zeros(n, np.int16),
                   np.full((n, k, 3), np.nan), np.full((n, k, 3), np.nan),
                   np.full((n, k), -1, np.int8), np.full((n, k), -1, np.int8),
                   np.full((n, hand_joints), np.nan), np.zeros((n, len(GRAVITY_PHASES)), bool),
                   np.full(n, np.nan))

    @classmethod
    def concatenate(cls, batches: list[DrawBatch]) -> DrawBatch:
        """The draws of ``batches`` (at least one) one after the other."""
        return cls(*(np.concatenate([getattr(b, f.name) for b in batches])
                     for f in fields(cls)))

    def __len__(self) -> int:
        return self.outcome.size

    def take(self, rows) -> DrawBatch:
        """The draws of ``rows`` (an index array or a slice), in that order (a slice gives
        views)."""
        return DrawBatch(*(getattr(self, f.name)[rows] for f in fields(self)))

    def part(self, start: int, stop: int) -> DrawBatch:
        """Draws start .. stop - 1 (views)."""
        return self.take(slice(start, stop))

    def put(self, rows: np.ndarray, other: DrawBatch) -> None:
        """Write ``other``'s draws into rows ``rows`` (len(other),) of this batch."""
        for f in fields(self):
            getattr(self, f.name)[rows] = getattr(other, f.name)

    def without_contacts(self) -> DrawBatch:
        """The draws' outcome, Q, contact count, static hold verdicts and push alone (no
        contact slots, no hand joints: ``points`` (n, 0, 3), ``hand`` (n, 0)): what their
        statistics need, about 25 bytes a draw."""
        n = len(self)
        return replace(self, points=np.empty((n, 0, 3)), normals=np.empty((n, 0, 3)),
                       finger=np.empty((n, 0), np.int8), link=np.empty((n, 0), np.int8),
                       hand=np.empty((n, 0)))

    @property
    def holds(self) -> np.ndarray:
        """(n,) bool: the static hold check held every load."""
        return self.held.all(axis=1)
