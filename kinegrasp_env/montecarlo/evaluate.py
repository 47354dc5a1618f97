"""P(FC) and Q moments of a grasp of any catalog robot (:func:`evaluate_grasp`).

Each draw: the arm joints at q0 + eps (eps from :class:`~kinegrasp_env.sampling.noise.
JointNoise` on the description's arm joints, the hand at its pre-shape exactly; or a noise
model's every source), the hand closed on the object by an engine (``pybullet``: pybullet
closest points on the URDF's own collision geometry, :meth:`~kinegrasp_env.closing.
generic_reference.RobotWorld.auto_close`; ``fast``: the batched closing of the same model,
:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`; ``physics``: the hand's
motors in pybullet), the contacts scored with the robot's contact model by one function for
every engine (:func:`score`). Every draw ends in one of the outcomes of
:data:`~kinegrasp_env.montecarlo.draws.OUTCOMES`; P(FC) comes with its Wilson interval, Q's
moments are over the force-closure draws. The draws are rows of the run's chunked random
streams (:mod:`~kinegrasp_env.montecarlo.chunks`), the same whatever the number of
processes or the backend.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.montecarlo.description_engine import (
    RobotEngine,
    outcome_of,
    score,
)
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES, DrawBatch
from kinegrasp_env.montecarlo.engines import ENGINES, make_engine
from kinegrasp_env.montecarlo.evaluation_checks import (
    check_engine_grasp,
    check_evaluation,
    integer_seed,
)
from kinegrasp_env.montecarlo.execution import Executor, LocalExecutor
from kinegrasp_env.montecarlo.reference_engine import RobotReferenceEngine
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import (
    JointNoise,
    SeedLike,
    as_generator,
)
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.noise_spec import spec_of
from kinegrasp_env.sampling.stats import skewness, wilson_interval
from kinegrasp_env.world.grasps import Grasp, check_robot

__all__ = [
    "ENGINES",
    "GraspEvaluation",
    "RobotEngine",
    "RobotReferenceEngine",
    "check_engine_grasp",
    "check_robot",
    "evaluate_grasp",
    "make_engine",
    "nominal_robot_quality",
    "outcome_of",
    "robot_configurations",
    "score",
    "summarize",
]


@dataclass(frozen=True)
class GraspEvaluation:
    """Monte Carlo statistics of one grasp.

    Attributes:
        n: draws.
        counts: outcome name -> draws.
        p_fc: fraction in force closure; ci: its Wilson 95% interval.
        q_mean, q_std, q_skew: Q over the force-closure draws (NaN where too few; the
            skewness NaN too where every Q is the same).
        draws: the per-draw results (``keep_draws=False``: without their contacts and
            closed hand, :meth:`~kinegrasp_env.montecarlo.draws.DrawBatch.without_contacts`).
        p_hold_static, hold_ci: the fraction of draws the static hold check held and its
            Wilson 95% interval (NaN where the engine did not check it).
        mass: the object's mass the check used, kg (NaN where not checked).
        q_nominal: Q of the nominal closing (the hand closed once at q0, without noise; 0
            where it is not in force closure; NaN where not computed).
        push_median, push_p95: over the draws where both jaws of a coupled pair touched, the
            median and 95th percentile of the push a coupled pair would give the object,
            metres (:func:`~kinegrasp_env.closing.coupled_jaws.jaw_push`; NaN for other
            hands).
    """

    n: int
    counts: dict[str, int]
    p_fc: float
    ci: tuple[float, float]
    q_mean: float
    q_std: float
    q_skew: float
    draws: DrawBatch
    p_hold_static: float = float("nan")
    hold_ci: tuple[float, float] = (float("nan"), float("nan"))
    mass: float = float("nan")
    q_nominal: float = float("nan")
    push_median: float = float("nan")
    push_p95: float = float("nan")


def summarize(draws: DrawBatch, mass: float | None = None) -> GraspEvaluation:
    """The statistics of per-draw results (see :class:`GraspEvaluation`); ``mass`` (kg): the
    draws carry the static hold check's verdicts, for an object of this mass."""
    n = int(draws.outcome.size)
    fc = draws.outcome == FORCE_CLOSURE
    k = int(fc.sum())
    q = draws.quality[fc]
    hold = {}
    pushed = draws.push[np.isfinite(draws.push)]
    if pushed.size:
        hold.update(push_median=float(np.median(pushed)),
                    push_p95=float(np.percentile(pushed, 95)))
    if mass is not None:
        held = int(draws.holds.sum())
        hold.update(p_hold_static=held / n if n else float("nan"),
                    hold_ci=wilson_interval(held, n), mass=float(mass))
    return GraspEvaluation(
        n, {name: int((draws.outcome == i).sum()) for i, name in enumerate(OUTCOMES)},
        k / n if n else float("nan"), wilson_interval(k, n),
        float(q.mean()) if k else float("nan"),
        float(q.std(ddof=1)) if k > 1 else float("nan"),
        float(skewness(q)) if k > 2 and np.ptp(q) > 0 else float("nan"), draws, **hold)


def nominal_robot_quality(grasp: Grasp, engine: RobotEngine) -> float:
    """Q of the grasp's nominal closing by ``engine`` (the hand closed once at q0, no noise,
    scored with the robot's contact model at the engine's friction); 0 where that closing
    is not in force closure."""
    draw = engine.run(engine.check(grasp.q0))
    return float(draw.quality[0]) if draw.outcome[0] == FORCE_CLOSURE else 0.0


def robot_configurations(grasp: Grasp, engine: RobotEngine, *, sigma: float | tuple[float, ...],
                         n: int, seed: SeedLike = 0, noise: str = "gaussian",
                         offset: int = 0, method: str = "mc") -> np.ndarray:
    """(n, dof) the draws :func:`evaluate_grasp` evaluates: the grasp's q0 with joint
    noise of ``sigma`` (radians) on the engine's robot's arm joints, the hand at its
    pre-shape. An integer or SeedSequence seed draws rows ``offset .. offset + n`` of the
    run's chunked streams (:func:`~kinegrasp_env.montecarlo.chunks.
    chunk_configurations`: the rows a run in chunks draws); a Generator (or None) is drawn
    from directly (``offset`` 0 only). ``method`` samples the noise
    (:data:`~kinegrasp_env.sampling.noise.METHODS`; per chunk of the streams)."""
    q0 = engine.check(grasp.q0)[0]
    arm = engine.description.arm_dof
    if isinstance(seed, (int, np.integer, np.random.SeedSequence)):
        return chunk_configurations(q0, arm, sigma, noise, seed, int(offset), int(n), method)
    eps = JointNoise(sigma, noise).sample(int(n), arm, as_generator(seed), method=method)
    q = np.repeat(q0[None], int(n), axis=0)
    q[:, :arm] += eps
    return q


def evaluation_rows(grasp: Grasp, engine: RobotEngine, *, sigma: float | tuple[float, ...],
                    n: int, seed: SeedLike = 0, noise: str = "gaussian",
                    noise_model: NoiseModel | None = None, offset: int = 0,
                    method: str = "mc") -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(configurations (n, dof), per-draw errors as the engine's ``run`` takes them) of the
    draws :func:`evaluate_grasp` evaluates in one process: joint noise
    (:func:`robot_configurations`, no errors), or the rows of ``noise_model``'s every
    source (:func:`~kinegrasp_env.montecarlo.noise_rows.model_rows`; ``seed`` an
    integer); rows ``offset .. offset + n`` of the run's, the joints sampled by ``method``."""
    if noise_model is None:
        return robot_configurations(grasp, engine, sigma=sigma, n=n, seed=seed,
                                    noise=noise, offset=offset, method=method), {}
    from kinegrasp_env.montecarlo.noise_rows import model_rows

    return model_rows(noise_model, engine.check(grasp.q0)[0], engine.description, int(seed),
                      int(offset), n, engine.obj.center_of_mass, method)


def evaluate_grasp(grasp: Grasp, *, sigma: float | tuple[float, ...] | None = None, n: int,
                   seed: SeedLike = 0, noise: str = "gaussian",
                   engine: RobotEngine | str = "pybullet",
                   robot: str | RobotDescription | None = None,
                   static_hold: bool = False, friction: float = 0.5,
                   executor: Executor | None = None,
                   noise_model: NoiseModel | None = None,
                   offset: int = 0, method: str = "mc",
                   progress: Callable[[int, int], None] | None = None,
                   keep_draws: bool = True) -> GraspEvaluation:
    """P(FC) and Q moments of ``grasp`` over n draws of joint noise on the arm joints, and
    its nominal Q (:func:`nominal_robot_quality`).

    Args:
        grasp: its ``robot`` names the robot (default: ``robot``, or the engine's).
        sigma: radians, scalar or one per arm joint (none with a ``noise_model``).
        n: draws (>= 1).
        seed: seed or Generator of the noise.
        noise: ``gaussian``, ``uniform`` or ``triangular``.
        engine: an engine to reuse (its robot and object must be the grasp's), or the name
            of one to build: ``pybullet`` (the reference), ``fast``
            (:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`) or ``physics``
            (:class:`~kinegrasp_env.montecarlo.physics_engine.RobotPhysicsEngine`).
        robot: the robot to evaluate with (default: the grasp's).
        static_hold: run the static hold check too (an engine to build; a given engine
            checks when it was made with ``static_hold=True``).
        friction: the contacts' mu (an engine to build; a given engine has its own); with a
            ``noise_model`` of a friction source, that source's nominal mu
            (:func:`~kinegrasp_env.sampling.noise_model.nominal_friction`: the draws take
            theirs from the source).
        executor: run the draws in chunks on it (:mod:`~kinegrasp_env.montecarlo.
            chunks`: the same draws, row for row, whatever the processes or backend;
            the seed an integer, the robot a catalog one). None, or a local executor of one
            process: in this process.
        noise_model: every source of error (:mod:`~kinegrasp_env.montecarlo.noise_rows`:
            joints, hand, palm, object, friction; the seed an integer), instead of ``sigma``
            and ``noise`` (refused beside them).
        offset: the draws are rows ``offset .. offset + n`` of the seed's run (an integer or
            SeedSequence seed; e.g. the fresh draws after a selection's:
            :func:`~kinegrasp_env.toolkit.selection.report_rows`).
        method: the joint noise's sampler in each chunk of the streams: ``mc`` (plain Monte
            Carlo), ``antithetic`` (pairs of opposite draws) or ``sobol`` (scrambled Sobol
            points; balanced over whole chunks of 250 rows).
        progress: ``progress(done, n)`` as the chunks of a run on ``executor`` come back
            (with it, a run on an executor of one local process runs in chunks too: the
            same draws and numbers; without an executor it is called once, at the end).
        keep_draws: keep every draw's contacts and closed hand in ``draws`` (about 0.6 kB a
            draw for a hand of 11 finger links). False: ``draws`` keeps what the statistics
            need (:meth:`~kinegrasp_env.montecarlo.draws.DrawBatch.without_contacts`, about
            25 bytes a draw), and a run in this process with an integer or SeedSequence seed
            closes its rows in blocks of :data:`IN_PROCESS_BLOCK`: the same draws and
            numbers, in memory that does not grow with the contacts of n draws.

    Raises:
        ValueError: before any closing, one line each: not a grasp, a grasp of another
            robot or object, an unknown robot, bad n, offset, seed, sigma, noise or method,
            ``sigma`` or ``noise`` beside a ``noise_model``, a noise model of no source or
            of sources the robot or engine cannot take, a ``robot`` that is not the given
            engine's, an unknown engine, a flag that is not a bool, a Generator as the seed
            of a chunked run.
        TypeError: a ``robot`` that is neither a name nor a description.
    """
    name, sigma, friction = check_evaluation(
        grasp, sigma=sigma, n=n, seed=seed, noise=noise, engine=engine, robot=robot,
        static_hold=static_hold, friction=friction, executor=executor,
        noise_model=noise_model, offset=offset, method=method, progress=progress,
        keep_draws=keep_draws)
    if executor is not None and (progress is not None or not (
            isinstance(executor, LocalExecutor) and executor.workers == 1)):
        return _chunked(grasp, name, engine, sigma=sigma, n=n, seed=seed, noise=noise,
                        static_hold=static_hold, friction=friction, executor=executor,
                        noise_model=noise_model, offset=int(offset), method=method,
                        progress=progress, keep_draws=keep_draws)
    own = isinstance(engine, str)
    if own:
        engine = make_engine(engine, grasp.robot if robot is None else robot, grasp.object,
                             static_hold=static_hold, friction=friction)
    try:
        check = engine.hold_check
        draws, nominal = _closed_rows(grasp, engine, sigma=sigma, n=n, seed=seed,
                                      noise=noise, noise_model=noise_model,
                                      offset=int(offset), method=method,
                                      keep_draws=keep_draws)
        stats = summarize(draws, None if check is None else check.mass)
        if progress is not None:
            progress(n, n)
        return replace(stats, q_nominal=float(nominal.quality[0])
                       if nominal.outcome[0] == FORCE_CLOSURE else 0.0)
    finally:
        if own:
            engine.close()


#: Rows an in-process run without its draws' contacts (``keep_draws=False``) closes at a time.
IN_PROCESS_BLOCK = 10_000


def _closed_rows(grasp: Grasp, engine: RobotEngine, *, sigma, n: int, seed: SeedLike,
                 noise: str, noise_model: NoiseModel | None, offset: int, method: str,
                 keep_draws: bool) -> tuple[DrawBatch, DrawBatch]:
    """(the n draws :func:`evaluate_grasp` evaluates in this process, the nominal closing's
    one draw), closed by ``engine``: in one call; without ``keep_draws`` and with a seed of
    row streams, in blocks of :data:`IN_PROCESS_BLOCK` rows (the same rows: each block is
    drawn by its offset), each kept without its contacts. The nominal configuration rides
    with the last block as its last row where the draws carry no per-draw errors, else it
    is closed alone, without errors, as a run in chunks closes it (its Q the same to the
    last digit)."""
    streams = isinstance(seed, (int, np.integer, np.random.SeedSequence))
    block = n if keep_draws or not streams else IN_PROCESS_BLOCK
    q0 = engine.check(grasp.q0)[0]
    parts, nominal = [], None
    for start in range(0, n, block):
        size = min(block, n - start)
        q, errors = evaluation_rows(grasp, engine, sigma=sigma, n=size, seed=seed,
                                    noise=noise, noise_model=noise_model,
                                    offset=offset + start, method=method)
        ride = start + size == n and not errors
        draws = engine.run(np.vstack([q, q0[None]]) if ride else q, **errors)
        if ride:
            nominal, draws = draws.take(slice(size, size + 1)), draws.take(slice(0, size))
        parts.append(draws if keep_draws else draws.without_contacts())
    if nominal is None:
        nominal = engine.run(q0[None])
    return (parts[0] if len(parts) == 1 else DrawBatch.concatenate(parts)), nominal


def _chunked(grasp: Grasp, robot: str, engine: RobotEngine | str, *, sigma, n: int,
             seed: SeedLike, noise: str, static_hold: bool, friction: float,
             executor: Executor, noise_model: NoiseModel | None = None,
             offset: int = 0, method: str = "mc", progress=None,
             keep_draws: bool = True) -> GraspEvaluation:
    """:func:`evaluate_grasp`'s run in chunks on ``executor`` (a given engine passes
    its name and settings to the workers, which build their own); ``progress`` as there."""
    from kinegrasp_env.montecarlo.chunks import (
        RobotChunk,
        chunked_draws,
        nominal_closing_quality,
    )
    from kinegrasp_env.world.objects import load_object

    if noise_model is not None or not isinstance(seed, np.random.SeedSequence):
        integer_seed(seed, "a run in chunks")
    options = ()
    if not isinstance(engine, str):
        static_hold = engine.hold_check is not None
        options = tuple(sorted(engine.options().items()))
        engine, friction = engine.name, engine.friction
    first = RobotChunk(robot, grasp.object, engine, tuple(np.asarray(grasp.q0, float)),
                       sigma if np.ndim(sigma) == 0 else tuple(sigma), noise,
                       seed if isinstance(seed, np.random.SeedSequence) else int(seed),
                       offset, n, friction, static_hold,
                       None if noise_model is None else json.dumps(spec_of(noise_model)),
                       method, options)
    draws = chunked_draws(first, n, executor, progress=progress, keep_contacts=keep_draws)
    stats = summarize(draws, load_object(grasp.object).mass if static_hold else None)
    return replace(stats, q_nominal=nominal_closing_quality(first, executor))
