"""The pre-shapes a planner draws a hand's open shape from: a description's ``preshapes``.

A list of draws; each names hand joints that take **one** value together (a coupled
flexion: every finger's proximal joint at the same angle), drawn uniformly from its
``range: [low, high]`` or as one of its ``values: [...]`` (a spread's discrete settings),
radians or metres::

    preshapes:
      - {joints: [f1_spread], values: [0.0, 0.5236, 1.0472]}
      - {joints: [f1_proximal, f2_proximal, f3_proximal], range: [-0.9, -0.2]}

A hand joint in no draw keeps its ``open`` value. Every value lies within each of its joints'
URDF limits; a joint is in one draw at most. Without ``preshapes`` the planners close every
candidate from the ``open`` pre-shape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.robot.description_fields import check_names, check_number, fail

__all__ = ["PreshapeDraw", "check_preshapes", "draw_preshapes"]


@dataclass(frozen=True)
class PreshapeDraw:
    """One draw of a pre-shape: ``joints`` take one value, uniform in ``low..high`` or one
    of ``values`` (then ``low``, ``high`` are its smallest and largest), radians or metres."""

    joints: tuple[str, ...]
    low: float
    high: float
    values: tuple[float, ...] = ()

    def text(self) -> str:
        """The draw in words, e.g. ``f1_proximal, f2_proximal: one value in [-0.9, -0.2]``."""
        drawn = (f"one of {', '.join(f'{v:g}' for v in self.values)}" if self.values
                 else f"one value in [{self.low:g}, {self.high:g}]")
        return f"{', '.join(self.joints)}: {drawn}"

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n,) drawn values."""
        if self.values:
            return np.asarray(self.values)[rng.integers(len(self.values), size=n)]
        return rng.uniform(self.low, self.high, size=n)


def check_preshapes(data: dict, where: str, hand: tuple[str, ...], movable: dict
                    ) -> tuple[PreshapeDraw, ...]:
    """The description's ``preshapes`` (module docstring; () when not given): ``hand`` the
    hand joints, ``movable`` joint name -> URDF joint (its limits)."""
    given = data.get("preshapes")
    given = [] if given is None else given
    if not isinstance(given, list):
        raise fail(where, "preshapes", f"expected a list of draws, got {given!r}")
    draws, seen = [], set()
    for i, entry in enumerate(given):
        key = f"preshapes[{i}]"
        if (not isinstance(entry, dict) or not all(isinstance(k, str) for k in entry)
                or sorted(entry) not in (["joints", "range"], ["joints", "values"])):
            raise fail(where, key, "expected {joints: [...], range: [low, high]} or "
                       f"{{joints: [...], values: [...]}}, got {entry!r}")
        joints = check_names(entry["joints"], where, f"{key}: joints")
        for j in joints:
            if j not in hand:
                raise fail(where, f"{key}: joints", f"{j!r} is not one of hand_joints")
            if j in seen:
                raise fail(where, f"{key}: joints", f"{j!r} is in an earlier draw too")
            seen.add(j)
        numbers = entry.get("range", entry.get("values"))
        if not isinstance(numbers, list) or not numbers:
            raise fail(where, key, f"expected a non-empty list of numbers, got {numbers!r}")
        numbers = [check_number(v, where, key) for v in numbers]
        if "range" in entry and (len(numbers) != 2 or numbers[0] > numbers[1]):
            raise fail(where, f"{key}: range", f"expected [low, high] with low <= high, got "
                       f"{entry['range']!r}")
        for j in joints:
            lo, hi = movable[j].lower, movable[j].upper
            outside = [v for v in numbers if not lo - 1e-12 <= v <= hi + 1e-12]
            if outside:
                raise fail(where, key, f"{j}: {outside[0]:g} is outside the joint's limits "
                           f"[{lo:g}, {hi:g}]")
        draws.append(PreshapeDraw(joints, min(numbers), max(numbers),
                                  tuple(numbers) if "values" in entry else ()))
    return tuple(draws)


def draw_preshapes(hand_joints: tuple[str, ...], opened: np.ndarray,
                   draws: tuple[PreshapeDraw, ...], rng: np.random.Generator, n: int
                   ) -> np.ndarray:
    """(n, len(hand_joints)) pre-shapes: ``opened`` (hand dof,) the ``open`` values, each of
    ``draws`` drawn in turn (one ``rng`` call per draw, in the description's order)."""
    out = np.repeat(np.asarray(opened, dtype=float)[None], n, axis=0)
    for draw in draws:
        value = draw.sample(rng, n)
        for j in draw.joints:
            out[:, hand_joints.index(j)] = value
    return out
