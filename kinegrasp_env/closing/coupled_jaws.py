"""Coupled jaws: what a parallel gripper's one actuator does that the closing does not.

The closing model closes every finger on its own until it touches, the object held where it
is (:mod:`~kinegrasp_env.closing.generic_reference`). A parallel gripper whose two jaws are
driven by one actuator (one actuated joint, the other jaw mimicking it) cannot do that: when
one jaw touches first it keeps moving with the other, pushing the object until the other
jaw meets it. The closing keeps its model (the contacts where each jaw meets the object at
rest) and reports, per draw, how far a coupled pair would have pushed the object: jaws that
touch after travelling d1 and d2 (metres along their axes) meet the pushed object when both
have moved (d1 + d2) / 2, so the push is |d1 - d2| / 2 (:func:`jaw_push`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.description import RobotDescription

__all__ = ["jaw_push", "jaw_speeds"]


def jaw_speeds(description: RobotDescription) -> np.ndarray | None:
    """(2,) each jaw's speed along its axis per unit closing parameter t (metres), for a hand
    of two fingers whose closing joints are all prismatic and driven by one actuated joint;
    None for any other hand."""
    fingers = description.fingers
    model = description.model
    if len(fingers) != 2 or not all(f.joints for f in fingers):
        return None
    drivers = model.drivers()
    joints = [model.joint(f.joints[0]) for f in fingers]
    sources = {drivers[j.name][0] for j in joints}
    if len(sources) != 1 or any(model.joint(name).kind != "prismatic"
                                for f in fingers for name in f.joints):
        return None
    close = description.close[model.actuated[sources.pop()]]
    return np.array([abs(drivers[j.name][1] * close) for j in joints])


def jaw_push(speeds: np.ndarray, travel: np.ndarray, missed: np.ndarray,
             start_collision: np.ndarray) -> np.ndarray:
    """(n,) metres: how far a coupled pair would push the object before both jaws touch
    (module docstring), from each jaw's closing parameter at contact ``travel`` (n, 2);
    NaN where a jaw missed or the draw started in collision."""
    moved = np.asarray(travel, dtype=float)[:, :2] * speeds
    push = 0.5 * np.abs(moved[:, 0] - moved[:, 1])
    touched = ~np.asarray(missed, dtype=bool)[:, :2].any(axis=1) & ~np.asarray(
        start_collision, dtype=bool)
    return np.where(touched, push, np.nan)
