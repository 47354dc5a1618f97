"""The holding test of a description robot as an engine (:class:`RobotHoldEngine`): its
physics closings scored as every engine of the robot scores them, and the holding test's
results; :func:`hold_engine` gives every robot's holding test, :func:`quick_hold_engine`
under the quick protocol (:data:`~kinegrasp_env.physics.protocol.QUICK_PROTOCOL`), the one
ranking and rewards use."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_batch import RobotCloseBatch
from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.hold_batch import HoldBatch
from kinegrasp_env.physics.protocol import QUICK_PROTOCOL, HoldProtocol
from kinegrasp_env.physics.robot_hold import QUICK_MOTORS, RobotMotorSettings
from kinegrasp_env.physics.simulators import simulator_class
from kinegrasp_env.threads import single_blas_thread

__all__ = ["RobotHoldEngine", "hold_engine", "quick_hold_engine"]


class RobotHoldEngine(RobotEngine):
    """The holding test of a description robot as an engine: the physics closing's outcomes
    and Q scored as every engine of the robot scores (:meth:`~kinegrasp_env.montecarlo.
    description_engine.RobotEngine.scored`: its contact model, the patch model's corners
    included), and the holding results (arguments: :class:`RobotEngine`;
    ``protocol``: the holding test's settings; ``motors``: the closing's end;
    ``simulator``: a name of :data:`~kinegrasp_env.physics.simulators.
    SIMULATORS`)."""

    name = "physics"

    def __init__(self, robot, object_name: str, *, protocol: HoldProtocol,
                 motors: RobotMotorSettings | None = None, simulator: str = "pybullet",
                 **kwargs) -> None:
        super().__init__(robot, object_name, **kwargs)
        #: the holding test's settings (what a :class:`HoldBatch`'s margin is taken under)
        self.protocol = protocol
        self.simulator = simulator_class(simulator)(
            self.description, self.obj, self.friction, protocol, settings=motors)

    def close(self) -> None:
        self.simulator.close()

    def run_hold(self, q: np.ndarray) -> tuple[DrawBatch, HoldBatch]:
        """Configurations q (n, dof): (the physics closings scored, their holding tests; the
        fingers' forces (n, fingers)); a draw that starts in the support table
        (:attr:`in_table`: the arm is not simulated) is a start collision in both."""
        q = self.check(q)
        n, fingers = q.shape[0], len(self.description.fingers)
        hold = HoldBatch.empty(n)
        hold.forces_gripped = np.full((n, fingers), np.nan)
        hold.forces_released = np.full((n, fingers), np.nan)
        closings = []
        for i, (row, in_table) in enumerate(zip(q, self.in_table(q), strict=True)):
            if in_table:
                closings.append(RobotCloseResult.collided(fingers))
                continue  # the batch's rows start as start collisions
            closing, result = self.simulator.run_draw(row)
            closings.append(closing)
            if result.forces_gripped.shape != (fingers,):  # not reached: NaN of the default
                result.forces_gripped = result.forces_released = np.full(fingers, np.nan)
            hold.record(i, result)
        with single_blas_thread():
            return self.scored(q, RobotCloseBatch.of_results(closings)), hold


def hold_engine(robot, object_name: str, *, protocol: HoldProtocol,
                motors: RobotMotorSettings | None = None, simulator: str = "pybullet",
                **kwargs) -> RobotEngine:
    """The holding test of ``robot`` (a catalog name or a description) on a catalog object
    under ``protocol`` in ``simulator`` (pybullet or MuJoCo): a :class:`RobotHoldEngine`
    (its ``run_hold(q)``), the hand closed by ``motors``; ``kwargs``: the engine's
    (``friction``, ``num_edges``, ...)."""
    return RobotHoldEngine(robot, object_name, protocol=protocol, motors=motors,
                           simulator=simulator, **kwargs)


def quick_hold_engine(robot, object_name: str, friction: float = 0.5,
                      simulator: str = "pybullet") -> RobotEngine:
    """The quick holding test of ``robot`` (a catalog name or a description) on a catalog
    object, in ``simulator`` (pybullet or MuJoCo), friction mu ``friction``
    (:func:`hold_engine` under :data:`~kinegrasp_env.physics.protocol.QUICK_PROTOCOL`, a
    description hand's motors at :data:`~kinegrasp_env.physics.robot_hold.QUICK_MOTORS`)."""
    return hold_engine(robot, object_name, protocol=QUICK_PROTOCOL, motors=QUICK_MOTORS,
                       friction=friction, simulator=simulator)
