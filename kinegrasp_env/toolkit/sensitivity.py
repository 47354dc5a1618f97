"""Which source of error limits a grasp: P(FC) per source and Sobol indices of force closure.

For a grasp and a :class:`~kinegrasp_env.sampling.noise_model.NoiseModel` with sources
(joints, hand, palm, object, friction), :func:`analyze` reports

* P(FC) with all sources, with each source alone, and with all but one, each with its
  Wilson 95% interval; all on the same draws (every source draws from its own stream, so
  "alone" and "all but one" reuse the draws of "all": their differences are paired). The
  gain of a source is P(FC) without it minus P(FC) with all: what making it exact would
  bring, with a paired 95% interval (normal, over the per-draw differences);
* the first-order and total Sobol indices of the force-closure indicator per source, the
  factors being the sources' blocks of random inputs (:mod:`kinegrasp_env.sampling.sobol`:
  Saltelli 2010 and Jansen 1999, percentile bootstrap intervals).

The sample A is the run's draws (chunks 0, 1, ... of the seed: its "all sources" P(FC) is
``evaluate_grasp`` with the same seed); B is the next chunks of the same seed, independent of
A. Friction only enters the scoring, so draws that share their geometric blocks are closed
once and only re-scored. Cost: N (2 + 3 g) draws for g geometric sources (friction adds
none), plus one.

A description robot (any catalog robot but ``kuka_sdh``): :func:`analyze_joints`, the same
analysis with one factor per arm joint and one per other source of its noise model (palm,
object, friction: :mod:`kinegrasp_env.montecarlo.robot_noise`), the robot's engine. A is
``evaluate_robot_grasp``'s draws with the same seed (rows 0 .. N-1 of each source's stream),
B the rows N .. 2N-1; a setting is closed once per distinct choice of rows (a joint of sigma
0 draws 0 in A and in B), so with g noisy factors it costs N (2 + 3 g) draws at most, plus
one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, NO_FORCE_CLOSURE, Engine
from kinegrasp_env.montecarlo.evaluate import (
    DEFAULT_CHUNK,
    check_noise_engine,
    chunk_draws,
    chunk_sizes,
)
from kinegrasp_env.montecarlo.perturbation import engine_inputs
from kinegrasp_env.montecarlo.robot_noise import with_hand
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseDraws, NoiseModel
from kinegrasp_env.sampling.noise_spec import spec_of
from kinegrasp_env.sampling.sobol import sobol_indices
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.world.grasps import Grasp

#: Sources that move the hand relative to the object (closing); friction only scores.
GEOMETRIC = ("joints", "hand", "palm", "object")


@dataclass
class SourceEffect:
    """One source: P(FC) alone and without it (Wilson 95%), the gain of making it exact
    (paired 95% interval), its Sobol indices (bootstrap intervals)."""

    source: str
    p_alone: float
    p_alone_ci: tuple[float, float]
    p_without: float
    p_without_ci: tuple[float, float]
    gain: float
    gain_ci: tuple[float, float]
    first: float
    first_ci: tuple[float, float]
    total: float
    total_ci: tuple[float, float]


@dataclass
class Sensitivity:
    """The result of :func:`analyze` (P(FC) with every source, and per source)."""

    object: str
    grasp: str
    samples: int
    seed: int
    engine: str
    p_all: float
    p_all_ci: tuple[float, float]
    variance: float
    effects: list[SourceEffect] = field(default_factory=list)
    noise_model: dict = field(default_factory=dict)
    #: a description robot's name (its factors are its arm joints); None: ``kuka_sdh``
    robot: str | None = None

    @property
    def dominant(self) -> str | None:
        """The source with the largest total index (None when none is defined)."""
        defined = [e for e in self.effects if math.isfinite(e.total)]
        return max(defined, key=lambda e: e.total).source if defined else None

    @property
    def most_to_gain(self) -> str:
        """The source whose removal raises P(FC) the most."""
        return max(self.effects, key=lambda e: e.gain).source

    def to_json(self) -> dict:
        """JSON-ready dict (NaN becomes None)."""
        def clean(value):
            if isinstance(value, float) and not math.isfinite(value):
                return None
            if isinstance(value, (list, tuple)):
                return [clean(v) for v in value]
            if isinstance(value, dict):
                return {k: clean(v) for k, v in value.items()}
            return value

        out = {k: getattr(self, k) for k in ("object", "grasp", "samples", "seed", "engine",
                                             "p_all", "p_all_ci", "variance", "noise_model")}
        if self.robot is not None:
            out = {"robot": self.robot, **out}
        out["dominant"] = self.dominant
        out["most_to_gain"] = self.most_to_gain
        out["sources"] = [vars(e) for e in self.effects]
        return clean(out)

    def table(self) -> str:
        """A console table, one row per source."""
        lo, hi = self.p_all_ci
        robot = "" if self.robot is None else f"robot {self.robot}, "
        w = max([9, *(len(e.source) + 1 for e in self.effects)])
        lines = [f"{robot}{self.object} grasp {self.grasp}, {self.samples} draws per setting, "
                 f"{self.engine} engine: P(FC) with all sources {self.p_all:.3f} "
                 f"({lo:.3f} .. {hi:.3f})",
                 f"{'source':<{w}} {'P(FC) alone':>11} {'all but it':>10} "
                 f"{'gain if exact (95%)':>24} {'first-order S (95%)':>22} "
                 f"{'total ST (95%)':>22}"]
        for e in self.effects:
            lines.append(f"{e.source:<{w}} {e.p_alone:>11.3f} {e.p_without:>10.3f} "
                         f"{_index(e.gain, e.gain_ci):>24} {_index(e.first, e.first_ci):>22} "
                         f"{_index(e.total, e.total_ci):>22}")
        lines.append(f"dominant source (largest total index): {self.dominant or 'undefined'};"
                     f" most to gain from making exact: {self.most_to_gain}")
        return "\n".join(lines)


def paired_gain(with_all: np.ndarray, without: np.ndarray) -> tuple[float, tuple[float, float]]:
    """Mean of the per-draw differences ``without - with_all`` (N,) and its normal 95%
    interval (the draws are paired: the same draws with and without a source)."""
    diff = without - with_all
    half = 1.959963984540054 * float(diff.std(ddof=1)) / math.sqrt(diff.size)
    mean = float(diff.mean())
    return mean, (mean - half, mean + half)


def _index(value: float, ci: tuple[float, float]) -> str:
    if not math.isfinite(value):
        return "-"
    return f"{value:6.3f} [{ci[0]:6.3f}, {ci[1]:6.3f}]"


class _FCOracle:
    """The force-closure indicator of draw variants, closing each geometry once."""

    def __init__(self, engine: Engine, q0: np.ndarray, size: int) -> None:
        self.engine, self.q0, self.size = engine, np.asarray(q0, dtype=float), size
        self.closed: dict[tuple, DrawBatch] = {}
        self.draws = 0

    def force_closure(self, draws: NoiseDraws, key: tuple) -> np.ndarray:
        """(N,) bool for ``draws``; ``key`` names its geometric blocks (equal key, equal
        geometry)."""
        batch = self.closed.get(key)
        if batch is None:
            batch = self.closed[key] = self._close(draws)
        if draws.friction is None:
            return batch.outcome == FORCE_CLOSURE
        outcome = np.where(batch.outcome == FORCE_CLOSURE, NO_FORCE_CLOSURE, batch.outcome)
        rescored = replace(batch, outcome=outcome.astype(np.int8), quality=np.zeros(self.size))
        self.engine.score(rescored, draws.friction)
        return rescored.outcome == FORCE_CLOSURE

    def _close(self, draws: NoiseDraws) -> DrawBatch:
        geometry = draws.with_block("friction", None)
        if not any(geometry.block(s) is not None for s in GEOMETRIC):  # the nominal grasp
            one = self.engine.run(self.q0[None])
            self.draws += 1
            return DrawBatch.concatenate([one] * self.size)
        inputs = engine_inputs(self.q0, geometry, self.engine.obj.center_of_mass)
        self.draws += self.size
        return self.engine.run(inputs.q, **inputs.errors())


def analyze(grasp: Grasp, model: NoiseModel, samples: int, seed: int = 0, *,
            engine: Engine, bootstrap: int = 1000, chunk: int = DEFAULT_CHUNK,
            progress: Callable[[int, int], None] | None = None) -> Sensitivity:
    """P(FC) per source and Sobol indices of force closure (module docstring).

    Args:
        grasp: the grasp (q0 (14,), radians).
        model: the noise model; its sources are the factors.
        samples: N, draws per setting (>= 2).
        seed: run seed (A: chunks 0.. of it, as ``evaluate_grasp``; B: the chunks after).
        engine: a kinematic engine for ``grasp.object`` (``make_engine``).
        bootstrap: resamples for the Sobol intervals.
        chunk: draws per chunk (the stream layout; keep the default to match evaluate).
        progress: called with (settings done, settings) after every setting.
    """
    if int(samples) != samples or samples < 2:
        raise ValueError(f"samples must be an integer >= 2, got {samples}")
    sources = model.sources
    if not sources:
        raise ValueError("the noise model has no source of error: nothing to analyze")
    check_noise_engine(model, engine.name)
    sizes = chunk_sizes(int(samples), chunk)
    draws_a = chunk_draws(model, seed, list(enumerate(sizes)))
    draws_b = chunk_draws(model, seed, [(len(sizes) + c, s) for c, s in enumerate(sizes)])
    oracle = _FCOracle(engine, grasp.q0, int(samples))
    settings = _settings(sources, draws_a, draws_b)
    y: dict[str, np.ndarray] = {}
    for done, (name, variant, key) in enumerate(settings, 1):
        y[name] = oracle.force_closure(variant, key).astype(float)
        if progress is not None:
            progress(done, len(settings))
    return _result(grasp, y, sources, int(samples), int(seed), engine.name, bootstrap,
                   spec_of(model))


def _result(grasp: Grasp, y: dict[str, np.ndarray], factors: tuple[str, ...], n: int,
            seed: int, engine: str, bootstrap: int, noise_model: dict,
            robot: str | None = None) -> Sensitivity:
    """The :class:`Sensitivity` of the force-closure indicators ``y`` (setting name -> (n,)
    0/1; the settings of :func:`_settings`) of every factor."""
    indices = sobol_indices(y["A"], y["B"], {s: y[f"AB:{s}"] for s in factors},
                            bootstrap=bootstrap, seed=seed)
    effects = []
    for s in factors:
        alone, without = y[f"alone:{s}"], y[f"without:{s}"]
        effects.append(SourceEffect(
            s, float(alone.mean()), wilson_interval(int(alone.sum()), n),
            float(without.mean()), wilson_interval(int(without.sum()), n),
            *paired_gain(y["A"], without), indices[s].first, indices[s].first_ci,
            indices[s].total, indices[s].total_ci))
    both = np.concatenate([y["A"], y["B"]])
    return Sensitivity(grasp.object, str(grasp.id), n, seed, engine,
                       float(y["A"].mean()), wilson_interval(int(y["A"].sum()), n),
                       float(both.var(ddof=1)), effects, noise_model, robot)


def analyze_joints(grasp: Grasp, noise: JointNoise | NoiseModel, samples: int, seed: int = 0,
                   *, engine: RobotEngine, bootstrap: int = 1000,
                   progress: Callable[[int, int], None] | None = None) -> Sensitivity:
    """P(FC) per factor and Sobol indices of force closure of a description robot's grasp,
    one factor per arm joint (named by the description's ``arm_joints``) and, for a noise
    model, one per hand, palm, object and friction source (module docstring).

    Args:
        grasp: a grasp of ``engine``'s robot and object (q0: its actuated vector).
        noise: joint noise on the arm joints (sigma scalar or one per arm joint, radians),
            or a noise model of the robot's sources.
        samples: N, draws per setting (>= 2).
        seed: A = ``evaluate_robot_grasp``'s draws with this seed; B = the next N rows.
        engine: the robot's engine (``robot_evaluate.make_engine``).
        bootstrap: resamples for the Sobol intervals.
        progress: called with (settings done, settings) after every setting.

    Raises:
        ValueError: a grasp of another robot or object, bad samples or sigma, a noise model
            the robot cannot take.
    """
    from kinegrasp_env.montecarlo.robot_noise import (
        check_robot_noise,
        error_rows,
        hand_rows,
        joint_rows,
    )
    from kinegrasp_env.sampling.noise_model import as_noise_model
    from kinegrasp_env.world.grasps import check_robot

    if int(samples) != samples or samples < 2:
        raise ValueError(f"samples must be an integer >= 2, got {samples}")
    description = engine.description
    check_robot(grasp, description.name)
    if grasp.object != engine.obj.name:
        raise ValueError(f"grasp {grasp.id!r} is a grasp of {grasp.object!r}, the engine "
                         f"holds {engine.obj.name!r}")
    model = as_noise_model(noise)
    n, arm = int(samples), description.arm_dof
    check_robot_noise(model, description, arm, engine.name, engine.hold_check is not None)
    if model.joints is not None and model.joints.covariance is not None:
        raise ValueError("one factor per arm joint needs independent joint errors; the "
                         "spec's joints covariance correlates them (give sigmas)")
    q0 = engine.check(grasp.q0)[0]
    stream = joint_rows(model, arm, int(seed), 0, 2 * n)
    noisy = model.sigma_vector(arm) > 0
    errors = error_rows(model, int(seed), 0, 2 * n, engine.obj.center_of_mass)
    if model.hand is not None and not model.hand.exact:  # the pre-shape's offsets
        errors["hand"] = hand_rows(model, description, int(seed), 0, 2 * n)
    sources = tuple(k for k in ("hand", "palm", "object_offset", "friction") if k in errors)
    factors = (*description.arm_joints, *(SOURCE_NAMES[k] for k in sources))
    blocks = {"A": (stream[:n], {k: v[:n] for k, v in errors.items()}),
              "B": (stream[n:], {k: v[n:] for k, v in errors.items()})}
    settings = _joint_settings(factors)
    closed: dict[tuple, np.ndarray] = {}
    y: dict[str, np.ndarray] = {}
    for done, (name, rows) in enumerate(settings, 1):
        key = tuple(r if j >= arm or noisy[j] else "0" for j, r in enumerate(rows))
        if key not in closed:
            closed[key] = _joint_fc(engine, q0, n, key, blocks, sources)
        y[name] = closed[key]
        if progress is not None:
            progress(done, len(settings))
    return _result(grasp, y, factors, n, int(seed), engine.name, bootstrap, spec_of(model),
                   description.name)


#: A description robot's source factors, by their key in the engine's errors.
SOURCE_NAMES = {"hand": "hand", "palm": "palm", "object_offset": "object",
                "friction": "friction"}


def _joint_settings(joints: tuple[str, ...]) -> list[tuple[str, tuple[str, ...]]]:
    """(name, per joint the rows it draws: ``A``, ``B`` or ``0`` exact) of every setting:
    A, B, and per joint AB, alone and without (as :func:`_settings`)."""
    k = len(joints)
    out = [("A", ("A",) * k), ("B", ("B",) * k)]
    for j, name in enumerate(joints):
        out.append((f"AB:{name}", tuple("B" if i == j else "A" for i in range(k))))
        out.append((f"alone:{name}", tuple("A" if i == j else "0" for i in range(k))))
        out.append((f"without:{name}", tuple("0" if i == j else "A" for i in range(k))))
    return out


def _joint_fc(engine: RobotEngine, q0: np.ndarray, n: int, rows: tuple[str, ...],
              blocks: dict[str, tuple], sources: tuple[str, ...] = ()) -> np.ndarray:
    """(n,) 0/1 force closure with arm joint j at column j of ``blocks[rows[j]]``'s joint
    rows and source ``sources[k]`` (an engine error) at ``blocks[rows[arm + k]]``'s (0:
    exact)."""
    if all(r == "0" for r in rows):  # the nominal grasp: closed once
        return np.repeat(float(engine.run(q0[None]).outcome[0] == FORCE_CLOSURE), n)
    arm = len(rows) - len(sources)
    q = np.repeat(q0[None], n, axis=0)
    for j, r in enumerate(rows[:arm]):
        if r != "0":
            q[:, j] += blocks[r][0][:, j]
    errors = {key: blocks[r][1][key] for key, r in zip(sources, rows[arm:], strict=True)
              if r != "0"}
    hand = errors.pop("hand", None)
    if hand is not None:  # the pre-shape's offsets, within the hand joints' limits
        q = with_hand(q, hand, engine.description)
    return (engine.run(q, **errors).outcome == FORCE_CLOSURE).astype(float)


def _settings(sources: tuple[str, ...], a: NoiseDraws, b: NoiseDraws
              ) -> list[tuple[str, NoiseDraws, tuple]]:
    """(name, draws, geometry key) of every setting: A, B, and per source AB (A with its
    block from B), alone (only its block of A) and without (A without it)."""
    def key(draws_from: dict[str, str]) -> tuple:
        return tuple((s, draws_from[s]) for s in GEOMETRIC if s in draws_from)

    every = dict.fromkeys(sources, "A")
    out = [("A", a, key(every)), ("B", b, key(dict.fromkeys(sources, "B")))]
    for s in sources:
        out.append((f"AB:{s}", a.with_block(s, b.block(s)), key({**every, s: "B"})))
        out.append((f"alone:{s}", a.only((s,)), key({s: "A"})))
        out.append((f"without:{s}", a.with_block(s, None),
                    key({k: v for k, v in every.items() if k != s})))
    return out
