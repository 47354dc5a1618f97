"""The fast engine of every robot (the default robot's included): the reference engine's
closing model (:mod:`~kinegrasp_env.closing.generic_reference`) batched over draws
(:class:`~kinegrasp_env.closing.generic_fast.FastRobotHand`), scored exactly as the
reference engine scores its closings
(:func:`~kinegrasp_env.montecarlo.description_engine.score_batch`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_batch import RobotCloseBatch
from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.closing.generic_fast import FastRobotHand
from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.threads import single_blas_thread

#: Draws closed in one batch (bounds the batch's temporaries).
BATCH = 1024


class RobotFastEngine(RobotEngine):
    """Batched closing of a description robot (arguments: :class:`~kinegrasp_env.montecarlo.
    description_engine.RobotEngine`); the object's distance grid is built on first use and
    cached."""

    name = "fast"
    takes_errors = True

    def __init__(self, robot: str | RobotDescription, object_name: str, **kwargs) -> None:
        super().__init__(robot, object_name, **kwargs)
        self.hand = FastRobotHand(self.description, self.obj)

    def starts_in_collision(self, q: np.ndarray) -> np.ndarray:
        """(n,) bool: the start-collision test of the closing
        (:meth:`~kinegrasp_env.closing.generic_fast.FastRobotHand.start_collision`) alone."""
        q = self.check(q)
        with single_blas_thread():
            return self.hand.start_collision(q)

    def close_all(self, q: np.ndarray, **errors: np.ndarray) -> list[RobotCloseResult]:
        return self.close_batch(q, **errors).results()

    def close_batch(self, q: np.ndarray, **errors: np.ndarray) -> RobotCloseBatch:
        if q.shape[0] == 0:
            return RobotCloseBatch.of_results([])
        batches = [self.hand.close_batch(q[start:start + BATCH],
                                         **{k: v[start:start + BATCH] for k, v in errors.items()})
                   for start in range(0, q.shape[0], BATCH)]
        return batches[0] if len(batches) == 1 else RobotCloseBatch.joined(batches)
