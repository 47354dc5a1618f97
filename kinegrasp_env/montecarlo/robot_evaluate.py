"""P(FC) and Q moments of a grasp of any description robot, through the reference closing.

Each draw: the arm joints at q0 + eps (eps from :class:`~kinegrasp_env.sampling.noise.
JointNoise` on the description's arm joints, the hand at its pre-shape exactly), the hand
closed on the object by :meth:`~kinegrasp_env.closing.generic_reference.RobotWorld.auto_close`
(pybullet closest points on the URDF's own collision geometry; or by the batched closing of
the same model, :class:`~kinegrasp_env.montecarlo.robot_fast.RobotFastEngine`), the contacts
scored with the robot's contact model (``soft`` for parallel jaws:
:mod:`kinegrasp_env.quality.soft_contacts`) by one function for every engine (:func:`score`).
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


def score(results: list[RobotCloseResult], max_contacts: int, quality) -> RobotDraws:
    """Per-draw results of closings: each one's outcome (:func:`outcome_of`), its contacts
    (at most ``max_contacts``) and, for a candidate, Q by ``quality(points, normals)`` (force
    closure where Q > 0). Every engine of a description robot scores its closings here."""
    out = RobotDraws.empty(len(results), max_contacts)
    for i, result in enumerate(results):
        out.outcome[i] = outcome_of(result)
        k = min(len(result.contacts), max_contacts)
        out.n_contacts[i] = k
        for j, c in enumerate(result.contacts[:k]):
            out.points[i, j], out.normals[i, j] = c.point, c.normal
            out.finger[i, j], out.link[i, j] = c.finger, c.link
        if out.outcome[i] == NO_FORCE_CLOSURE:
            out.quality[i] = quality(out.points[i, :k], out.normals[i, :k])
            if out.quality[i] > 0:
                out.outcome[i] = FORCE_CLOSURE
    return out


class RobotEngine:
    """What every engine of a description robot shares: the robot, the object, the quality
    measure, the input check and the scoring; a subclass closes (:meth:`close_all`).

    Args:
        robot: a catalog name or a loaded description.
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure.
        finger_radius: soft contacts' patch radius (metres).
    """

    name = ""

    def __init__(self, robot: str | RobotDescription, object_name: str, *,
                 friction: float = 0.5, num_edges: int = 8,
                 finger_radius: float = FINGER_RADIUS) -> None:
        self.description = load_robot(robot) if isinstance(robot, str) else robot
        self.obj = load_object(object_name)
        self.friction, self.num_edges, self.finger_radius = friction, num_edges, finger_radius
        self.max_contacts = len(self.description.finger_links)

    def close(self) -> None:
        """Release what the engine holds (nothing by default)."""

    def __enter__(self) -> RobotEngine:
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

    def close_all(self, q: np.ndarray) -> list[RobotCloseResult]:
        """One closing per configuration of q (n, dof) (checked)."""
        raise NotImplementedError

    def run(self, q: np.ndarray) -> RobotDraws:
        """Outcomes of configurations q (n, dof) (arm noisy, hand at its pre-shape)."""
        return score(self.close_all(self.check(q)), self.max_contacts, self.quality)


class RobotReferenceEngine(RobotEngine):
    """The reference engine for a description robot: one pybullet world, draw by draw
    (arguments: :class:`RobotEngine`)."""

    name = "pybullet"

    def __init__(self, robot: str | RobotDescription, object_name: str, **kwargs) -> None:
        super().__init__(robot, object_name, **kwargs)
        self.world = RobotWorld(self.description, self.obj)

    def close(self) -> None:
        self.world.close()

    def close_one(self, q: np.ndarray) -> RobotCloseResult:
        """One closing at configuration q (dof,) (the world is left at its final state)."""
        return self.world.auto_close(self.check(q)[0])

    def close_all(self, q: np.ndarray) -> list[RobotCloseResult]:
        return [self.world.auto_close(row) for row in q]


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


#: The engines of a description robot, by name.
ENGINES = ("pybullet", "fast")


def make_engine(name: str, robot: str | RobotDescription, object_name: str,
                **kwargs) -> RobotEngine:
    """A new engine by name (:data:`ENGINES`) for ``robot`` and catalog ``object_name``."""
    if name == "fast":
        from kinegrasp_env.montecarlo.robot_fast import RobotFastEngine

        return RobotFastEngine(robot, object_name, **kwargs)
    if name == "pybullet":
        return RobotReferenceEngine(robot, object_name, **kwargs)
    raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {name!r}")


def evaluate_robot_grasp(grasp: Grasp, *, sigma: float | tuple[float, ...], n: int,
                         seed: SeedLike = 0, noise: str = "gaussian",
                         engine: RobotEngine | str = "pybullet",
                         robot: str | RobotDescription | None = None) -> RobotEvaluation:
    """P(FC) and Q moments of ``grasp`` over n draws of joint noise on the arm joints.

    Args:
        grasp: its ``robot`` names the robot (default: ``robot``, or the engine's).
        sigma: radians, scalar or one per arm joint.
        n: draws (>= 1).
        seed: seed or Generator of the noise.
        noise: ``gaussian``, ``uniform`` or ``triangular``.
        engine: an engine to reuse (its robot and object must be the grasp's), or the name
            of one to build: ``pybullet`` (the reference) or ``fast``
            (:class:`~kinegrasp_env.montecarlo.robot_fast.RobotFastEngine`).
        robot: the robot to evaluate with (default: the grasp's).

    Raises:
        ValueError: a grasp of another robot or object, bad n or sigma, an unknown engine.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive number of draws, got {n!r}")
    noise_model = JointNoise(sigma, noise)
    if isinstance(engine, str) and engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if not isinstance(engine, str):
        name = engine.description.name
        if engine.obj.name != grasp.object:
            raise ValueError(f"grasp {grasp.id!r} is a grasp of {grasp.object!r}, the engine "
                             f"holds {engine.obj.name!r}")
    else:
        name = grasp.robot if robot is None else getattr(robot, "name", robot)
    check_robot(grasp, name)
    own = isinstance(engine, str)
    if own:
        engine = make_engine(engine, grasp.robot if robot is None else robot, grasp.object)
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
