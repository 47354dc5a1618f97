"""Does P(FC) predict holding? ``kinegrasp validate``: per grasp, the same noisy draws through
a kinematic engine (force closure as kinegrasp computes it), the physics engine (the paper's
closing under pybullet dynamics) and its lift test (held or dropped).

The draws are :func:`~kinegrasp_env.montecarlo.evaluate.chunk_configurations` of the seed,
the same as ``kinegrasp evaluate`` with that seed and sigma (any engine). The kinematic
outcome comes from the ``fast`` engine by default (it agrees with the ``pybullet`` reference
draw by draw, see ``benchmarks/agreement.py``); ``kinematic="pybullet"`` uses the reference.

Each grasp's per-draw results are cached in ``<out>/cache`` under a key of every setting (and
of the physics, motor and lift settings), so an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import hashlib
import io
import logging
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, Engine, make_engine
from kinegrasp_env.montecarlo.evaluate import DEFAULT_CHUNK, chunk_configurations, chunk_sizes
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.montecarlo.physics_engine import PhysicsEngine
from kinegrasp_env.physics.pybullet_closing import MotorSettings
from kinegrasp_env.physics.pybullet_lift import LiftProfile
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.toolkit.progress import Progress
from kinegrasp_env.world.grasps import Grasp, write_atomic
from kinegrasp_env.world.objects import object_version

log = logging.getLogger(__name__)

KINEMATIC_ENGINES = ("fast", "pybullet")


@dataclass(frozen=True)
class ValidationSettings:
    """What a validation run draws and scores.

    Attributes:
        sigma: joint noise on the 7 arm joints, radians; samples: draws per grasp.
        seed: the draws' seed (the same draws as ``evaluate`` with this seed).
        friction, num_edges: the quality's friction cone (also the simulated mu).
        kinematic: the kinematic engine, ``fast`` (default) or ``pybullet``.
    """

    sigma: float
    samples: int
    seed: int = 0
    friction: float = 0.5
    num_edges: int = 8
    kinematic: str = "fast"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and 0 <= self.sigma <= np.pi):
            raise ValueError(f"sigma must be in [0, pi] radians, got {self.sigma!r}")
        if int(self.samples) != self.samples or self.samples < 1:
            raise ValueError(f"samples must be an integer >= 1, got {self.samples!r}")
        if self.kinematic not in KINEMATIC_ENGINES:
            raise ValueError(f"kinematic engine must be one of {', '.join(KINEMATIC_ENGINES)}, "
                             f"got {self.kinematic!r}")


ARRAYS = ("kin_outcome", "kin_quality", "phys_outcome", "phys_quality", "held", "max_offset",
          "lift_time")


@dataclass
class GraspDraws:
    """One grasp's draws.

    Attributes:
        object, index, id: the grasp (index in its set, id in its file).
        kin_outcome, phys_outcome: (n,) int8 outcome indices (``OUTCOMES``) of the kinematic
            and the physics closing; kin_quality, phys_quality: (n,) their Q.
        held: (n,) bool, the object held through the lift test (False: not closed).
        max_offset: (n,) largest object offset in the palm frame during the test, metres
            (NaN: not lifted); lift_time: (n,) seconds the test ran (NaN: not lifted).
    """

    object: str
    index: int
    id: str
    kin_outcome: np.ndarray
    kin_quality: np.ndarray
    phys_outcome: np.ndarray
    phys_quality: np.ndarray
    held: np.ndarray
    max_offset: np.ndarray
    lift_time: np.ndarray

    @property
    def kin_fc(self) -> np.ndarray:
        return self.kin_outcome == FORCE_CLOSURE

    @property
    def phys_fc(self) -> np.ndarray:
        return self.phys_outcome == FORCE_CLOSURE

    def to_bytes(self) -> bytes:
        buffer = io.BytesIO()
        np.savez(buffer, object=self.object, index=self.index, id=self.id,
                 **{name: getattr(self, name) for name in ARRAYS})
        return buffer.getvalue()

    def __len__(self) -> int:
        return int(self.held.size)

    @classmethod
    def from_file(cls, path: Path, samples: int) -> GraspDraws:
        """The first ``samples`` draws cached in ``path`` (all of them if it holds fewer)."""
        with np.load(path) as data:
            return cls(str(data["object"]), int(data["index"]), str(data["id"]),
                       *(data[name][:samples] for name in ARRAYS))

    def extended(self, more: GraspDraws) -> GraspDraws:
        """These draws followed by ``more`` (the next draws of the same grasp)."""
        return GraspDraws(self.object, self.index, self.id,
                          *(np.concatenate([getattr(self, n), getattr(more, n)]) for n in ARRAYS))


def settings_key(grasp: Grasp, settings: ValidationSettings) -> str:
    """A hash of everything a grasp's draws depend on (its q0, the settings but the number
    of draws, the physics defaults): the name of its cache file. The draws of n samples are
    the first n of any larger number (chunk c's stream is the same whatever its size), so a
    cached run of more draws serves a smaller one, and a larger one runs only the draws
    missing (outcomes and lift results the same as in one run; Q may differ in the last
    bit, as scoring is batched by contact count: 3e-17 measured)."""
    kept = [(f.name, getattr(settings, f.name)) for f in fields(settings) if f.name != "samples"]
    text = repr((grasp.object, grasp.q0.tobytes().hex(), kept, WorldSettings(),
                 MotorSettings(), LiftProfile(), DEFAULT_CHUNK))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# a worker's engines, built on first use: (kinematic, physics) per (object, settings)
_ENGINES: dict[tuple, tuple[Engine, PhysicsEngine]] = {}


def worker_engines(object_name: str, settings: ValidationSettings) -> tuple[Engine, PhysicsEngine]:
    # the object's version too: an object re-imported under the same name gets new engines
    key = (object_name, object_version(object_name), settings.kinematic, settings.friction,
           settings.num_edges)
    if key not in _ENGINES:
        _ENGINES[key] = (make_engine(settings.kinematic, object_name, settings.friction,
                                     settings.num_edges),
                         PhysicsEngine(object_name, settings.friction, settings.num_edges))
    return _ENGINES[key]


def grasp_draws(task: tuple[int, Grasp, ValidationSettings, int]) -> GraspDraws:
    """Run one grasp ``(index, grasp, settings, start)``: its draws start..samples-1 through
    both engines and the lift test (every draw is independent of the others)."""
    index, grasp, settings, start = task
    kinematic, physics = worker_engines(grasp.object, settings)
    chunks = list(enumerate(chunk_sizes(settings.samples, DEFAULT_CHUNK)))
    q = chunk_configurations(grasp.q0, JointNoise(settings.sigma), settings.seed,
                             chunks)[start:]
    kin = kinematic.run(q)
    phys, lift = physics.run_lift(q)
    return GraspDraws(grasp.object, index, grasp.id, kin.outcome, kin.quality, phys.outcome,
                      phys.quality, lift.held, lift.max_offset, lift.time)


def summary_text(draws: GraspDraws) -> str:
    return (f"{draws.object} grasp {draws.index}: P(FC) kinematic {draws.kin_fc.mean():.2f}, "
            f"physics {draws.phys_fc.mean():.2f}, P(hold) {draws.held.mean():.2f}")


def run_validation(grasps: list[tuple[int, Grasp]], settings: ValidationSettings,
                   out_dir: str | Path, processes: int = 1,
                   progress: bool = False) -> list[GraspDraws]:
    """Every grasp's draws (``grasps``: (index in its set, grasp) pairs), in the order given;
    each grasp is read from ``<out_dir>/cache`` when it is there, else run and cached there
    at once (atomically), so a rerun resumes; a cached grasp with fewer draws than
    ``settings.samples`` runs only the missing ones."""
    cache = Path(out_dir) / "cache"
    paths = [cache / f"{g.object}_{i}_{settings_key(g, settings)}.npz" for i, g in grasps]
    results: list[GraspDraws | None] = [
        GraspDraws.from_file(p, settings.samples) if p.exists() else None for p in paths]
    todo = [k for k, r in enumerate(results) if r is None or len(r) < settings.samples]
    done = sum(len(r) for r in results if r is not None)
    if done:
        log.info("validate: %d of %d draws read from %s", done,
                 len(grasps) * settings.samples, cache)
    report = Progress("validate", len(grasps) * settings.samples, len(grasps)) \
        if progress else None
    if report is not None and done:
        report.advance(done)
    with LocalExecutor(processes) as executor:
        tasks = [(*grasps[k], settings, 0 if results[k] is None else len(results[k]))
                 for k in todo]
        for position, new in executor.as_completed(grasp_draws, tasks):
            k = todo[position]
            draws = new if results[k] is None else results[k].extended(new)
            write_atomic(paths[k], draws.to_bytes())
            results[k] = draws
            done += len(new)
            if report is not None:
                report.advance(done)
                report.cell_done(summary_text(draws))
    if report is not None:
        report.close()
    return [r for r in results if r is not None]


@dataclass
class GraspRow:
    """Per-grasp estimates: P(FC) of each engine and P(hold), with Wilson 95% intervals."""

    object: str
    index: int
    id: str
    samples: int
    p_fc_kinematic: float
    p_fc_kinematic_ci: tuple[float, float]
    p_fc_physics: float
    p_fc_physics_ci: tuple[float, float]
    p_hold: float
    p_hold_ci: tuple[float, float]

    @classmethod
    def of(cls, draws: GraspDraws) -> GraspRow:
        n = int(draws.held.size)
        values = []
        for flags in (draws.kin_fc, draws.phys_fc, draws.held):
            k = int(np.sum(flags))
            values += [k / n, wilson_interval(k, n)]
        return cls(draws.object, draws.index, draws.id, n, *values)

    def to_json(self) -> dict:
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}
