"""The checks of the environments' arguments, reset options and actions: each returns the
value in the form the env keeps, or raises a ValueError of one line naming the bad value
(:func:`env_arguments`: every constructor argument of the KineGrasp env at once)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.counts import check_count
from kinegrasp_env.envs.grasp_task import HOLD_TEST_SCORES, N_DRAWS, SCORES
from kinegrasp_env.envs.tasks import GRASP_OPTIONS
from kinegrasp_env.montecarlo.grasp_stats import ENGINES, MAX_SIGMA
from kinegrasp_env.montecarlo.palm_batch import check_batch_engine
from kinegrasp_env.robot.catalog import check_robot_name
from kinegrasp_env.sampling.noise import DISTRIBUTIONS, JointNoise


def box_action(action, shape: tuple[int, ...], meaning: str) -> np.ndarray:
    """``action`` as a float64 array, checked: exactly ``shape``, finite, every entry in
    [-1, 1] (the action space; agents such as stable-baselines3 clip to it before stepping).

    Raises:
        ValueError: one line naming the expected shape and range, and what was wrong.
    """
    expected = f"the action must be a float array of shape {shape} in [-1, 1] ({meaning})"
    try:
        array = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{expected}; got {action!r}") from None
    if array.shape != shape:
        raise ValueError(f"{expected}; got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{expected}; got {array.tolist()} (not finite)")
    if np.any(np.abs(array) > 1.0):
        raise ValueError(f"{expected}; got {array.tolist()} (outside [-1, 1])")
    return array


def finite_number(name: str, value, *, positive: bool = False) -> float:
    """``value`` as a finite float (``> 0`` where ``positive``); ValueError (one line, naming
    ``name`` and the value) otherwise."""
    kind = "a finite number > 0" if positive else "a finite number"
    if isinstance(value, bool):
        raise ValueError(f"{name} must be {kind}, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {kind}, got {value!r}") from None
    if not math.isfinite(number) or (positive and number <= 0):
        raise ValueError(f"{name} must be {kind}, got {value!r}")
    return number


def names_of(name: str, value, known: tuple[str, ...] | None = None) -> tuple[str, ...]:
    """``value`` as a non-empty tuple of strings (``objects``, ``noise_types``), each one of
    ``known`` where given; ValueError (one line, naming ``name`` and the bad value)
    otherwise. A lone string is refused: it is not a sequence of names."""
    shape = f"{name} must be a non-empty list or tuple of names"
    if isinstance(value, str) or not isinstance(value, (list, tuple)) or not value:
        raise ValueError(f"{shape}, got {value!r}")
    for item in value:
        if not isinstance(item, str):
            raise ValueError(f"{shape}, got {item!r} in {value!r}")
        if known is not None and item not in known:
            raise ValueError(f"unknown {name} entry {item!r}; choose from {', '.join(known)}")
    return tuple(value)


def sigma_bounds(value) -> tuple[float, float]:
    """``sigma_range`` as (low, high) radians with 0 <= low <= high <= pi; ValueError (one
    line, naming the value) otherwise."""
    expected = f"sigma_range must be 0 <= low <= high <= pi ({MAX_SIGMA:.5f} rad): (low, high) " \
               "radians"
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{expected}, got {value!r}") from None
    if not 0 <= low <= high <= MAX_SIGMA:  # (False for NaN)
        raise ValueError(f"{expected}, got {value!r}")
    return low, high


def reset_sigma(value) -> float:
    """A ``sigma`` reset option, validated as the library's joint noise is
    (:class:`~kinegrasp_env.sampling.noise.JointNoise`: a finite number in [0, pi] radians),
    one for every arm joint (per-joint sigmas are a ``noise_model``'s joints source)."""
    if np.ndim(value) != 0 or isinstance(value, (bool, np.bool_, str)):
        raise ValueError(f"sigma must be one number of radians for all arm joints (one per "
                         f"joint is a noise_model's joints source), got {value!r}")
    return float(JointNoise(value).sigma)


#: The reset options the envs take (:mod:`kinegrasp_env.envs.task_choice` documents them).
RESET_OPTIONS = ("object", *GRASP_OPTIONS, "sigma", "noise", "psi", "noise_model")


def reset_options(options) -> dict:
    """The reset ``options`` as a fresh dict (None: empty), checked: a dict of
    :data:`RESET_OPTIONS` only; ValueError (one line) otherwise."""
    if options is not None and not isinstance(options, dict):
        raise ValueError(f"reset options must be a dict or None, got {options!r}")
    options = dict(options or {})
    unknown = set(options) - set(RESET_OPTIONS)
    if unknown:
        raise ValueError(f"unknown reset options {sorted(unknown)}; the env takes "
                         f"{', '.join(RESET_OPTIONS)}")
    return options


def reset_psi(value) -> float:
    """A ``psi`` reset option (the elbow angle to start at), validated: a finite number of
    radians; ValueError (one line, naming the value) otherwise."""
    if not isinstance(value, (int, float, np.number)) or not math.isfinite(value):
        raise ValueError(f"psi must be a finite elbow angle in radians, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class EnvArguments:
    """The KineGrasp env's constructor arguments, checked, with their defaults filled in
    (:class:`~kinegrasp_env.envs.kinegrasp.KineGraspEnv` documents each one)."""

    robot: str
    n_draws: int
    engine: str
    score: str
    render_mode: str | None
    reward: str
    hold_simulator: str
    batch_size: int
    max_steps: int
    sigma_range: tuple[float, float]  # radians
    noise_types: tuple[str, ...]
    q_weight: float
    limit_penalty: float
    step_size: float  # radians of psi per unit action
    split: str | None
    objects: tuple[str, ...] | None


def env_arguments(*, robot: str, n_draws: int | None, engine: str | None, score: str,
                  render_mode: str | None, render_modes: list[str], reward: str,
                  hold_simulator: str, batch_size: int, max_steps: int,
                  sigma_range: tuple[float, float], noise_types: tuple[str, ...],
                  q_weight: float, limit_penalty: float, step_size: float, split: str | None,
                  objects: tuple[str, ...] | None) -> EnvArguments:
    """The KineGrasp env's constructor arguments, checked in the order the constructor
    takes them: ``n_draws`` None is :data:`~kinegrasp_env.envs.grasp_task.N_DRAWS`;
    ``engine`` None is ``fast``; ``render_modes`` are the env's (its ``metadata``).

    Raises:
        ValueError: one line naming the first bad argument and its value (an unknown robot:
            :func:`~kinegrasp_env.robot.catalog.check_robot_name`'s error).
    """
    robot = check_robot_name(robot)
    if n_draws is None:
        n_draws = N_DRAWS
    if engine is None:
        engine = "fast"
    if score not in SCORES:
        raise ValueError(f"score must be one of {', '.join(SCORES)}, got {score!r}")
    if render_mode not in (None, *render_modes):
        raise ValueError(f"render_mode must be None or one of "
                         f"{', '.join(render_modes)}, got {render_mode!r}")
    if reward not in ("draws", "batch"):
        raise ValueError(f"reward must be 'draws' or 'batch', got {reward!r}")
    if hold_simulator != "pybullet" and score not in HOLD_TEST_SCORES:
        raise ValueError(f"hold_simulator {hold_simulator!r} is the holding test's "
                         "simulator; it runs with score='hold' or 'hold_margin'")
    if reward == "batch" and score != "pfc":
        raise ValueError(f"reward 'batch' re-weights P(FC); score {score!r} takes "
                         "reward 'draws'")
    batch_size = check_count(batch_size, "batch_size")
    n_draws = check_count(n_draws, "n_draws")
    max_steps = check_count(max_steps, "max_steps")
    sigma_range = sigma_bounds(sigma_range)
    noise_types = names_of("noise_types", noise_types, DISTRIBUTIONS)
    q_weight = finite_number("q_weight", q_weight)
    limit_penalty = finite_number("limit_penalty", limit_penalty)
    step_size = finite_number("step_size", step_size, positive=True)
    if split not in (None, "train", "test"):
        raise ValueError(f"split must be None, 'train' or 'test', got {split!r}")
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if reward == "batch":
        check_batch_engine(engine)
    if objects is not None:
        objects = names_of("objects", objects)
    return EnvArguments(robot, n_draws, engine, score, render_mode, reward, hold_simulator,
                        batch_size, max_steps, sigma_range, noise_types, q_weight,
                        limit_penalty, step_size, split, objects)
