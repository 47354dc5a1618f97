"""Monte Carlo evaluation of a grasp under noise -> :class:`GraspStats`.

The noise is a :class:`~kinegrasp_env.sampling.noise.JointNoise` (arm joints only) or a
:class:`~kinegrasp_env.sampling.noise_model.NoiseModel` (joints, hand, palm pose, object pose,
friction); a joints-only model gives the ``JointNoise`` numbers bit for bit.

Draws are processed in chunks of a fixed size. Chunk c draws its joint noise from the stream
``SeedSequence(seed, spawn_key=(c,))`` (and a model's other sources from their own children
of it, ``spawn_key=(c, k)``), so the draws, and therefore every statistic, are the same
whatever the number of worker processes; chunk results are merged in chunk order with exact
streaming formulas, so memory stays flat for 10^6 draws and the numbers are identical with
1 or N processes.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field

import numpy as np

from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.engines import (
    FORCE_CLOSURE,
    OUTCOMES,
    Engine,
    cached_engine,
)
from kinegrasp_env.montecarlo.execution import Executor, LocalExecutor
from kinegrasp_env.montecarlo.nominal import nominal_quality
from kinegrasp_env.montecarlo.perturbation import EngineInputs, configurations, engine_inputs
from kinegrasp_env.montecarlo.robot_noise import check_hand
from kinegrasp_env.quality.wrenches import check_parameters
from kinegrasp_env.sampling.noise import (  # noqa: F401  (MAX_SIGMA importable from here too)
    MAX_SIGMA,
    JointNoise,
    check_sigma_bound,
    is_integer_seed,
)
from kinegrasp_env.sampling.noise_model import STREAM_CHUNK, NoiseDraws, NoiseModel, chunk_stream
from kinegrasp_env.sampling.noise_spec import spec_of
from kinegrasp_env.sampling.stats import StreamingMoments, wilson_interval
from kinegrasp_env.world.grasps import DEFAULT_ROBOT, Grasp, check_robot

DEFAULT_CHUNK = STREAM_CHUNK
#: Most chunks the fast engine runs in one call: its auto-close iterations have a fixed
#: cost, so bigger batches are cheaper per draw (10 chunks per call beat 4 on 10,000 draws
#: on 2 processes); results are identical.
FAST_GROUP = 10
ENGINES = ("pybullet", "fast", "physics")
#: What every evaluation takes as its noise.
Noise = JointNoise | NoiseModel
#: Engines that take a model's palm, object and friction errors (the kinematic ones).
ERROR_ENGINES = ("pybullet", "fast")


@dataclass
class GraspStats:
    """Monte Carlo statistics of one grasp.

    Attributes:
        p_fc: fraction of draws in force closure; p_fc_ci: Wilson 95% interval.
        q_mean, q_var, q_std, q_skew: moments of Q over the force-closure draws (NaN if
            fewer than 2 of them; skewness per docs/conventions.md).
        q_nominal: Q of the nominal grasp; error: q_nominal - q_mean (the paper's "Error").
        samples: number of draws; outcomes: counts by outcome name.
        sigma, noise, seed, engine: the settings (sigma and noise describe the joints).
        draws: per-draw results, when requested.
        noise_model: the spec of a :class:`NoiseModel` noise (None for ``JointNoise``).
    """

    p_fc: float
    p_fc_ci: tuple[float, float]
    q_mean: float
    q_var: float
    q_std: float
    q_skew: float
    q_nominal: float
    error: float
    samples: int
    outcomes: dict[str, int]
    sigma: float | list[float]
    noise: str
    seed: int
    engine: str = "pybullet"
    draws: DrawBatch | None = field(default=None, repr=False)
    noise_model: dict | None = None

    def to_json(self) -> dict:
        """JSON-ready dict (NaN becomes None), without the draws (and without
        ``noise_model`` for joint noise)."""
        out = {k: v for k, v in asdict(self).items() if k != "draws"
               and not (k == "noise_model" and v is None)}
        out["p_fc_ci"] = list(self.p_fc_ci)
        for key, value in out.items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
        return out


def chunk_sizes(n_samples: int, chunk: int) -> list[int]:
    return [min(chunk, n_samples - start) for start in range(0, n_samples, chunk)]


def chunk_noise(noise: Noise, seed: int, index: int, size: int,
                method: str = "mc") -> np.ndarray:
    """Arm-joint noise (size, 7) of chunk ``index``: its own stream, derived from the seed."""
    if isinstance(noise, NoiseModel):
        joints = noise.only("joints").draw(seed, index, size, method).joints
        return np.zeros((size, 7)) if joints is None else joints
    return noise.sample(size, 7, chunk_stream(seed, index), method=method)


def chunk_draws(noise: NoiseModel, seed: int, chunks: list[tuple[int, int]],
                method: str = "mc") -> NoiseDraws:
    """A model's draws of chunks ``[(index, size), ...]``, stacked."""
    return NoiseDraws.concatenate([noise.draw(seed, index, size, method)
                                   for index, size in chunks])


# one engine per worker process, built on first use
_ENGINES: dict[tuple, Engine] = {}


def _engine(key: tuple) -> Engine:
    """The worker's engine of ``key`` = (engine, object, friction, num_edges[, static_hold])
    (a new one when the object was re-imported since: :func:`cached_engine`)."""
    return cached_engine(_ENGINES, *key)


def chunk_configurations(q0: np.ndarray, noise: Noise, seed: int,
                         chunks: list[tuple[int, int]], method: str = "mc") -> np.ndarray:
    """q0 (14,) plus the arm noise (and a model's hand offsets) of chunks
    ``[(index, size), ...]``, stacked: (sum sizes, 14)."""
    if isinstance(noise, NoiseModel):
        return configurations(q0, chunk_draws(noise, seed, chunks, method))
    q = np.repeat(np.asarray(q0, dtype=float)[None], sum(size for _, size in chunks), axis=0)
    q[:, :7] += np.concatenate([chunk_noise(noise, seed, index, size, method)
                                for index, size in chunks])
    return q


def chunk_inputs(q0: np.ndarray, noise: Noise, seed: int, chunks: list[tuple[int, int]],
                 method: str, center: np.ndarray) -> EngineInputs:
    """What the engine takes for chunks ``[(index, size), ...]``: the configurations and a
    model's per-draw palm, object and friction errors (``center`` (3,): the object's centre
    of mass, about which an object error rotates)."""
    if isinstance(noise, NoiseModel):
        return engine_inputs(q0, chunk_draws(noise, seed, chunks, method), center)
    return EngineInputs(chunk_configurations(q0, noise, seed, chunks, method))


def run_inputs(engine: Engine, inputs: EngineInputs) -> DrawBatch:
    """``engine.run`` on engine inputs."""
    return engine.run(inputs.q, **inputs.errors())


def draw_chunk(engine: Engine, q0: np.ndarray, noise: Noise, seed: int,
               index: int, size: int, method: str = "mc") -> DrawBatch:
    """Run chunk ``index`` of a run: q0 (14,) plus that chunk's noise, through ``engine``."""
    return run_inputs(engine, chunk_inputs(q0, noise, seed, [(index, size)], method,
                                           engine.obj.center_of_mass))


def draw_rows(engine: Engine, q0: np.ndarray, noise: Noise, seed: int, n: int,
              method: str = "mc") -> DrawBatch:
    """The first n draws of a run of ``seed`` at q0 (14,) through ``engine``, in one call:
    the draws an evaluation of that seed makes (its chunks of :data:`DEFAULT_CHUNK` rows)."""
    chunks = list(enumerate(chunk_sizes(n, DEFAULT_CHUNK)))
    return run_inputs(engine, chunk_inputs(q0, noise, seed, chunks, method,
                                           engine.obj.center_of_mass))


ChunkResult = tuple[np.ndarray, StreamingMoments, DrawBatch | None]


def tally(draws: DrawBatch) -> tuple[np.ndarray, StreamingMoments]:
    """(outcome counts (4,), streaming moments of Q over the force-closure draws) of
    ``draws``: what a chunk contributes to a run's statistics."""
    counts = np.bincount(draws.outcome, minlength=len(OUTCOMES))
    return counts, StreamingMoments(1).update(draws.quality[draws.outcome == FORCE_CLOSURE])


def _run_chunk_group(task: tuple) -> list[ChunkResult]:
    """Chunks ``[(index, size), ...]`` through one engine call (draws are independent of
    their batch, so the results equal one call per chunk); one result per chunk."""
    key, q0, noise, seed, chunks, method, keep = task
    validate_task(q0, noise)
    engine = _engine(key)
    draws = run_inputs(engine, chunk_inputs(q0, noise, seed, chunks, method,
                                            engine.obj.center_of_mass))
    results, start = [], 0
    for _, size in chunks:
        part = draws.part(start, start + size)
        start += size
        counts, moments = tally(part)
        results.append((counts, moments, part if keep else None))
    return results


def group_size(engine: str, n_chunks: int, workers: int) -> int:
    """Chunks per engine call: the fast engine's per-iteration cost is fixed, so it runs up
    to :data:`FAST_GROUP` chunks at once while every worker still gets two tasks."""
    if engine != "fast":
        return 1
    return max(1, min(FAST_GROUP, n_chunks // (2 * max(1, workers))))


def _chunks(tasks: list[tuple], processes: int,
            executor: Executor | None) -> Iterator[ChunkResult]:
    """Chunk results in chunk order, from ``executor`` or a local pool of ``processes``."""
    if executor is not None:
        for group in executor.map(_run_chunk_group, tasks):
            yield from group
        return
    with LocalExecutor(processes) as local:
        for group in local.map(_run_chunk_group, tasks):
            yield from group


def validate_task(q0: np.ndarray, noise: Noise) -> None:
    """Refuse a nominal configuration q0 (14,) that is not finite and a noise whose sigma
    is above :data:`MAX_SIGMA` (both ValueError): non-finite draws are an input error,
    never an outcome."""
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (14,):
        raise ValueError(f"q0 must be 14 finite numbers (radians), got shape {q0.shape}")
    bad = np.flatnonzero(~np.isfinite(q0))
    if bad.size:
        raise ValueError(f"q0 must be 14 finite numbers (radians), got q0[{bad[0]}] = "
                         f"{q0[bad[0]]}")
    check_sigma_bound(noise.sigma_vector(7))


def check_noise_engine(noise: Noise, engine: str) -> None:
    """ValueError (one line) when ``engine`` cannot take a source of the noise model."""
    if isinstance(noise, NoiseModel) and engine not in ERROR_ENGINES:
        extra = [s for s in ("palm", "object", "friction") if getattr(noise, s) is not None]
        if extra:
            raise ValueError(f"the {engine} engine takes joint and hand noise only; the noise "
                             f"model has {', '.join(extra)} errors (use "
                             f"{' or '.join(ERROR_ENGINES)})")


def validate_request(n_samples: int, processes: int, chunk: int) -> None:
    if int(n_samples) != n_samples or n_samples < 1:
        raise ValueError(f"samples must be an integer >= 1, got {n_samples}")
    if int(processes) != processes or processes < 1:
        raise ValueError(f"processes must be an integer >= 1, got {processes}")
    if chunk < 1:
        raise ValueError(f"chunk size must be >= 1, got {chunk}")


def evaluate_grasp(grasp: Grasp, noise: Noise, n_samples: int, seed: int = 0, *,
                   processes: int = 1, friction: float = 0.5, num_edges: int = 8,
                   engine: str = "pybullet", method: str = "mc", chunk: int = DEFAULT_CHUNK,
                   return_draws: bool = False, progress: bool | Callable = False,
                   executor: Executor | None = None, static_hold: bool = False) -> GraspStats:
    """Estimate P(FC) and the moments of Q for ``grasp`` under joint noise.

    Args:
        grasp: the grasp (its q0 is the nominal configuration).
        noise: joint noise on the 7 arm joints (``JointNoise``), or a ``NoiseModel`` of
            every source of error (joints, hand, palm, object, friction; its friction source
            replaces ``friction`` draw by draw).
        n_samples: number of draws.
        seed: run seed; chunk c uses ``SeedSequence(seed, spawn_key=(c,))``.
        processes: local worker processes (results do not depend on it).
        executor: where chunks run (:mod:`kinegrasp_env.montecarlo.execution`: a local pool or
            Ray); overrides ``processes``. Results do not depend on it either.
        friction, num_edges: friction cone of the quality measure.
        engine: ``pybullet`` (the reference) or ``fast`` (batched, against the object's
            distance grid; same noise draws, so the two compare draw by draw).
        method: noise sampler (``mc``, ``antithetic``, ``sobol``: per chunk).
        chunk: draws per chunk (part of the random stream layout: keep it fixed to
            reproduce numbers).
        return_draws: keep every draw's outcome, contacts and Q.
        progress: show a tqdm bar on stderr (True) or call ``progress(done, total)``.
        static_hold: the draws carry the static hold check's verdicts (``held``; kept with
            ``return_draws``: :class:`~kinegrasp_env.montecarlo.engines.Engine`).

    Raises:
        ValueError: a non-finite q0, a sigma above :data:`MAX_SIGMA` (pi radians), or draws
            whose configurations are not finite (checked by every engine before it runs); a
            grasp of another robot than the default one (every robot's grasp is evaluated by
            :func:`~kinegrasp_env.montecarlo.robot_evaluate.evaluate_robot_grasp`, which
            draws the same joint noise as this function for the default robot's).
    """
    validate_request(n_samples, processes, chunk)
    counts, moments, draws = run_chunks(
        grasp, noise, seed, sizes=chunk_sizes(n_samples, chunk), processes=processes,
        friction=friction, num_edges=num_edges, engine=engine, method=method,
        return_draws=return_draws, progress=progress, executor=executor,
        static_hold=static_hold)
    if engine == "physics":  # its own nominal closing, as every robot's evaluation takes it
        from kinegrasp_env.montecarlo.robot_evaluate import nominal_robot_quality

        closing = _engine((engine, grasp.object, float(friction), int(num_edges),
                           bool(static_hold)))  # the run's own engine, where it ran here
        q_nominal = nominal_robot_quality(grasp, closing.robot)
    else:
        q_nominal = nominal_quality(grasp, friction, num_edges)
    return summarize(grasp, noise, seed, engine, counts, moments, draws, q_nominal=q_nominal)


def run_chunks(grasp: Grasp, noise: Noise, seed: int, *, sizes: list[int],
               first_chunk: int = 0, processes: int = 1, friction: float = 0.5,
               num_edges: int = 8, engine: str = "pybullet", method: str = "mc",
               return_draws: bool = False, progress: bool | Callable = False,
               executor: Executor | None = None, static_hold: bool = False
               ) -> tuple[np.ndarray, StreamingMoments, DrawBatch | None]:
    """Run chunks ``first_chunk, first_chunk + 1, ...`` of the given sizes and merge them.

    Returns outcome counts (4,), streaming moments of Q over force-closure draws, and the
    draws if requested (with ``static_hold``, their hold verdicts). Chunk c always draws the
    same noise for the same seed, so a run can be extended later by asking for the next
    chunks (adaptive ranking does).
    """
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; choose from {ENGINES}")
    if not isinstance(noise, (JointNoise, NoiseModel)):
        raise ValueError(f"noise must be a JointNoise or a NoiseModel, got "
                         f"{type(noise).__name__} (sigma s radians on every arm joint: "
                         "JointNoise(s))")
    if not is_integer_seed(seed):
        raise ValueError(f"seed must be an integer >= 0 (chunk c draws from "
                         f"SeedSequence(seed, spawn_key=(c,))), got {seed!r}")
    check_robot(grasp, DEFAULT_ROBOT, "evaluate_grasp takes the default robot's grasps; every "
                "robot's grasp is evaluated by kinegrasp_env.montecarlo.robot_evaluate."
                "evaluate_robot_grasp, as `kinegrasp evaluate` evaluates it")
    validate_task(grasp.q0, noise)
    check_noise_engine(noise, engine)
    if isinstance(noise, NoiseModel) and noise.hand is not None:
        check_hand(noise.hand, DEFAULT_ROBOT)  # before any chunk (in a worker) draws it
    check_parameters(friction, num_edges)
    n_samples = int(sum(sizes))
    key = (engine, grasp.object, float(friction), int(num_edges), bool(static_hold))
    chunks = [(first_chunk + i, size) for i, size in enumerate(sizes)]
    group = group_size(engine, len(chunks), executor.workers if executor else processes)
    tasks = [(key, grasp.q0, noise, int(seed), chunks[i:i + group], method, return_draws)
             for i in range(0, len(chunks), group)]
    counts = np.zeros(len(OUTCOMES), dtype=np.int64)
    moments = StreamingMoments(1)
    kept: list[DrawBatch] = []
    bar = None
    if progress is True:
        from tqdm import tqdm

        bar = tqdm(total=n_samples, desc=f"{grasp.object} grasp {grasp.id}", unit="draw",
                   file=sys.stderr, disable=None)
    done = 0
    results = _chunks(tasks, processes, executor)
    for (chunk_counts, chunk_moments, draws), size in zip(results, sizes, strict=True):
        counts += chunk_counts
        moments.merge(chunk_moments)
        if draws is not None:
            kept.append(draws)
        done += size
        if bar is not None:
            bar.update(size)
        elif callable(progress):
            progress(done, n_samples)
    if bar is not None:
        bar.close()
    return counts, moments, DrawBatch.concatenate(kept) if kept else None


def summarize(grasp: Grasp, noise: Noise, seed: int, engine: str, counts: np.ndarray,
              moments: StreamingMoments, draws: DrawBatch | None, *,
              q_nominal: float | None = None) -> GraspStats:
    """The statistics of merged chunks; ``q_nominal``: the grasp's nominal Q at the run's
    friction (default: the grasp's recorded ``q_nominal``)."""
    q_nominal = grasp.q_nominal if q_nominal is None else float(q_nominal)
    n = int(counts.sum())
    fc = int(counts[FORCE_CLOSURE])
    result = moments.result()
    mean = float(result.mean[0]) if fc else math.nan
    var = float(result.cov[0, 0]) if fc > 1 else math.nan
    sigma = noise.sigma if isinstance(noise.sigma, float) else list(noise.sigma)
    return GraspStats(
        p_fc=fc / n, p_fc_ci=wilson_interval(fc, n), q_mean=mean, q_var=var,
        q_std=math.sqrt(var) if fc > 1 else math.nan,
        q_skew=float(result.skew[0]) if fc > 1 else math.nan, q_nominal=q_nominal,
        error=q_nominal - mean if fc else math.nan, samples=n,
        outcomes={name: int(c) for name, c in zip(OUTCOMES, counts, strict=True)},
        sigma=sigma, noise=noise.kind, seed=int(seed), engine=engine, draws=draws,
        noise_model=spec_of(noise) if isinstance(noise, NoiseModel) else None)

