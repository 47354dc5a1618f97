"""Turning a batch of the default robot's noisy configurations into draw outcomes, by name:
``pybullet`` (the reference), ``fast`` and ``physics`` (its simulated closing) are its
description's engines (:class:`DescriptionEngine`).

Each draw: the arm at q = q0 + eps (eps on the 7 arm joints, the hand pre-shape exact) puts
the flange, hence the hand, somewhere; the hand auto-closes on the object; the contacts give
Q. Every draw ends in exactly one outcome (:data:`OUTCOMES`).

The kinematic engines also take per-draw errors beyond the configuration
(:meth:`Engine.run`): the hand's pose on the flange, the object's true pose, and the friction
coefficient (see :mod:`kinegrasp_env.montecarlo.perturbation`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from kinegrasp_env.montecarlo.draws import (  # noqa: F401  (importable from here too)
    FORCE_CLOSURE,
    MISSED,
    NO_FORCE_CLOSURE,
    OUTCOMES,
    START_COLLISION,
    DrawBatch,
    provisional_outcomes,
)
from kinegrasp_env.montecarlo.perturbation import check_errors
from kinegrasp_env.quality.epsilon import prepare_exact_paths
from kinegrasp_env.quality.wrenches import check_parameters
from kinegrasp_env.robot.default_robot import HAND_JOINTS, default_description
from kinegrasp_env.threads import single_blas_thread
from kinegrasp_env.world.objects import load_object, object_version

if TYPE_CHECKING:  # the description robots' engine module imports this one
    from kinegrasp_env.closing.close_batch import RobotCloseBatch
    from kinegrasp_env.montecarlo.description_engine import RobotEngine

MAX_CONTACTS = 6
#: entries of a configuration: 7 arm joints, then 7 hand DOF
CONFIGURATION_SIZE = 14


def check_configurations(q: np.ndarray) -> np.ndarray:
    """q as a float (n, 14) array of finite configurations (radians); ValueError otherwise,
    naming the first bad draw and joint."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.ndim != 2 or q.shape[1] != CONFIGURATION_SIZE:
        raise ValueError(f"configurations must have shape (n, {CONFIGURATION_SIZE}) "
                         f"(7 arm joints + 7 hand DOF), got {q.shape}")
    bad = ~np.isfinite(q)
    if bad.any():
        draw, joint = (int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"configuration {draw} is not finite: joint {joint} = {q[draw, joint]} "
                         f"({int(bad.any(axis=1).sum())} of {q.shape[0]} configurations have "
                         "NaN or inf entries)")
    return q


@dataclass
class EngineTiming:
    """Seconds spent per stage."""

    kinematics: float = 0.0
    autoclose: float = 0.0
    quality: float = 0.0
    draws: int = 0


class Engine:
    """What the engines share: the object, the quality settings, the input checks and timing.

    Args:
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure.
        static_hold: also run the static hold check on every closing that touches (the
            draws' ``held``: :class:`~kinegrasp_env.montecarlo.hold_check.StaticHoldCheck`
            on the default robot's description, as every robot's engine runs it).
    """

    name = ""
    #: whether :meth:`run` takes per-draw palm, object and friction errors
    takes_errors = False

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8, *,
                 static_hold: bool = False) -> None:
        check_parameters(friction, num_edges)  # before the quality's tables are built
        self.obj = load_object(object_name)
        self.friction = friction
        self.num_edges = num_edges
        self.static_hold = static_hold
        self.timing = EngineTiming()
        prepare_exact_paths(num_edges)  # Q's rarer paths ready before the first draw

    def close(self) -> None:
        """Release what the engine holds."""

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @staticmethod
    def empty_draws(n: int) -> DrawBatch:
        """n draws of the default robot, none closed yet (:data:`MAX_CONTACTS` contact slots,
        its hand joints)."""
        return DrawBatch.empty(n, MAX_CONTACTS, len(HAND_JOINTS))

    def run(self, q: np.ndarray, *, palm: np.ndarray | None = None,
            object_offset: np.ndarray | None = None,
            friction: np.ndarray | None = None) -> DrawBatch:
        """Outcomes of configurations q (n, 14) (arm noisy, hand = pre-shape), radians.

        Per-draw errors (None: exact; engines with ``takes_errors`` only):
            palm: (n, 4, 4) the hand root in the flange frame.
            object_offset: (n, 4, 4) the object's true pose in the frame it was believed at;
                contacts are in the true object's frame.
            friction: (n,) mu of each draw's quality (instead of the engine's friction).

        Raises:
            ValueError: q is not (n, 14) or has a non-finite entry (NaN or inf is an input
                error, never an outcome; nothing reaches the compiled kernels); an error of
                the wrong shape, or one the engine does not take.
        """
        q = check_configurations(q)
        errors = check_errors(q.shape[0], palm, object_offset, friction,
                              static_hold=self.static_hold)
        if errors and not self.takes_errors:
            raise ValueError(f"the {self.name} engine takes joint and hand noise only, not "
                             f"{', '.join(errors)} errors")
        with single_blas_thread():
            return self._run(q, **errors)

    def _run(self, q: np.ndarray, **errors: np.ndarray) -> DrawBatch:  # pragma: no cover
        raise NotImplementedError  # abstract: errors only where takes_errors

    def _account(self, draws: int, *, kinematics: float, autoclose: float,
                 quality: float) -> None:
        self.timing.kinematics += kinematics
        self.timing.autoclose += autoclose
        self.timing.quality += quality
        self.timing.draws += draws


class DescriptionEngine(Engine):
    """An engine of the default robot that is its description's (``kuka_sdh.yaml``) engine of
    the same name (:meth:`engine_class`, as :func:`~kinegrasp_env.montecarlo.robot_engines.
    make_engine` gives it): its closing,
    the support table's start check included, and its scoring (the point contact model's Q,
    :data:`MAX_CONTACTS` contacts a draw).

    Args:
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure.
    """

    takes_errors = True

    @staticmethod
    def engine_class() -> type[RobotEngine]:  # pragma: no cover - each engine names its own
        """The description robots' engine class this engine is."""
        raise NotImplementedError

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8, *,
                 static_hold: bool = False) -> None:
        super().__init__(object_name, friction, num_edges, static_hold=static_hold)
        self.robot = self.engine_class()(default_description(), object_name,
                                         friction=friction, num_edges=num_edges,
                                         max_contacts=MAX_CONTACTS, static_hold=static_hold)

    def close(self) -> None:
        self.robot.close()

    def table_hits(self, q: np.ndarray, palm: np.ndarray | None = None,
                   object_offset: np.ndarray | None = None, **_) -> np.ndarray:
        """(n,) bool: draw i (q (n, 14), radians) puts a link in the object's support table
        (the description engine's :attr:`~kinegrasp_env.montecarlo.description_engine.
        RobotEngine.in_table`; all False without a table). Palm and object errors move the
        robot against the table only in the fast engine's test (:class:`FastEngine`)."""
        if palm is not None or object_offset is not None:
            raise ValueError(f"the {self.name} engine's table test takes no palm or object "
                             "errors (the fast engine's does)")
        return self.robot.in_table(check_configurations(q))

    def closings(self, q: np.ndarray, palm: np.ndarray | None,
                 object_offset: np.ndarray | None) -> RobotCloseBatch:
        """The closings of configurations q (n, 14) with their palm and object errors (None:
        exact; only an engine that :attr:`takes_errors` is given any)."""
        errors = {"palm": palm, "object_offset": object_offset}
        return self.robot.close_batch(q, **{k: v for k, v in errors.items() if v is not None})

    def _run(self, q: np.ndarray, palm: np.ndarray | None = None,
             object_offset: np.ndarray | None = None,
             friction: np.ndarray | None = None) -> DrawBatch:
        t0 = time.perf_counter()
        batch = self.closings(q, palm, object_offset)
        t1 = time.perf_counter()
        out = self.robot.scored(q, batch, friction)
        # the fingers' kinematics is part of the closing
        self._account(len(q), kinematics=0.0, autoclose=t1 - t0,
                      quality=time.perf_counter() - t1)
        return out


class PybulletEngine(DescriptionEngine):
    """The reference engine: the description robots' reference closing, draw by draw
    (:class:`~kinegrasp_env.montecarlo.reference_engine.RobotReferenceEngine`: the whole URDF in
    pybullet, its closest points far from the object and the exact pair of a capsule link
    near it)."""

    name = "pybullet"

    @staticmethod
    def engine_class() -> type[RobotEngine]:
        from kinegrasp_env.montecarlo.reference_engine import RobotReferenceEngine

        return RobotReferenceEngine

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8, *,
                 static_hold: bool = False) -> None:
        super().__init__(object_name, friction, num_edges, static_hold=static_hold)
        #: the robot and the object in pybullet, left at the last draw's closed hand
        self.world = self.robot.world


class FastEngine(DescriptionEngine):
    """The batched engine: the description robots' batched closing
    (:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`:
    :class:`~kinegrasp_env.closing.generic_fast.FastRobotHand`, with the start collision by
    exact distances, and the capsule fingers by the compiled capsule loop against the
    object's distance grid)."""

    name = "fast"

    @staticmethod
    def engine_class() -> type[RobotEngine]:
        from kinegrasp_env.montecarlo.batched_engine import RobotFastEngine

        return RobotFastEngine

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8, *,
                 static_hold: bool = False) -> None:
        super().__init__(object_name, friction, num_edges, static_hold=static_hold)
        self.hand = self.robot.hand

    def table_hits(self, q: np.ndarray, palm: np.ndarray | None = None,
                   object_offset: np.ndarray | None = None, **_) -> np.ndarray:
        """(n,) bool: draw i (q (n, 14), radians; per-draw errors as in :meth:`run`) puts a
        link in the object's support table (the description's test:
        :meth:`~kinegrasp_env.closing.generic_fast.FastRobotHand.table_hits`)."""
        maps = None
        if palm is not None or object_offset is not None:
            maps = self.hand.error_maps(q, palm, object_offset)
        return self.hand.table_hits(q, maps)

    def closings(self, q: np.ndarray, palm: np.ndarray | None,
                 object_offset: np.ndarray | None) -> RobotCloseBatch:
        """One closing of the whole group of chunks (its iterations' cost is per call)."""
        return self.hand.close_batch(q, palm=palm, object_offset=object_offset)


class PhysicsEngine(DescriptionEngine):
    """The closing under pybullet dynamics: the description robots' physics engine, draw by
    draw (:class:`~kinegrasp_env.montecarlo.robot_physics.RobotPhysicsEngine`: the hand's
    motors from its description, the object free); joint and hand noise only."""

    name = "physics"
    takes_errors = False

    @staticmethod
    def engine_class() -> type[RobotEngine]:
        from kinegrasp_env.montecarlo.robot_physics import RobotPhysicsEngine

        return RobotPhysicsEngine


ENGINE_CLASSES = {"pybullet": PybulletEngine, "fast": FastEngine, "physics": PhysicsEngine}


def make_engine(name: str, object_name: str, friction: float = 0.5,
                num_edges: int = 8, static_hold: bool = False) -> Engine:
    """An engine by name (``pybullet``, ``fast`` or ``physics``); ``static_hold``: its draws
    carry the static hold check's verdicts (:class:`Engine`)."""
    if name not in ENGINE_CLASSES:
        raise ValueError(f"unknown engine {name!r}; choose from {', '.join(ENGINE_CLASSES)}")
    return ENGINE_CLASSES[name](object_name, friction, num_edges, static_hold=static_hold)


def cached_engine(cache: dict[tuple, Engine], name: str, object_name: str,
                  friction: float = 0.5, num_edges: int = 8,
                  static_hold: bool = False) -> Engine:
    """:func:`make_engine`'s engine, kept in ``cache`` (e.g. one per worker process) under
    its settings and the object's :func:`~kinegrasp_env.world.objects.object_version`: an
    object re-imported under the same name gets a new engine (the stale one is closed), and
    at most :data:`~kinegrasp_env.montecarlo.execution.MAX_ENGINES` are kept (the oldest is
    closed)."""
    from kinegrasp_env.montecarlo.execution import MAX_ENGINES

    key = (name, object_name, friction, num_edges, static_hold)
    versioned = (*key, object_version(object_name))
    engine = cache.get(versioned)
    if engine is None:
        for stale in [k for k in cache if k[:len(key)] == key]:
            cache.pop(stale).close()
        while len(cache) >= MAX_ENGINES:
            cache.pop(next(iter(cache))).close()
        engine = cache[versioned] = make_engine(name, object_name, friction, num_edges,
                                                static_hold)
    return engine
