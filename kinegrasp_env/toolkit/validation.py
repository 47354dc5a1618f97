"""Does P(FC) predict holding? ``kinegrasp validate``: per grasp, the same noisy draws through
a kinematic engine (force closure as kinegrasp computes it) and the holding test
(:mod:`~kinegrasp_env.physics.protocol`) in a registered simulator: its closing on the pinned
object (the physics outcome and Q), the grip's own displacement of the object after the
release, and the disturbance phases (six gravity directions, the lift, optionally the shake),
each held or not.

The draws are :func:`~kinegrasp_env.montecarlo.evaluate.chunk_configurations` of the seed,
the same as ``kinegrasp evaluate`` with that seed and sigma (any engine). The kinematic
outcome comes from the ``fast`` engine by default (it agrees with the ``pybullet`` reference
draw by draw, see ``benchmarks/agreement.py``); ``kinematic="pybullet"`` uses the reference.

A description robot's grasps (another robot than ``kuka_sdh``) run through
:mod:`~kinegrasp_env.toolkit.robot_validation`, which hands its own draw and cache-key
functions to :func:`run_validation`.

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
from kinegrasp_env.montecarlo.physics_engine import HoldBatch, PhysicsEngine
from kinegrasp_env.physics.protocol import HELD, HOLD_OUTCOMES, PHASES, HoldProtocol
from kinegrasp_env.physics.pybullet_closing import MotorSettings
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.physics.simulators import check_simulator
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
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
        simulator: the simulator of the holding test (registered names:
            :data:`~kinegrasp_env.physics.simulators.SIMULATORS`).
        torque_scale: multiplies the assumed torque limits of the hand's joints.
        shake: run the shake phase after the lift.
    """

    sigma: float
    samples: int
    seed: int = 0
    friction: float = 0.5
    num_edges: int = 8
    kinematic: str = "fast"
    simulator: str = "pybullet"
    torque_scale: float = 1.0
    shake: bool = False

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and 0 <= self.sigma <= np.pi):
            raise ValueError(f"sigma must be in [0, pi] radians, got {self.sigma!r}")
        if int(self.samples) != self.samples or self.samples < 1:
            raise ValueError(f"samples must be an integer >= 1, got {self.samples!r}")
        if self.kinematic not in KINEMATIC_ENGINES:
            raise ValueError(f"kinematic engine must be one of {', '.join(KINEMATIC_ENGINES)}, "
                             f"got {self.kinematic!r}")
        check_simulator(self.simulator)
        self.protocol  # noqa: B018 - checks torque_scale

    @property
    def protocol(self) -> HoldProtocol:
        """The holding protocol of these settings."""
        return HoldProtocol(shake=bool(self.shake), torque_scale=float(self.torque_scale))


#: The kinematic and physics closing's arrays of :class:`GraspDraws`.
CLOSING_ARRAYS = ("kin_outcome", "kin_quality", "phys_outcome", "phys_quality")
#: The holding test's arrays of :class:`GraspDraws`: name -> the field of
#: :class:`~kinegrasp_env.montecarlo.physics_engine.HoldBatch` it is.
HOLD_ARRAYS = {("hold_outcome" if f == "outcome" else f): f for f in HoldBatch.FIELDS}
#: Every array of :class:`GraspDraws`, in the order :meth:`GraspDraws.from_arrays` takes them.
ARRAYS = CLOSING_ARRAYS + tuple(HOLD_ARRAYS)


@dataclass
class GraspDraws:
    """One grasp's draws.

    Attributes:
        object, index, id: the grasp (index in its set, id in its file).
        kin_outcome, phys_outcome: (n,) int8 outcome indices (``OUTCOMES``) of the kinematic
            and the physics closing (the holding test's, object pinned); kin_quality,
            phys_quality: (n,) their Q.
        hold: the holding test (outcome index into ``HOLD_OUTCOMES``; phases in ``PHASES``
            order, 1 held, 0 failed, -1 not run); its arrays are attributes of the draws too
            (:data:`HOLD_ARRAYS`: ``hold_outcome`` is ``hold.outcome``, ``grip_shift`` ...
            ``phase_turn`` the same names).
    """

    object: str
    index: int
    id: str
    kin_outcome: np.ndarray
    kin_quality: np.ndarray
    phys_outcome: np.ndarray
    phys_quality: np.ndarray
    hold: HoldBatch

    @classmethod
    def from_arrays(cls, object: str, index: int, id: str, *arrays: np.ndarray) -> GraspDraws:
        """The draws of a grasp from its arrays in :data:`ARRAYS` order."""
        if len(arrays) != len(ARRAYS):
            raise ValueError(f"expected {len(ARRAYS)} arrays ({', '.join(ARRAYS)}), "
                             f"got {len(arrays)}")
        closing = len(CLOSING_ARRAYS)
        return cls(object, index, id, *arrays[:closing], HoldBatch(*arrays[closing:]))

    def __getattr__(self, name: str):
        if name in HOLD_ARRAYS:  # only names of the holding test (no recursion on "hold")
            return getattr(self.hold, HOLD_ARRAYS[name])
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def held(self) -> np.ndarray:
        """(n,) bool: the draw's holding outcome is ``held`` (grip stood, every phase run
        held)."""
        return self.hold_outcome == HELD

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
        return int(self.hold_outcome.size)

    @classmethod
    def from_file(cls, path: Path, samples: int) -> GraspDraws:
        """The first ``samples`` draws cached in ``path`` (all of them if it holds fewer)."""
        with np.load(path) as data:
            return cls.from_arrays(str(data["object"]), int(data["index"]), str(data["id"]),
                                   *(data[name][:samples] for name in ARRAYS))

    def extended(self, more: GraspDraws) -> GraspDraws:
        """These draws followed by ``more`` (the next draws of the same grasp)."""
        return GraspDraws.from_arrays(
            self.object, self.index, self.id,
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
                 MotorSettings(), settings.protocol, PHASES, HOLD_OUTCOMES, DEFAULT_CHUNK))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# a worker's engines, built on first use: (kinematic, physics) per (object, settings)
_ENGINES: dict[tuple, tuple[Engine, PhysicsEngine]] = {}


def worker_engines(object_name: str, settings: ValidationSettings) -> tuple[Engine, PhysicsEngine]:
    # the object's version too: an object re-imported under the same name gets new engines
    key = (object_name, object_version(object_name), settings.kinematic, settings.friction,
           settings.num_edges, settings.simulator, settings.protocol)
    if key not in _ENGINES:
        _ENGINES[key] = (make_engine(settings.kinematic, object_name, settings.friction,
                                     settings.num_edges),
                         PhysicsEngine(object_name, settings.friction, settings.num_edges,
                                       protocol=settings.protocol,
                                       simulator=settings.simulator))
    return _ENGINES[key]


def grasp_draws(task: tuple[int, Grasp, ValidationSettings, int]) -> GraspDraws:
    """Run one grasp ``(index, grasp, settings, start)``: its draws start..samples-1 through
    the kinematic engine and the holding test (every draw is independent of the others)."""
    index, grasp, settings, start = task
    kinematic, physics = worker_engines(grasp.object, settings)
    chunks = list(enumerate(chunk_sizes(settings.samples, DEFAULT_CHUNK)))
    q = chunk_configurations(grasp.q0, JointNoise(settings.sigma), settings.seed,
                             chunks)[start:]
    kin = kinematic.run(q)
    phys, hold = physics.run_hold(q)
    return GraspDraws(grasp.object, index, grasp.id, kin.outcome, kin.quality, phys.outcome,
                      phys.quality, hold)


def summary_text(draws: GraspDraws) -> str:
    return (f"{draws.object} grasp {draws.index}: P(FC) kinematic {draws.kin_fc.mean():.2f}, "
            f"physics {draws.phys_fc.mean():.2f}, P(hold) {draws.held.mean():.2f}")


def robot_prefix(grasp: Grasp) -> str:
    """The cache file prefix of a grasp: none for the default robot's, else its robot's name
    and ``_``."""
    return "" if grasp.robot == DEFAULT_ROBOT else f"{grasp.robot}_"


def run_validation(grasps: list[tuple[int, Grasp]], settings: ValidationSettings,
                   out_dir: str | Path, processes: int = 1,
                   progress: bool = False, task=None, key=None) -> list[GraspDraws]:
    """Every grasp's draws (``grasps``: (index in its set, grasp) pairs), in the order given;
    each grasp is read from ``<out_dir>/cache`` when it is there, else run and cached there
    at once (atomically), so a rerun resumes; a cached grasp with fewer draws than
    ``settings.samples`` runs only the missing ones. ``task`` and ``key`` replace
    :func:`grasp_draws` and :func:`settings_key` (a description robot's grasps:
    :mod:`~kinegrasp_env.toolkit.robot_validation`; their cache files start with the robot's
    name)."""
    task, key = task or grasp_draws, key or settings_key
    cache = Path(out_dir) / "cache"
    paths = [cache / f"{robot_prefix(g)}{g.object}_{i}_{key(g, settings)}.npz"
             for i, g in grasps]
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
        for position, new in executor.as_completed(task, tasks):
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


def phase_counts(draws: GraspDraws, phases: tuple[str, ...] = PHASES) -> dict[str, dict]:
    """Per phase: ``{"run": draws that ran it, "held": of those, held}``."""
    out = {}
    for name in phases:
        column = draws.phase_held[:, PHASES.index(name)]
        out[name] = {"run": int(np.sum(column >= 0)), "held": int(np.sum(column == 1))}
    return out


def outcome_counts(draws: GraspDraws) -> dict[str, int]:
    """Draws per holding outcome (every name of ``HOLD_OUTCOMES``)."""
    return {name: int(np.sum(draws.hold_outcome == k)) for k, name in enumerate(HOLD_OUTCOMES)}


def millimetres(values: np.ndarray) -> list[float | None]:
    """Metres (n,) as millimetres rounded to 0.01 (None: NaN), for JSON."""
    return [None if not np.isfinite(v) else round(float(v) * 1e3, 2) for v in values]


@dataclass
class GraspRow:
    """Per-grasp estimates: P(FC) of each engine and P(hold), with Wilson 95% intervals;
    the holding outcomes, each phase's counts and the grip's shift per draw."""

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
    outcomes: dict[str, int]
    phases: dict[str, dict]
    draw_outcomes: list[str]
    grip_shift_mm: list[float | None]
    grip_turn_deg: list[float | None]
    pin_force_n: list[float | None]

    @classmethod
    def of(cls, draws: GraspDraws, phases: tuple[str, ...] = PHASES) -> GraspRow:
        n = len(draws)
        values = []
        for flags in (draws.kin_fc, draws.phys_fc, draws.held):
            k = int(np.sum(flags))
            values += [k / n, wilson_interval(k, n)]
        turns = [None if not np.isfinite(v) else round(float(np.degrees(v)), 2)
                 for v in draws.grip_turn]
        return cls(draws.object, draws.index, draws.id, n, *values, outcome_counts(draws),
                   phase_counts(draws, phases), [HOLD_OUTCOMES[k] for k in draws.hold_outcome],
                   millimetres(draws.grip_shift), turns,
                   [None if not np.isfinite(v) else round(float(v), 2) for v in draws.pin_force])

    def to_json(self) -> dict:
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}
