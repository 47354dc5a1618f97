"""A robot's draws in chunks, on any executor (a local process pool or Ray).

Draw i of a run is row i of the run's joint noise (``JointNoise(sigma, noise)`` on the arm
joints, drawn in the chunked streams every run has: :func:`~kinegrasp_env.sampling.
noise_model.stream_rows`) added to the arm joints of q0 (the hand at its pre-shape exactly; a
noise model's rows, every source's, from :func:`~kinegrasp_env.montecarlo.noise_rows.
model_rows`). The rows do not depend on how many are drawn, so a chunk of rows ``offset ..
offset + size`` closes the same configurations whichever process runs it: a run split into
chunks over any number of processes gives the draws of the run in one process, row for row.

Engines are built once per process and kept (:func:`robot_engine`), so a worker's later
chunks of the same robot, object and settings reuse them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.execution import MAX_ENGINES, Executor
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import STREAM_CHUNK, NoiseModel, stream_rows

#: Draws per chunk.
CHUNK = STREAM_CHUNK
#: Most chunks the fast engine closes in one task: its closing's iterations cost the same for
#: any batch, so bigger batches are cheaper per draw; the draws are the same rows either way.
FAST_GROUP = 10
_ENGINES: dict[tuple, RobotEngine] = {}


def robot_engine(engine: str, robot: str, object_name: str, friction: float = 0.5,
                 static_hold: bool = False, **options) -> RobotEngine:
    """This process's engine ``engine`` of catalog robot ``robot`` and ``object_name`` at
    friction mu ``friction`` (with the static hold check when asked; ``options``: the
    engine's other settings where they differ from the defaults, :meth:`~kinegrasp_env.
    montecarlo.description_engine.RobotEngine.options`), built on first use
    and kept under the object's :func:`~kinegrasp_env.world.objects.object_version`: an
    object re-imported under the same name gets a new engine (the stale one is closed)."""
    from kinegrasp_env.world.objects import object_version

    settings = (engine, robot, object_name, float(friction), bool(static_hold),
                repr(sorted(options.items())))
    key = (*settings, object_version(object_name))
    if key not in _ENGINES:
        from kinegrasp_env.montecarlo.engines import make_engine

        for stale in [k for k in _ENGINES if k[:len(settings)] == settings]:
            _ENGINES.pop(stale).close()
        while len(_ENGINES) >= MAX_ENGINES:
            _ENGINES.pop(next(iter(_ENGINES))).close()
        _ENGINES[key] = make_engine(engine, robot, object_name, friction=friction,
                                    static_hold=static_hold, **options)
    return _ENGINES[key]


def close_engines() -> None:
    """Close every engine this process keeps."""
    while _ENGINES:
        _ENGINES.popitem()[1].close()


def chunk_configurations(q0: np.ndarray, arm_dof: int, sigma: float | tuple[float, ...],
                         noise: str, seed: int, offset: int, size: int,
                         method: str = "mc") -> np.ndarray:
    """(size, dof) configurations: q0 (dof,) with rows ``offset .. offset + size`` of the
    run's stream (sigma: radians, scalar or one per arm joint; ``method``: each chunk's
    sampler, :data:`~kinegrasp_env.sampling.noise.METHODS`) added to its first ``arm_dof``
    entries."""
    joints = JointNoise(sigma, noise)
    eps = stream_rows(seed, "joints", offset, size,
                      lambda generator, rows: joints.sample(rows, arm_dof, generator,
                                                            method=method))
    q = np.repeat(np.asarray(q0, dtype=float)[None], size, axis=0)
    q[:, :arm_dof] += eps
    return q


@dataclass(frozen=True)
class RobotChunk:
    """Rows ``offset .. offset + size`` of one run (what a worker needs, picklable).

    Attributes:
        robot, object: catalog names; engine: ``pybullet``, ``fast`` or ``physics``.
        q0: the grasp's nominal configuration (dof,), radians (metres for prismatic joints).
        sigma, noise, seed: the run's joint noise and seed (an integer, or a
            :class:`numpy.random.SeedSequence` for joint noise alone).
        friction: the contacts' mu; static_hold: run the static hold check too.
        model: a noise model's spec JSON (:func:`~kinegrasp_env.sampling.noise_spec.
            spec_of`), which replaces ``sigma`` and ``noise``
            (:mod:`~kinegrasp_env.montecarlo.noise_rows`); None: joint noise alone.
        method: each chunk's sampler of the joint noise (``mc``, ``antithetic``, ``sobol``).
        options: the engine's other settings, as (name, value) pairs (:func:`robot_engine`;
            a given engine's, which the workers rebuild); empty: the defaults.
    """

    robot: str
    object: str
    engine: str
    q0: tuple[float, ...]
    sigma: float | tuple[float, ...]
    noise: str
    seed: int | np.random.SeedSequence
    offset: int
    size: int
    friction: float = 0.5
    static_hold: bool = False
    model: str | None = None
    method: str = "mc"
    options: tuple[tuple[str, object], ...] = ()


def run_robot_chunk(task: RobotChunk) -> DrawBatch:
    """The draws of one chunk (in a worker, or inline)."""
    if task.model is None:
        return close_chunk(task)
    import json

    from kinegrasp_env.sampling.noise_spec import noise_model_from_spec

    return close_chunk(task, noise_model_from_spec(json.loads(task.model)))


def close_chunk(task: RobotChunk, model: NoiseModel | None = None) -> DrawBatch:
    """The draws of one chunk, with the noise model ``model`` in place of the task's joint
    noise (its ``model`` field is not read)."""
    engine = robot_engine(task.engine, task.robot, task.object, task.friction,
                          task.static_hold, **dict(task.options))
    q, errors = chunk_rows(task, engine.description, engine.obj.center_of_mass, model)
    return engine.run(q, **errors)


def chunk_rows(task: RobotChunk, description: RobotDescription, center: np.ndarray,
               model: NoiseModel | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(configurations (size, dof), per-draw errors as an engine's ``run`` takes them) of
    the chunk's rows for ``description`` (the object's centre of mass ``center`` (3,)):
    joint noise (:func:`chunk_configurations`, no errors), or with ``model`` its every
    source's rows (:func:`~kinegrasp_env.montecarlo.noise_rows.model_rows`)."""
    if model is None:
        return chunk_configurations(np.asarray(task.q0, dtype=float), description.arm_dof,
                                    task.sigma, task.noise, task.seed, task.offset,
                                    task.size, task.method), {}
    from kinegrasp_env.montecarlo.noise_rows import model_rows

    return model_rows(model, task.q0, description, task.seed, task.offset, task.size,
                      center, task.method)


def task_rows(engine: str, n: int, workers: int) -> int:
    """Rows per task of a run of n draws on ``workers`` processes: one chunk, or for the fast
    engine up to :data:`FAST_GROUP` chunks while every worker still gets two tasks."""
    if engine != "fast":
        return CHUNK
    chunks = -(-n // CHUNK)
    return CHUNK * max(1, min(FAST_GROUP, chunks // (2 * max(1, workers))))


def chunked_draws(first: RobotChunk, n: int, executor: Executor, chunk: int | None = None,
                  progress: Callable[[int, int], None] | None = None,
                  keep_contacts: bool = True) -> DrawBatch:
    """Rows ``first.offset .. first.offset + n`` of ``first``'s run (its ``size`` is
    ignored), split into tasks of ``chunk`` draws (default: :func:`task_rows`) run on
    ``executor``, in row order; ``progress(done, n)`` after each task comes back.
    ``keep_contacts=False``: each task's draws are kept :meth:`~kinegrasp_env.montecarlo.
    draws.DrawBatch.without_contacts` as they come back."""
    from dataclasses import replace

    chunk = task_rows(first.engine, n, executor.workers) if chunk is None else chunk
    tasks = [replace(first, offset=first.offset + start, size=min(chunk, n - start))
             for start in range(0, n, chunk)]
    parts, done = [], 0
    for part in executor.map(run_robot_chunk, tasks):
        parts.append(part if keep_contacts else part.without_contacts())
        done += len(part.outcome)
        if progress is not None:
            progress(done, n)
    return DrawBatch.concatenate(parts)


def nominal_closing_quality(first: RobotChunk, executor: Executor) -> float:
    """Q of the closing at ``first``'s q0 without noise (its engine and friction, run on
    ``executor``); 0 where it is not in force closure."""
    from dataclasses import replace

    from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE

    exact = replace(first, sigma=0.0, offset=0, size=1, model=None)
    draw = next(executor.map(run_robot_chunk, [exact]))
    return float(draw.quality[0]) if draw.outcome[0] == FORCE_CLOSURE else 0.0
