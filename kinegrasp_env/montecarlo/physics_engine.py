"""The physics engine: the paper's closing under pybullet dynamics, draw by draw.

Same interface and scoring as the kinematic engines (:class:`~kinegrasp_env.montecarlo.engines.
Engine`): ``run(q (n, 14)) -> DrawBatch``, the same outcomes and Q from the same contacts'
friction cones, the same eps for the same seed. The closing is
:func:`~kinegrasp_env.physics.pybullet_closing.physics_close` (motors close the fingers until they
stall; the object free or fixed), the contacts are in the object's frame where the object
ended. :meth:`PhysicsEngine.run_lift` adds the lift test
(:func:`~kinegrasp_env.physics.pybullet_lift.lift_test`) to every draw that closed.

Every draw starts from the same saved simulator state, so a draw's result depends only on its
configuration: the same configurations give the same bits in any order, in any chunking.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from kinegrasp_env.montecarlo.engines import (
    FLANGE_LINK,
    DrawBatch,
    Engine,
    check_configurations,
    record_close,
)
from kinegrasp_env.physics.pybullet_closing import MotorSettings, physics_close
from kinegrasp_env.physics.pybullet_lift import LiftProfile, lift_test
from kinegrasp_env.physics.pybullet_world import PhysicsWorld, WorldSettings
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.model import kuka_sdh
from kinegrasp_env.threads import single_blas_thread


@dataclass
class LiftBatch:
    """Lift-test results of n draws.

    Attributes:
        held: (n,) bool, the object held through lift, hold and shake (False for draws that
            did not close: start collision).
        max_offset: (n,) how far the object moved in the palm frame, metres (NaN: not lifted).
        time: (n,) seconds the test ran (the drop, or its full length; NaN: not lifted).
        tracking: (n,) largest distance of the palm from its commanded place, metres (NaN:
            not lifted).
    """

    held: np.ndarray
    max_offset: np.ndarray
    time: np.ndarray
    tracking: np.ndarray

    @classmethod
    def empty(cls, n: int) -> LiftBatch:
        return cls(np.zeros(n, bool), np.full(n, np.nan), np.full(n, np.nan),
                   np.full(n, np.nan))

    def put(self, rows: np.ndarray, other: LiftBatch) -> None:
        """Write ``other``'s draws into rows ``rows`` (len(other),) of this batch."""
        for f in ("held", "max_offset", "time", "tracking"):
            getattr(self, f)[rows] = getattr(other, f)


class PhysicsEngine(Engine):
    """Closing under pybullet dynamics (see the module docstring).

    Args:
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure; ``friction`` is also the
            simulated finger-object friction.
        world: :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings` (density, object
            free or fixed, time step); its friction is replaced by ``friction``.
        motors: :class:`~kinegrasp_env.physics.pybullet_closing.MotorSettings`.
        profile: :class:`~kinegrasp_env.physics.pybullet_lift.LiftProfile` of :meth:`run_lift`.
    """

    name = "physics"

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8,
                 world: WorldSettings | None = None, motors: MotorSettings | None = None,
                 profile: LiftProfile | None = None) -> None:
        super().__init__(object_name, friction, num_edges)
        self.settings = replace(world or WorldSettings(), friction=friction)
        self.motors = motors or MotorSettings()
        self.profile = profile or LiftProfile()
        self.kin = Kinematics(kuka_sdh())
        self.world = PhysicsWorld(self.obj, self.settings)

    def close(self) -> None:
        super().close()
        self.world.close()

    def _close_all(self, q: np.ndarray, lift: LiftBatch | None) -> DrawBatch:
        n = q.shape[0]
        out = DrawBatch.empty(n)
        t0 = time.perf_counter()
        roots = self.kin.pose(q, FLANGE_LINK)
        t1 = time.perf_counter()
        for i in range(n):
            result = physics_close(self.world, roots[i], q[i, 7:], self.motors)
            record_close(out, i, result)
            if lift is not None and not result.start_collision:
                test = lift_test(self.world, self.profile, self.motors)
                lift.held[i], lift.max_offset[i] = test.held, test.max_offset
                lift.time[i], lift.tracking[i] = test.time, test.tracking
        t2 = time.perf_counter()
        self.score(out)
        self._account(n, kinematics=t1 - t0, autoclose=t2 - t1, quality=time.perf_counter() - t2)
        return out

    def _run(self, q: np.ndarray) -> DrawBatch:
        return self._close_all(q, None)

    def run_lift(self, q: np.ndarray) -> tuple[DrawBatch, LiftBatch]:
        """Outcomes of configurations q (n, 14) (as :meth:`run`: the same numbers) and the
        lift test of every draw that closed (its time counts as auto-close time).

        Raises:
            ValueError: bad configurations, or the engine's object is fixed.
        """
        if not self.settings.object_free:
            raise ValueError("the lift test needs a free object (object_free=True)")
        q = check_configurations(q)
        lift = LiftBatch.empty(q.shape[0])
        with single_blas_thread():
            if self.obj.table is None:
                return self._close_all(q, lift), lift
            clear = LiftBatch.empty(0)

            def close_rows(q_rows: np.ndarray) -> DrawBatch:
                nonlocal clear
                clear = LiftBatch.empty(q_rows.shape[0])
                return self._close_all(q_rows, clear)

            out, keep = self.clear_of_table(q, {}, close_rows)
            lift.put(keep, clear)
            return out, lift
