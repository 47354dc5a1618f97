"""The hold scores of the default robot's own engines' draws.

**The static hold check** (:class:`DrawHoldCheck`; the check itself:
:class:`~kinegrasp_env.montecarlo.hold_check.StaticHoldCheck`): can each closing carry the
object's weight in the holding test's six gravity directions and the lift, within the hand's
effort limits?

The check runs on the robot's description (``kuka_sdh.yaml``: the engines' joints, fingers
and links, :mod:`~kinegrasp_env.robot.default_robot`, and contact records), on
the draw's final configuration: its arm joints (the draw's noise) and the closed hand the
engine recorded (:attr:`~kinegrasp_env.montecarlo.draws.DrawBatch.hand`). Joint noise
only: a palm or object error moves the palm against the object, which the configuration does
not say, and a friction error changes the cones the check holds at one mu.

**The quick holding test** (:class:`QuickHoldTest`): the default robot's own holding test
(:class:`~kinegrasp_env.montecarlo.physics_engine.PhysicsEngine`, its grip balanced over the
three fingers) with the quick protocol (:data:`~kinegrasp_env.physics.protocol.
QUICK_PROTOCOL`), in pybullet or MuJoCo, on the same draws' configurations (the noise
limits of the static check).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, NO_FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import chunk_configurations, chunk_sizes
from kinegrasp_env.montecarlo.hold_check import StaticHoldCheck
from kinegrasp_env.physics.protocol import HELD, QUICK_PROTOCOL, HoldProtocol
from kinegrasp_env.quality.soft_contacts import FINGER_RADIUS
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.world.grasps import DEFAULT_ROBOT, Grasp
from kinegrasp_env.world.objects import load_object

__all__ = ["DrawHoldCheck", "QuickHoldTest", "check_hold_noise", "grasp_holds"]


def check_hold_noise(noise, robot: str = DEFAULT_ROBOT, score: str = "the hold scores"
                     ) -> None:
    """ValueError (one line) for a noise model with a palm, object or friction source:
    ``score`` of ``robot``'s draws (the default robot's hold scores; any robot's holding
    test) takes joint and hand noise only (the holding test places the hand by its joints)."""
    if not isinstance(noise, NoiseModel):
        return
    other = [name for name in ("palm", "object", "friction") if getattr(noise, name) is not None]
    if other:
        raise ValueError(f"{score} of {robot}'s draws take joint and hand noise only; the "
                         f"noise spec has {', '.join(other)}")


class DrawHoldCheck:
    """The static hold check of the default robot on one catalog object.

    Args:
        object_name: the catalog object (its pose and mass).
        friction, num_edges: the friction cones (the quality measure's).
        protocol: the holding test whose loads are checked (default: the full protocol).
        description: the default robot's description (default: the catalog's; another with
            the same joints, fingers and links, e.g. other ``efforts``).
    """

    def __init__(self, object_name: str, *, friction: float = 0.5, num_edges: int = 8,
                 protocol: HoldProtocol | None = None,
                 description: RobotDescription | None = None) -> None:
        description = description or load_robot(DEFAULT_ROBOT)
        self.arm_dof = description.arm_dof
        self.dof = description.model.dof
        self.check = StaticHoldCheck(description, load_object(object_name), friction=friction,
                                     num_edges=num_edges, finger_radius=FINGER_RADIUS,
                                     protocol=protocol)

    def close(self) -> None:
        """Nothing to release (the check holds no simulator)."""

    @property
    def mass(self) -> float:
        """The object's mass, kg (the catalog's)."""
        return self.check.mass

    def configurations(self, arm: np.ndarray, draws: DrawBatch) -> np.ndarray:
        """(n, dof) each draw's final configuration in the description's joint order: its arm
        joints ``arm`` (n, 7), radians, then the closed hand the engine recorded (NaN where
        the hand did not close)."""
        arm = np.asarray(arm, dtype=float)
        if arm.shape != (len(draws), self.arm_dof):
            raise ValueError(f"arm joints of shape {arm.shape} for {len(draws)} draws of a "
                             f"{self.arm_dof}-joint arm")
        if self.arm_dof + draws.hand.shape[1] != self.dof:
            raise ValueError(f"{draws.hand.shape[1]} hand joints per draw; {DEFAULT_ROBOT}'s "
                             f"description has {self.dof - self.arm_dof}")
        return np.concatenate([arm, draws.hand], axis=1)

    def held(self, arm: np.ndarray, draws: DrawBatch) -> np.ndarray:
        """(n,) whether each draw's closing holds all six loads (a draw that starts in
        collision or misses with a finger does not).

        Args:
            arm: (n, 7) the draws' arm joints, radians.
            draws: the engine's n draws (contacts in the object frame, the closed hand).
        """
        q = self.configurations(arm, draws)
        touched = (draws.outcome == NO_FORCE_CLOSURE) | (draws.outcome == FORCE_CLOSURE)
        rows = np.flatnonzero(touched & np.isfinite(q).all(axis=1))
        out = np.zeros(len(draws), dtype=bool)
        if rows.size:
            out[rows] = self.check.held(q[rows], {}, draws.points[rows], draws.normals[rows],
                                        draws.finger[rows].astype(int),
                                        draws.link[rows].astype(int)).all(axis=1)
        return out

    def chunk_held(self, q0: np.ndarray, noise, seed: int, draws: DrawBatch, *, chunk: int,
                   first_chunk: int = 0) -> np.ndarray:
        """(n,) the verdicts of the n draws a run from configuration q0 (14,) made with
        ``noise`` and ``seed`` in chunks of ``chunk`` from chunk ``first_chunk`` on (the draws'
        arm joints are those chunks' noise:
        :func:`~kinegrasp_env.montecarlo.evaluate.chunk_configurations`)."""
        check_hold_noise(noise)
        arm = run_configurations(q0, noise, seed, len(draws), chunk, first_chunk)
        return self.held(arm[:, :self.arm_dof], draws)


def grasp_holds(grasp: Grasp, noise, seed: int, draws: DrawBatch, *, chunk: int,
                first_chunk: int = 0, friction: float = 0.5, num_edges: int = 8
                ) -> tuple[np.ndarray, float]:
    """(held (n,), the object's mass in kg) of the n draws an evaluation of ``grasp`` made
    (:meth:`DrawHoldCheck.chunk_held` from the grasp's q0)."""
    hold = DrawHoldCheck(grasp.object, friction=friction, num_edges=num_edges)
    return hold.chunk_held(grasp.q0, noise, seed, draws, chunk=chunk,
                           first_chunk=first_chunk), hold.mass


def run_configurations(q0: np.ndarray, noise, seed: int, n: int, chunk: int,
                       first_chunk: int = 0) -> np.ndarray:
    """(n, 14) the configurations of the n draws a run from q0 (14,) makes with ``noise`` and
    ``seed`` in chunks of ``chunk`` from chunk ``first_chunk`` on."""
    if n == 0:
        return np.empty((0, np.asarray(q0).size))
    chunks = [(first_chunk + i, size) for i, size in enumerate(chunk_sizes(n, chunk))]
    return chunk_configurations(q0, noise, seed, chunks)


class QuickHoldTest:
    """The default robot's quick holding test on one catalog object (module docstring).

    Args:
        object_name: the catalog object; friction: Coulomb mu, finger-object.
        simulator: ``pybullet`` or ``mujoco``.
    """

    def __init__(self, object_name: str, *, friction: float = 0.5,
                 simulator: str = "pybullet") -> None:
        from kinegrasp_env.montecarlo.physics_engine import PhysicsEngine

        self.engine = PhysicsEngine(object_name, friction, protocol=QUICK_PROTOCOL,
                                    simulator=simulator)
        self.simulator = simulator

    def chunk_held(self, q0: np.ndarray, noise, seed: int, n: int, *, chunk: int,
                   first_chunk: int = 0) -> np.ndarray:
        """(n,) whether the test holds each of the n draws a run from q0 (14,) makes with
        ``noise`` and ``seed`` in chunks of ``chunk`` from chunk ``first_chunk`` on."""
        check_hold_noise(noise)
        q = run_configurations(q0, noise, seed, n, chunk, first_chunk)
        return self.engine.run_hold(q)[1].outcome == HELD

    def close(self) -> None:
        self.engine.close()

    def __enter__(self) -> QuickHoldTest:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
