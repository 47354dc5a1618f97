"""The static hold check (:class:`~kinegrasp_env.montecarlo.hold_check.StaticHoldCheck`) of
the default robot's own engines' draws: can each closing carry the object's weight in the
holding test's six gravity directions and the lift, within the hand's effort limits?

The check runs on the robot's description (``kuka_sdh.yaml``: the same joints, fingers and
links as the engines' :data:`~kinegrasp_env.robot.model.HAND_JOINTS` and contact records), on
the draw's final configuration: its arm joints (the draw's noise) and the closed hand the
engine recorded (:attr:`~kinegrasp_env.montecarlo.engines.DrawBatch.hand`). Joint noise
only: a palm or object error moves the palm against the object, which the configuration does
not say, and a friction error changes the cones the check holds at one mu.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.engines import DrawBatch
from kinegrasp_env.montecarlo.evaluate import chunk_configurations, chunk_sizes
from kinegrasp_env.montecarlo.hold_check import StaticHoldCheck
from kinegrasp_env.physics.protocol import HoldProtocol
from kinegrasp_env.quality.soft_contacts import FINGER_RADIUS
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.world.grasps import DEFAULT_ROBOT, Grasp
from kinegrasp_env.world.objects import load_object

__all__ = ["DrawHoldCheck", "check_hold_noise", "grasp_holds"]


def check_hold_noise(noise) -> None:
    """ValueError (one line) for a noise model with a palm, object or friction source: the
    static hold check of the default robot's draws takes joint (and hand) noise only."""
    if not isinstance(noise, NoiseModel):
        return
    other = [name for name in ("palm", "object", "friction") if getattr(noise, name) is not None]
    if other:
        raise ValueError(f"the static hold check of {DEFAULT_ROBOT}'s draws takes joint and "
                         f"hand noise only; the noise spec has {', '.join(other)}")


class DrawHoldCheck:
    """The static hold check of the default robot on one catalog object.

    Args:
        object_name: the catalog object (its pose and mass).
        friction, num_edges: the friction cones (the quality measure's).
        protocol: the holding test whose loads are checked (default: the full protocol).
    """

    def __init__(self, object_name: str, *, friction: float = 0.5, num_edges: int = 8,
                 protocol: HoldProtocol | None = None) -> None:
        description = load_robot(DEFAULT_ROBOT)
        self.arm_dof = description.arm_dof
        self.dof = description.model.dof
        self.check = StaticHoldCheck(description, load_object(object_name), friction=friction,
                                     num_edges=num_edges, finger_radius=FINGER_RADIUS,
                                     protocol=protocol)

    @property
    def mass(self) -> float:
        """The object's mass, kg (the catalog's)."""
        return self.check.mass

    def held(self, arm: np.ndarray, draws: DrawBatch) -> np.ndarray:
        """(n,) whether each draw's closing holds all six loads.

        Args:
            arm: (n, 7) the draws' arm joints, radians.
            draws: the engine's n draws (contacts in the object frame, the closed hand).
        """
        arm = np.asarray(arm, dtype=float)
        if arm.shape != (len(draws), self.arm_dof):
            raise ValueError(f"arm joints of shape {arm.shape} for {len(draws)} draws of a "
                             f"{self.arm_dof}-joint arm")
        if self.arm_dof + draws.hand.shape[1] != self.dof:
            raise ValueError(f"{draws.hand.shape[1]} hand joints per draw; {DEFAULT_ROBOT}'s "
                             f"description has {self.dof - self.arm_dof}")
        rows = np.flatnonzero((draws.n_contacts > 0) & np.isfinite(draws.hand).all(axis=1))
        out = np.zeros(len(draws), dtype=bool)
        if rows.size:
            q = np.concatenate([arm[rows], draws.hand[rows]], axis=1)
            out[rows] = self.check.held(q, {}, draws.points[rows], draws.normals[rows],
                                        draws.finger[rows].astype(int),
                                        draws.link[rows].astype(int)).all(axis=1)
        return out


def grasp_holds(grasp: Grasp, noise, seed: int, draws: DrawBatch, *, chunk: int,
                first_chunk: int = 0, friction: float = 0.5, num_edges: int = 8
                ) -> tuple[np.ndarray, float]:
    """(held (n,), the object's mass in kg) of the n draws an evaluation of ``grasp`` made
    with ``noise`` and ``seed`` in chunks of ``chunk`` from chunk ``first_chunk`` on (the
    draws' arm joints are those chunks' noise:
    :func:`~kinegrasp_env.montecarlo.evaluate.chunk_configurations`)."""
    check_hold_noise(noise)
    sizes = chunk_sizes(len(draws), chunk)
    chunks = [(first_chunk + i, size) for i, size in enumerate(sizes)]
    arm = chunk_configurations(grasp.q0, noise, seed, chunks)[:, :7]
    hold = DrawHoldCheck(grasp.object, friction=friction, num_edges=num_edges)
    return hold.held(arm, draws), hold.mass
