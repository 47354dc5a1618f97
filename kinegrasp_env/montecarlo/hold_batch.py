"""The holding test's results of a batch of draws, as arrays (:class:`HoldBatch`): what every
robot's holding test (:class:`~kinegrasp_env.montecarlo.hold_engine.RobotHoldEngine`)
returns beside its scored closings, and what ``kinegrasp validate`` stores per draw."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.physics.protocol import (
    HELD,
    PHASES,
    START_COLLISION,
    HoldProtocol,
    HoldResult,
    hold_margin,
)


@dataclass
class HoldBatch:
    """Holding-test results of n draws (:class:`~kinegrasp_env.physics.protocol.HoldResult`
    as arrays).

    Attributes:
        outcome: (n,) int8 index into :data:`~kinegrasp_env.physics.protocol.HOLD_OUTCOMES`.
        grip_shift, grip_turn: (n,) the grip's own displacement after the release, metres and
            radians (NaN: not released).
        forces_gripped, forces_released: (n, 3) the fingers' normal forces, newtons (NaN).
        pin_force: (n,) the net force of the grip on the pinned object, newtons (NaN).
        phase_held: (n, P) int8 per phase of :data:`~kinegrasp_env.physics.protocol.PHASES`:
            1 held, 0 failed, -1 not run.
        phase_shift, phase_turn: (n, P) the largest displacement (m) and rotation (rad) in
            each phase (NaN: not run).
    """

    outcome: np.ndarray
    grip_shift: np.ndarray
    grip_turn: np.ndarray
    forces_gripped: np.ndarray
    forces_released: np.ndarray
    pin_force: np.ndarray
    phase_held: np.ndarray
    phase_shift: np.ndarray
    phase_turn: np.ndarray

    FIELDS = ("outcome", "grip_shift", "grip_turn", "forces_gripped", "forces_released",
              "pin_force", "phase_held", "phase_shift", "phase_turn")

    @classmethod
    def empty(cls, n: int) -> HoldBatch:
        p = len(PHASES)
        return cls(np.full(n, START_COLLISION, np.int8), np.full(n, np.nan), np.full(n, np.nan),
                   np.full((n, 3), np.nan), np.full((n, 3), np.nan), np.full(n, np.nan),
                   np.full((n, p), -1, np.int8),
                   np.full((n, p), np.nan), np.full((n, p), np.nan))

    def record(self, i: int, result: HoldResult) -> None:
        """Draw i's result."""
        self.outcome[i] = result.outcome
        self.grip_shift[i], self.grip_turn[i] = result.grip_shift, result.grip_turn
        self.forces_gripped[i], self.forces_released[i] = (result.forces_gripped,
                                                           result.forces_released)
        self.pin_force[i] = result.pin_force
        for k, name in enumerate(PHASES):
            if name in result.phase_held:
                self.phase_held[i, k] = int(result.phase_held[name])
                self.phase_shift[i, k] = result.phase_shift[name]
                self.phase_turn[i, k] = result.phase_turn[name]

    def put(self, rows: np.ndarray, other: HoldBatch) -> None:
        """Write ``other``'s draws into rows ``rows`` (len(other),) of this batch."""
        for f in self.FIELDS:
            getattr(self, f)[rows] = getattr(other, f)

    @property
    def held(self) -> np.ndarray:
        """(n,) bool: outcome ``held``."""
        return self.outcome == HELD

    def margin(self, protocol: HoldProtocol) -> np.ndarray:
        """(n,) how far each draw got through ``protocol`` (the one it ran), in [0, 1]
        (:func:`~kinegrasp_env.physics.protocol.hold_margin`)."""
        return hold_margin(self.phase_held, self.phase_shift, self.phase_turn, protocol)
