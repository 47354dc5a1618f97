"""Which source of error limits a grasp: P(FC) per source and Sobol indices of force closure.

For a grasp of any robot and a :class:`~kinegrasp_env.sampling.noise_model.NoiseModel` with
sources (joints, hand, palm, object, friction: :mod:`kinegrasp_env.montecarlo.noise_rows`),
:func:`analyze` reports

* P(FC) with all sources, with each factor alone, and with all but one, each with its
  Wilson 95% interval; all on the same draws (every source draws from its own stream, so
  "alone" and "all but one" reuse the draws of "all": their differences are paired). The
  gain of a factor is P(FC) without it minus P(FC) with all: what making it exact would
  bring, with a paired 95% interval (normal, over the per-draw differences);
* the first-order and total Sobol indices of the force-closure indicator per factor, the
  factors being blocks of random inputs (:mod:`kinegrasp_env.sampling.sobol`: Saltelli 2010
  and Jansen 1999, percentile bootstrap intervals).

The factors are the model's sources, the arm joints one of them (``joints``), or with
``per_joint`` one factor per arm joint (named by the description's ``arm_joints``) beside the
hand, palm, object and friction sources. The sample A is ``evaluate_grasp``'s draws
with the same seed (rows 0 .. N-1 of each source's stream, the rows ``evaluate`` draws for
every robot), B the rows N .. 2N-1; a setting is closed once per distinct choice of rows (a
joint of sigma 0 draws 0 in A and in B), so with g noisy factors it costs N (2 + 3 g) draws
at most, plus one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.noise_rows import with_hand
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.noise_spec import spec_of
from kinegrasp_env.sampling.sobol import sobol_indices
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.world.grasps import Grasp


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
    """The result of :func:`analyze` (P(FC) with every source, and per factor)."""

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
    #: the robot's name
    robot: str | None = None

    @property
    def dominant(self) -> str | None:
        """The source with the largest total index (None when none is defined)."""
        defined = [e for e in self.effects if math.isfinite(e.total)]
        return max(defined, key=lambda e: e.total).source if defined else None

    @property
    def most_to_gain(self) -> str | None:
        """The source whose removal raises P(FC) the most (None when no removal raises it)."""
        gaining = [e for e in self.effects if math.isfinite(e.gain) and e.gain > 0]
        return max(gaining, key=lambda e: e.gain).source if gaining else None

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
        robot = "" if self.robot is None else f" of robot {self.robot}"
        w = max([9, *(len(e.source) + 1 for e in self.effects)])
        lines = [f"{self.object} grasp {self.grasp}{robot}, {self.samples} draws per setting, "
                 f"{self.engine} engine: P(FC) with all sources {self.p_all:.3f} "
                 f"({lo:.3f} .. {hi:.3f})",
                 f"{'source':<{w}} {'P(FC) alone':>11} {'all but it':>10} "
                 f"{'gain if exact (95%)':>24} {'first-order S (95%)':>22} "
                 f"{'total ST (95%)':>22}"]
        for e in self.effects:
            lines.append(f"{e.source:<{w}} {e.p_alone:>11.3f} {e.p_without:>10.3f} "
                         f"{_index(e.gain, e.gain_ci):>24} {_index(e.first, e.first_ci):>22} "
                         f"{_index(e.total, e.total_ci):>22}")
        outside = [f"{name} of {e.source}" for e in self.effects
                   for name, ci in (("S", e.first_ci), ("ST", e.total_ci))
                   if ci[0] > 1 or ci[1] < 0]
        if outside:  # the percentile bootstrap holds the draws' sampling bias, not only noise
            lines.append(f"note: Sobol indices lie in [0, 1]; the interval of "
                         f"{', '.join(outside)} lies outside it: the estimators' bias at "
                         f"{self.samples} draws (too few failures, or too few shared by the "
                         "two samples), which the bootstrap does not show; give more --samples")
        steady = "P(FC) does not vary over these draws" if self.variance == 0 else "undefined"
        lines.append(f"dominant source (largest total index): {self.dominant or f'none ({steady})'}"
                     f"; most to gain from making exact: "
                     f"{self.most_to_gain or 'none (no source made exact raises P(FC))'}")
        return "\n".join(lines)


def paired_gain(with_all: np.ndarray, without: np.ndarray) -> tuple[float, tuple[float, float]]:
    """Mean of the per-draw differences ``without - with_all`` (N,) and its normal 95%
    interval (the draws are paired: the same draws with and without a source)."""
    diff = without - with_all
    half = 1.959963984540054 * float(diff.std(ddof=1)) / math.sqrt(diff.size)
    mean = float(diff.mean())
    return mean, (mean - half, mean + half)


def _index(value: float, ci: tuple[float, float]) -> str:
    """``value [lo, hi]``; ``-`` for an undefined value, and the value alone where it has no
    interval (``--bootstrap 0``)."""
    if not math.isfinite(value):
        return "-"
    if not all(math.isfinite(end) for end in ci):
        return f"{value:6.3f} {'(no interval)':>16}"
    return f"{value:6.3f} [{ci[0]:6.3f}, {ci[1]:6.3f}]"


def _result(grasp: Grasp, y: dict[str, np.ndarray], factors: tuple[str, ...], n: int,
            seed: int, engine: str, bootstrap: int, noise_model: dict,
            robot: str | None = None) -> Sensitivity:
    """The :class:`Sensitivity` of the force-closure indicators ``y`` (setting name -> (n,)
    0/1; the settings of :func:`_factor_settings`) of every factor."""
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


def analyze(grasp: Grasp, noise: JointNoise | NoiseModel, samples: int, seed: int = 0, *,
            engine: RobotEngine | str = "fast", bootstrap: int = 1000,
            progress: Callable[[int, int], None] | None = None, per_joint: bool = False,
            friction: float = 0.5) -> Sensitivity:
    """P(FC) per factor and Sobol indices of force closure of ``grasp`` (module docstring).

    Args:
        grasp: a grasp of any robot (its ``robot``; q0: its actuated vector).
        noise: joint noise on the arm joints (sigma scalar or one per arm joint, radians),
            or a noise model of the robot's sources.
        samples: N, draws per setting (>= 2).
        seed: A = ``evaluate_grasp``'s draws with this seed; B = the next N rows.
        engine: an engine of the grasp's robot and object (``run(q, palm=, object_offset=,
            friction=)`` on the robot's actuated vectors), or the name of the one
            ``evaluate`` closes the robot's draws with (``engines.make_engine``),
            built (and closed) here at friction mu ``friction``.
        bootstrap: resamples for the Sobol intervals.
        progress: called with (settings done, settings) after every setting.
        per_joint: one factor per arm joint instead of one for the joints (independent,
            zero-mean joint errors only).

    Raises:
        ValueError: a grasp of another robot or object, bad samples or sigma, a seed that
            is not an integer >= 0, a negative bootstrap count, a noise model the robot
            cannot take or with no source of error.
    """
    from kinegrasp_env.counts import check_count
    from kinegrasp_env.montecarlo.evaluation_checks import integer_seed

    integer_seed(seed, "analyze")
    check_count(bootstrap, "bootstrap", least=0)  # 0: no intervals
    if isinstance(engine, str):
        from kinegrasp_env.montecarlo.engines import make_engine

        built = make_engine(engine, grasp.robot, grasp.object, friction=friction)
        try:
            return analyze(grasp, noise, samples, seed, engine=built, bootstrap=bootstrap,
                           progress=progress, per_joint=per_joint)
        finally:
            built.close()
    from kinegrasp_env.montecarlo.noise_rows import (
        check_robot_noise,
        error_rows,
        hand_rows,
        joint_rows,
    )
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.sampling.noise_model import as_noise_model
    from kinegrasp_env.world.grasps import check_robot

    if int(samples) != samples or samples < 2:
        raise ValueError(f"samples must be an integer >= 2, got {samples}")
    description = load_robot(grasp.robot)
    engine_robot = getattr(engine, "description", description)
    check_robot(grasp, engine_robot.name)
    if grasp.object != engine.obj.name:
        raise ValueError(f"grasp {grasp.id!r} is a grasp of {grasp.object!r}, the engine "
                         f"holds {engine.obj.name!r}")
    model = as_noise_model(noise)
    n, arm = int(samples), description.arm_dof
    check_robot_noise(model, description, arm, engine.name,
                      getattr(engine, "hold_check", None) is not None)
    check_factors(model, per_joint)
    joints = model.joints
    q0 = np.asarray(grasp.q0, dtype=float)
    if q0.shape != (description.model.dof,) or not np.all(np.isfinite(q0)):
        raise ValueError(f"grasp {grasp.id!r}: q0 must be {description.model.dof} finite "
                         f"values of robot {description.name!r}, got shape {q0.shape}")
    stream = joint_rows(model, arm, int(seed), 0, 2 * n)
    # a joint draws its rows where it has noise or a bias; else it is exact (rows "0")
    noisy = np.any(stream != 0, axis=0)
    errors = error_rows(model, int(seed), 0, 2 * n, engine.obj.center_of_mass)
    if model.hand is not None and not model.hand.exact:  # the pre-shape's offsets
        errors["hand"] = hand_rows(model, description, int(seed), 0, 2 * n)
    sources = tuple(k for k in ("hand", "palm", "object_offset", "friction") if k in errors)
    groups = ([] if joints is None else
              [(name, (j,)) for j, name in enumerate(description.arm_joints)] if per_joint
              else [("joints", tuple(range(arm)))])
    factors = (*(name for name, _ in groups), *(SOURCE_NAMES[k] for k in sources))
    if not factors:
        raise ValueError("the noise model has no source of error: nothing to analyze")
    blocks = {"A": (stream[:n], {k: v[:n] for k, v in errors.items()}),
              "B": (stream[n:], {k: v[n:] for k, v in errors.items()})}
    settings = _factor_settings(factors)
    closed: dict[tuple, np.ndarray] = {}
    y: dict[str, np.ndarray] = {}
    for done, (name, factor_rows) in enumerate(settings, 1):
        rows = _column_rows(factor_rows, groups, arm)
        key = tuple(r if j >= arm or noisy[j] else "0" for j, r in enumerate(rows))
        if key not in closed:
            closed[key] = _joint_fc(engine, description, q0, n, key, blocks, sources)
        y[name] = closed[key]
        if progress is not None:
            progress(done, len(settings))
    return _result(grasp, y, factors, n, int(seed), engine.name, bootstrap, spec_of(model),
                   description.name)


def check_factors(model: NoiseModel, per_joint: bool) -> None:
    """ValueError (one line) where ``model`` cannot be split into :func:`analyze`'s factors:
    one factor per arm joint needs independent, zero-mean joint errors."""
    joints = model.joints
    if per_joint and joints is not None and (joints.covariance is not None
                                             or joints.bias is not None):
        raise ValueError("one factor per arm joint needs independent, zero-mean joint "
                         "errors (a distribution and sigmas), not a joints covariance or bias")


#: The source factors, by their key in the engine's errors.
SOURCE_NAMES = {"hand": "hand", "palm": "palm", "object_offset": "object",
                "friction": "friction"}


def _factor_settings(factors: tuple[str, ...]) -> list[tuple[str, tuple[str, ...]]]:
    """(name, per factor the rows it draws: ``A``, ``B`` or ``0`` exact) of every setting:
    A, B, and per factor AB (A with that factor's rows from B), alone (only its rows of A)
    and without (A without it)."""
    k = len(factors)
    out = [("A", ("A",) * k), ("B", ("B",) * k)]
    for j, name in enumerate(factors):
        out.append((f"AB:{name}", tuple("B" if i == j else "A" for i in range(k))))
        out.append((f"alone:{name}", tuple("A" if i == j else "0" for i in range(k))))
        out.append((f"without:{name}", tuple("0" if i == j else "A" for i in range(k))))
    return out


def _column_rows(factor_rows: tuple[str, ...], groups: list[tuple[str, tuple[int, ...]]],
                 arm: int) -> list[str]:
    """A setting's rows per column (each arm joint, then each source) from its rows per
    factor: a joint factor's rows for each of its ``groups`` columns (joints in no group:
    ``0``, exact), then the sources' rows as they are."""
    rows = ["0"] * arm + list(factor_rows[len(groups):])
    for (_, columns), r in zip(groups, factor_rows, strict=False):
        for j in columns:
            rows[j] = r
    return rows


def _joint_fc(engine: RobotEngine, description: RobotDescription, q0: np.ndarray, n: int,
              rows: tuple[str, ...], blocks: dict[str, tuple], sources: tuple[str, ...] = ()
              ) -> np.ndarray:
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
        q = with_hand(q, hand, description)
    return (engine.run(q, **errors).outcome == FORCE_CLOSURE).astype(float)
