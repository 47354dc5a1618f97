"""The checks of the environments' arguments, reset options and actions: each returns the
value in the form the env keeps, or raises a ValueError of one line naming the bad value."""

from __future__ import annotations

import math

import numpy as np

from kinegrasp_env.montecarlo.evaluate import MAX_SIGMA


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


def positive_count(name: str, value) -> int:
    """``value`` as an int >= 1 (``n_draws``, ``max_steps``); ValueError (one line, naming
    ``name`` and the value) for anything else, a bool or a float included."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


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
    expected = f"sigma_range must be 0 <= low <= high <= pi ({MAX_SIGMA:.4f}): (low, high) " \
               "radians"
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{expected}, got {value!r}") from None
    if not 0 <= low <= high <= MAX_SIGMA:  # (False for NaN)
        raise ValueError(f"{expected}, got {value!r}")
    return low, high


def reset_sigma(value) -> float:
    """A ``sigma`` reset option, validated: a finite number in [0, pi] radians."""
    try:
        sigma = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"sigma must be a number of radians, got {value!r}") from None
    if not (math.isfinite(sigma) and 0 <= sigma <= MAX_SIGMA):
        raise ValueError(f"sigma must be finite and >= 0 and at most pi ({MAX_SIGMA:.4f}) "
                         f"radians, got {value!r}")
    return sigma
