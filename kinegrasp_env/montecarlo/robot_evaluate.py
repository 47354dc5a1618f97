"""P(FC) and Q moments of a grasp of any description robot, through the reference closing.

Each draw: the arm joints at q0 + eps (eps from :class:`~kinegrasp_env.sampling.noise.
JointNoise` on the description's arm joints, the hand at its pre-shape exactly), the hand
closed on the object by :meth:`~kinegrasp_env.closing.generic_reference.RobotWorld.auto_close`
(pybullet closest points on the URDF's own collision geometry), the contacts scored with the
robot's contact model (``soft`` for parallel jaws: :mod:`kinegrasp_env.quality.soft_contacts`).
Every draw ends in one of the engines' outcomes (:data:`~kinegrasp_env.montecarlo.engines.
OUTCOMES`); P(FC) comes with its Wilson interval, Q's moments are over the force-closure draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.generic_reference import RobotCloseResult, RobotWorld
from kinegrasp_env.montecarlo.engines import (
    FORCE_CLOSURE,
    MISSED,
    NO_FORCE_CLOSURE,
    OUTCOMES,
    START_COLLISION,
)
from kinegrasp_env.quality.soft_contacts import FINGER_RADIUS, contact_quality
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import JointNoise, SeedLike, as_generator
from kinegrasp_env.sampling.stats import skewness, wilson_interval
from kinegrasp_env.world.grasps import Grasp, check_robot
from kinegrasp_env.world.objects import load_object


@dataclass
class RobotDraws:
    """Per-draw results of n draws with k contacts at most (k = the finger links).

    Attributes:
        outcome: (n,) int8 index into OUTCOMES.
        quality: (n,) Q (0 unless force closure).
        n_contacts: (n,) contacts found.
        points, normals: (n, k, 3) contacts (object frame, normals inward), NaN-padded.
        finger, link: (n, k) int8 finger index and link index within it, -1 padded.
    """

    outcome: np.ndarray
    quality: np.ndarray
    n_contacts: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    finger: np.ndarray
    link: np.ndarray

    @classmethod
    def empty(cls, n: int, k: int) -> RobotDraws:
        return cls(np.zeros(n, np.int8), np.zeros(n), np.zeros(n, np.int16),
                   np.full((n, k, 3), np.nan), np.full((n, k, 3), np.nan),
                   np.full((n, k), -1, np.int8), np.full((n, k), -1, np.int8))


def outcome_of(result: RobotCloseResult) -> int:
    """The provisional outcome of one closing before scoring: start collision, missed (a
    finger missed, or fewer than two contacts) or no force closure (a candidate)."""
    if result.start_collision:
        return START_COLLISION
    if any(result.missed) or len(result.contacts) < 2:
        return MISSED
    return NO_FORCE_CLOSURE


class RobotReferenceEngine:
    """The reference engine for a description robot: one pybullet world, draw by draw.

    Args:
        robot: a catalog name or a loaded description.
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure.
        finger_radius: soft contacts' patch radius (metres).
    """

    name = "pybullet"

    def __init__(self, robot: str | RobotDescription, object_name: str, *,
                 friction: float = 0.5, num_edges: int = 8,
                 finger_radius: float = FINGER_RADIUS) -> None:
        self.description = load_robot(robot) if isinstance(robot, str) else robot
        self.obj = load_object(object_name)
        self.friction, self.num_edges, self.finger_radius = friction, num_edges, finger_radius
        self.world = RobotWorld(self.description, self.obj)
        self.max_contacts = len(self.description.finger_links)

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> RobotReferenceEngine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def check(self, q: np.ndarray) -> np.ndarray:
        """q as a finite (n, dof) float array; ValueError otherwise."""
        dof = self.description.model.dof
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.ndim != 2 or q.shape[1] != dof:
            raise ValueError(f"configurations of robot {self.description.name!r} must have "
                             f"shape (n, {dof}), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise ValueError("configurations have NaN or infinite entries")
        return q

    def quality(self, points: np.ndarray, normals: np.ndarray) -> float:
        """Q of contacts (k, 3) with the robot's contact model."""
        return contact_quality(points, normals, contact_model=self.description.contact_model,
                               friction=self.friction, num_edges=self.num_edges,
                               torque_scale=self.obj.torque_scale,
                               center=self.obj.center_of_mass,
                               **({"finger_radius": self.finger_radius}
                                  if self.description.contact_model == "soft" else {}))

    def close_one(self, q: np.ndarray) -> RobotCloseResult:
        """One closing at configuration q (dof,) (the world is left at its final state)."""
        return self.world.auto_close(self.check(q)[0])

    def run(self, q: np.ndarray) -> RobotDraws:
        """Outcomes of configurations q (n, dof) (arm noisy, hand at its pre-shape)."""
        q = self.check(q)
        out = RobotDraws.empty(q.shape[0], self.max_contacts)
        for i, row in enumerate(q):
            result = self.world.auto_close(row)
            out.outcome[i] = outcome_of(result)
            k = min(len(result.contacts), self.max_contacts)
            out.n_contacts[i] = k
            for j, c in enumerate(result.contacts[:k]):
                out.points[i, j], out.normals[i, j] = c.point, c.normal
                out.finger[i, j], out.link[i, j] = c.finger, c.link
            if out.outcome[i] == NO_FORCE_CLOSURE:
                out.quality[i] = self.quality(out.points[i, :k], out.normals[i, :k])
                if out.quality[i] > 0:
                    out.outcome[i] = FORCE_CLOSURE
        return out


@dataclass(frozen=True)
class RobotEvaluation:
    """Monte Carlo statistics of one grasp.

    Attributes:
        n: draws.
        counts: outcome name -> draws.
        p_fc: fraction in force closure; ci: its Wilson 95% interval.
        q_mean, q_std, q_skew: Q over the force-closure draws (NaN where too few; the
            skewness NaN too where every Q is the same).
        draws: the per-draw results.
    """

    n: int
    counts: dict[str, int]
    p_fc: float
    ci: tuple[float, float]
    q_mean: float
    q_std: float
    q_skew: float
    draws: RobotDraws


def summarize(draws: RobotDraws) -> RobotEvaluation:
    """The statistics of per-draw results (see :class:`RobotEvaluation`)."""
    n = int(draws.outcome.size)
    fc = draws.outcome == FORCE_CLOSURE
    k = int(fc.sum())
    q = draws.quality[fc]
    return RobotEvaluation(
        n, {name: int((draws.outcome == i).sum()) for i, name in enumerate(OUTCOMES)},
        k / n if n else float("nan"), wilson_interval(k, n),
        float(q.mean()) if k else float("nan"),
        float(q.std(ddof=1)) if k > 1 else float("nan"),
        float(skewness(q)) if k > 2 and np.ptp(q) > 0 else float("nan"), draws)


def evaluate_robot_grasp(grasp: Grasp, *, sigma: float | tuple[float, ...], n: int,
                         seed: SeedLike = 0, noise: str = "gaussian",
                         engine: RobotReferenceEngine | None = None,
                         robot: str | RobotDescription | None = None) -> RobotEvaluation:
    """P(FC) and Q moments of ``grasp`` over n draws of joint noise on the arm joints.

    Args:
        grasp: its ``robot`` names the robot (default: ``robot``, or the engine's).
        sigma: radians, scalar or one per arm joint.
        n: draws (>= 1).
        seed: seed or Generator of the noise.
        noise: ``gaussian``, ``uniform`` or ``triangular``.
        engine: a reference engine to reuse (its robot and object must be the grasp's).
        robot: the robot to evaluate with (default: the grasp's).

    Raises:
        ValueError: a grasp of another robot or object, bad n or sigma.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive number of draws, got {n!r}")
    noise_model = JointNoise(sigma, noise)
    if engine is not None:
        name = engine.description.name
        if engine.obj.name != grasp.object:
            raise ValueError(f"grasp {grasp.id!r} is a grasp of {grasp.object!r}, the engine "
                             f"holds {engine.obj.name!r}")
    else:
        name = grasp.robot if robot is None else getattr(robot, "name", robot)
    check_robot(grasp, name)
    own = engine is None
    if own:
        engine = RobotReferenceEngine(grasp.robot if robot is None else robot, grasp.object)
    try:
        q0 = engine.check(grasp.q0)[0]
        arm = engine.description.arm_dof
        eps = noise_model.sample(int(n), arm, as_generator(seed))
        q = np.repeat(q0[None], int(n), axis=0)
        q[:, :arm] += eps
        return summarize(engine.run(q))
    finally:
        if own:
            engine.close()
