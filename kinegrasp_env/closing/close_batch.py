"""Closings of many draws as arrays (:class:`RobotCloseBatch`): what the batched closing of a
description robot gives, one row per draw and one row per contact, and the per-draw
:class:`~kinegrasp_env.closing.close_result.RobotCloseResult` view of it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult, RobotContact

__all__ = ["RobotCloseBatch"]


@dataclass
class RobotCloseBatch:
    """n closings of a hand with F fingers and C contacts in all.

    Attributes:
        start_collision: (n,) bool, a link penetrated the object at q.
        missed: (n, F) bool, the finger closed to its limits without touching.
        gaps: (n, F) final gap of each finger, metres (NaN after a start collision).
        travel: (n, F) final closing parameter t of each finger.
        joints: closing joint name -> (n,) final value.
        queries: (n,) int64 exact distances used.
        row: (C,) int64 the draw of each contact, non-decreasing; a draw's contacts in
            finger order, then link order.
        finger, link: (C,) int64 the contact's finger and its link index within the finger.
        points, normals: (C, 3) object frame, metres; unit normals pointing into the object.
        distances: (C,) signed link-object distance at the contact, metres.
    """

    start_collision: np.ndarray
    missed: np.ndarray
    gaps: np.ndarray
    travel: np.ndarray
    joints: dict[str, np.ndarray]
    queries: np.ndarray
    row: np.ndarray
    finger: np.ndarray
    link: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    distances: np.ndarray

    @classmethod
    def of_results(cls, results: list[RobotCloseResult]) -> RobotCloseBatch:
        """The batch of closings given one by one (their contacts in their order)."""
        n = len(results)
        fingers = max((len(r.missed) for r in results), default=0)
        missed = np.zeros((n, fingers), dtype=bool)
        gaps, travel = np.full((n, fingers), np.nan), np.zeros((n, fingers))
        for i, r in enumerate(results):
            missed[i, :len(r.missed)] = r.missed
            gaps[i, :len(r.gaps)], travel[i, :len(r.travel)] = r.gaps, r.travel
        names = sorted({name for r in results for name in r.joints})
        joints = {name: np.array([r.joints.get(name, np.nan) for r in results])
                  for name in names}
        contacts = [(i, c) for i, r in enumerate(results) for c in r.contacts]
        return cls(np.array([r.start_collision for r in results], dtype=bool), missed, gaps,
                   travel, joints, np.array([r.queries for r in results], dtype=np.int64),
                   np.array([i for i, _ in contacts], dtype=np.int64),
                   np.array([c.finger for _, c in contacts], dtype=np.int64),
                   np.array([c.link for _, c in contacts], dtype=np.int64),
                   np.array([c.point for _, c in contacts], dtype=float).reshape(-1, 3),
                   np.array([c.normal for _, c in contacts], dtype=float).reshape(-1, 3),
                   np.array([c.distance for _, c in contacts], dtype=float))

    @classmethod
    def joined(cls, batches: list[RobotCloseBatch]) -> RobotCloseBatch:
        """One batch of several, their draws in order."""
        offsets = np.cumsum([0] + [len(b) for b in batches])
        return cls(*(np.concatenate([getattr(b, key) for b in batches])
                     for key in ("start_collision", "missed", "gaps", "travel")),
                   {name: np.concatenate([b.joints[name] for b in batches])
                    for name in batches[0].joints},
                   np.concatenate([b.queries for b in batches]),
                   np.concatenate([b.row + o
                                   for b, o in zip(batches, offsets[:-1], strict=True)]),
                   *(np.concatenate([getattr(b, key) for b in batches])
                     for key in ("finger", "link", "points", "normals", "distances")))

    def __len__(self) -> int:
        return len(self.start_collision)

    @property
    def contact_counts(self) -> np.ndarray:
        """(n,) int64 contacts of each draw."""
        return np.bincount(self.row, minlength=len(self))

    @property
    def slot(self) -> np.ndarray:
        """(C,) int64 each contact's index among its draw's contacts."""
        first = np.searchsorted(self.row, self.row, side="left")
        return np.arange(len(self.row)) - first

    def results(self) -> list[RobotCloseResult]:
        """The per-draw view: one :class:`RobotCloseResult` per draw."""
        starts = np.searchsorted(self.row, np.arange(len(self) + 1), side="left")
        fingers = self.missed.shape[1]
        out = []
        for i in range(len(self)):
            if self.start_collision[i]:
                out.append(RobotCloseResult(True, queries=int(self.queries[i]),
                                            missed=(False,) * fingers,
                                            gaps=np.full(fingers, np.nan),
                                            travel=np.zeros(fingers)))
                continue
            contacts = [RobotContact(int(self.finger[c]), int(self.link[c]),
                                     self.points[c].copy(), self.normals[c].copy(),
                                     float(self.distances[c]))
                        for c in range(starts[i], starts[i + 1])]
            out.append(RobotCloseResult(
                False, contacts, tuple(bool(x) for x in self.missed[i]), self.gaps[i].copy(),
                self.travel[i].copy(), {name: float(v[i]) for name, v in self.joints.items()},
                int(self.queries[i])))
        return out
