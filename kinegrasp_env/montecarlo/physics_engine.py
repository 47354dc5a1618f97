"""The physics engine: the paper's closing under pybullet dynamics, draw by draw, and the
holding test.

Same interface and scoring as the kinematic engines (:class:`~kinegrasp_env.montecarlo.engines.
Engine`): ``run(q (n, 14)) -> DrawBatch``, the same outcomes and Q from the same contacts'
friction cones, the same eps for the same seed. The closing is
:func:`~kinegrasp_env.physics.pybullet_closing.physics_close` (motors close the fingers until they
stall; the object free or fixed), the contacts are in the object's frame where the object
ended. :meth:`PhysicsEngine.run_hold` runs the holding test
(:mod:`~kinegrasp_env.physics.protocol`) in a registered simulator instead: its closing on the
pinned object gives the outcomes and Q, and every draw gets a
:class:`~kinegrasp_env.physics.protocol.HoldResult` (:class:`HoldBatch`).

Every draw starts from the same saved simulator state, so a draw's result depends only on its
configuration: the same configurations give the same bits in any order, in any chunking.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.engines import (
    MAX_CONTACTS,
    Engine,
    check_configurations,
)
from kinegrasp_env.physics.protocol import (
    HELD,
    PHASES,
    START_COLLISION,
    HoldProtocol,
    HoldResult,
    hold_margin,
)
from kinegrasp_env.physics.pybullet_closing import MotorSettings, physics_close
from kinegrasp_env.physics.pybullet_world import PhysicsWorld, WorldSettings
from kinegrasp_env.physics.simulators import HoldSimulator, simulator_class
from kinegrasp_env.quality.soft_contacts import FINGER_RADIUS
from kinegrasp_env.robot.default_robot import default_hand_mount, kuka_sdh
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.threads import single_blas_thread


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


class PhysicsEngine(Engine):
    """Closing under pybullet dynamics (see the module docstring).

    Args:
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure; ``friction`` is also the
            simulated finger-object friction.
        world: :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings` (density, object
            free or fixed, time step); its friction is replaced by ``friction``.
        motors: :class:`~kinegrasp_env.physics.pybullet_closing.MotorSettings`.
        protocol: :class:`~kinegrasp_env.physics.protocol.HoldProtocol` of :meth:`run_hold`.
        simulator: the registered simulator of :meth:`run_hold`
            (:data:`~kinegrasp_env.physics.simulators.SIMULATORS`).
        static_hold: the static hold check on every closing that touches (:class:`Engine`).
    """

    name = "physics"

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8,
                 world: WorldSettings | None = None, motors: MotorSettings | None = None,
                 protocol: HoldProtocol | None = None, simulator: str = "pybullet", *,
                 static_hold: bool = False) -> None:
        super().__init__(object_name, friction, num_edges, static_hold=static_hold)
        self.settings = replace(world or WorldSettings(), friction=friction)
        self.motors = motors or MotorSettings()
        self.protocol = protocol or HoldProtocol()
        self.simulator_class = simulator_class(simulator)
        self.kin = Kinematics(kuka_sdh())
        self.world = PhysicsWorld(self.obj, self.settings)
        self._holder: HoldSimulator | None = None

    def close(self) -> None:
        super().close()
        self.world.close()
        if self._holder is not None:
            self._holder.close()

    @property
    def holder(self) -> HoldSimulator:
        """The simulator of :meth:`run_hold` (built on first use)."""
        if self._holder is None:
            self._holder = self.simulator_class(self.obj, self.friction, self.protocol)
        return self._holder

    def _close_all(self, q: np.ndarray, hold: HoldBatch | None) -> DrawBatch:
        n = q.shape[0]
        t0 = time.perf_counter()
        roots = self.kin.pose(q, default_hand_mount())
        t1 = time.perf_counter()
        results = []
        for i in range(n):
            if hold is None:
                results.append(physics_close(self.world, roots[i], q[i, 7:], self.motors))
            else:
                result, test = self.holder.run_draw(roots[i], q[i, 7:])
                hold.record(i, test)
                results.append(result)
        t2 = time.perf_counter()
        out = self.scored(q, results)
        self._account(n, kinematics=t1 - t0, autoclose=t2 - t1, quality=time.perf_counter() - t2)
        return out

    def _run(self, q: np.ndarray) -> DrawBatch:
        return self._close_all(q, None)

    def run_hold(self, q: np.ndarray) -> tuple[DrawBatch, HoldBatch]:
        """The holding test of configurations q (n, 14): the outcomes and Q of its closing
        (the object pinned) and every draw's :class:`HoldBatch` row (its time counts as
        auto-close time). Draws whose robot starts in the support table are start collisions.

        Raises:
            ValueError: bad configurations, or the engine's object is fixed.
        """
        if not self.settings.object_free:
            raise ValueError("the holding test needs a free object (object_free=True)")
        q = check_configurations(q)
        hold = HoldBatch.empty(q.shape[0])
        with single_blas_thread():
            if self.obj.table is None:
                return self._close_all(q, hold), hold
            clear = HoldBatch.empty(0)

            def close_rows(q_rows: np.ndarray) -> DrawBatch:
                nonlocal clear
                clear = HoldBatch.empty(q_rows.shape[0])
                return self._close_all(q_rows, clear)

            out, keep = self.clear_of_table(q, {}, close_rows)
            hold.put(keep, clear)
            return out, hold


class PaperPhysicsEngine(RobotEngine):
    """:class:`PhysicsEngine` (the paper's closing under pybullet dynamics: its hand's own
    finger controller, :func:`~kinegrasp_env.physics.pybullet_closing.physics_close`) with
    every robot's engine interface (:class:`~kinegrasp_env.montecarlo.description_engine.
    RobotEngine`: ``description``, ``check``, ``run``, ``hold_check``): the ``physics`` engine
    :func:`~kinegrasp_env.montecarlo.robot_engines.make_engine` gives the robot whose hand
    that controller closes, so that every robot's evaluation, ranking and tables close its
    draws with its own physics. Its draws are :class:`PhysicsEngine`'s, row for row;
    :meth:`run_hold` is its holding test.

    Args:
        robot: the default robot (its name or description; chosen by name:
            :func:`~kinegrasp_env.montecarlo.robot_engines.own_physics`).
        object_name: catalog object.
        friction, num_edges, static_hold: as :class:`PhysicsEngine` (it simulates at one mu:
            :meth:`run` refuses a per-draw friction).
        max_contacts: None or :data:`~kinegrasp_env.montecarlo.engines.MAX_CONTACTS`, the
            contacts its closing scores a draw (another number is a ValueError).
        finger_radius: as every robot's engine takes it (its contacts are points).
        protocol, simulator: :class:`PhysicsEngine`'s, of :meth:`run_hold`.

    (Its settings of the world and the motors are :class:`PhysicsEngine`'s own defaults;
    build a :class:`PhysicsEngine` for others.)
    """

    name = "physics"

    def __init__(self, robot: str | RobotDescription, object_name: str, *,
                 friction: float = 0.5, num_edges: int = 8, static_hold: bool = False,
                 max_contacts: int | None = None, finger_radius: float = FINGER_RADIUS,
                 protocol: HoldProtocol | None = None, simulator: str = "pybullet") -> None:
        if max_contacts not in (None, MAX_CONTACTS):
            raise ValueError(f"the default robot's physics engine scores {MAX_CONTACTS} "
                             f"contacts a draw, got max_contacts={max_contacts!r}")
        super().__init__(robot, object_name, friction=friction, num_edges=num_edges,
                         finger_radius=finger_radius, max_contacts=MAX_CONTACTS)
        self.engine = PhysicsEngine(object_name, friction, num_edges, protocol=protocol,
                                    simulator=simulator, static_hold=static_hold)
        self.hold_check = self.engine.scoring.hold_check

    def close(self) -> None:
        self.engine.close()

    @property
    def simulator(self) -> HoldSimulator:
        """The simulator of :meth:`run_hold` (built on first use; its ``name``)."""
        return self.engine.holder

    @property
    def protocol(self) -> HoldProtocol:
        """The holding test's settings of :meth:`run_hold` (its margins are taken under it)."""
        return self.engine.protocol

    def run(self, q: np.ndarray, *, palm: np.ndarray | None = None,
            object_offset: np.ndarray | None = None,
            friction: np.ndarray | None = None) -> DrawBatch:
        """:meth:`PhysicsEngine.run` of configurations q (n, dof) (checked against the
        robot's description first)."""
        return self.engine.run(self.check(q), palm=palm, object_offset=object_offset,
                               friction=friction)

    def run_hold(self, q: np.ndarray) -> tuple[DrawBatch, HoldBatch]:
        """:meth:`PhysicsEngine.run_hold` of configurations q (n, dof)."""
        return self.engine.run_hold(self.check(q))
