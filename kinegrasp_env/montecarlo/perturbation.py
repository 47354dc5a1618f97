"""From a noise model's draws to what the engines take, and where a pose error puts the hand.

:func:`engine_inputs` turns :class:`~kinegrasp_env.sampling.noise_model.NoiseDraws` into the
configurations q (n, 14) (arm joints plus their error; hand pre-shape plus its offsets,
clipped to the hand's joint limits) and the per-draw keyword arguments of
:meth:`~kinegrasp_env.montecarlo.engines.Engine.run`: ``palm`` (n, 4, 4), the hand root in
the flange frame; ``object_offset`` (n, 4, 4), the true object pose in the believed object
frame (rotating about the centre of mass); ``friction`` (n,).

Only the hand's pose relative to the object matters to closing and scoring, so the engines
keep the object where it was believed to be and move the hand instead: with W_F the flange
pose, W_O the believed object pose, P the palm error and D the object error, the hand root in
the true object's frame is X = D^-1 W_O^-1 W_F P (:func:`hand_in_object`). An object error D
and a palm error P = W_F^-1 W_O D^-1 W_O^-1 W_F (the same rigid motion, inverted, expressed in
the flange frame) therefore give the same draws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.hand_errors import hand_in_object, world_to_object
from kinegrasp_env.robot.default_robot import FINGERS, HAND_JOINTS, kuka_sdh
from kinegrasp_env.robot.kinematics import rigid_inverse
from kinegrasp_env.sampling.noise_model import NoiseDraws, offset_transforms

ARM = 7

__all__ = ["EngineInputs", "configurations", "engine_inputs", "hand_in_object",
           "hand_limits", "rigid_inverse", "world_to_object"]


@dataclass
class EngineInputs:
    """What one engine call takes for n draws (None: that error is absent).

    Attributes:
        q: (n, 14) configurations, radians.
        palm: (n, 4, 4) hand root in the flange frame.
        object_offset: (n, 4, 4) true object pose in the believed object's frame.
        friction: (n,) mu per draw.
    """

    q: np.ndarray
    palm: np.ndarray | None = None
    object_offset: np.ndarray | None = None
    friction: np.ndarray | None = None

    def errors(self) -> dict[str, np.ndarray]:
        """The keyword arguments of ``Engine.run`` beyond q (only those present)."""
        return {k: v for k, v in (("palm", self.palm), ("object_offset", self.object_offset),
                                  ("friction", self.friction)) if v is not None}


def hand_limits() -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) (7,) limits of the hand DOF in ``HAND_JOINTS`` order, radians."""
    model = kuka_sdh()
    return (np.array([model.joint(j).lower for j in HAND_JOINTS]),
            np.array([model.joint(j).upper for j in HAND_JOINTS]))


def configurations(q0: np.ndarray, draws: NoiseDraws) -> np.ndarray:
    """q (n, 14): q0 (14,) plus the joint errors on the arm and the hand offsets (spread;
    each finger's offset on both of its flexion joints), clipped to the hand's limits."""
    q = np.repeat(np.asarray(q0, dtype=float)[None], draws.size, axis=0)
    if draws.joints is not None:
        q[:, :ARM] += draws.joints
    if draws.hand is not None:
        offsets = np.zeros((draws.size, len(HAND_JOINTS)))
        offsets[:, 0] = draws.hand[:, 0]
        for f, finger in enumerate(FINGERS):
            for joint in finger[:2]:
                offsets[:, HAND_JOINTS.index(joint)] = draws.hand[:, 1 + f]
        lower, upper = hand_limits()
        q[:, ARM:] = np.clip(q[:, ARM:] + offsets, lower, upper)
    return q


def engine_inputs(q0: np.ndarray, draws: NoiseDraws, center: np.ndarray) -> EngineInputs:
    """The engine inputs of ``draws`` around q0 (14,); ``center`` (3,) is the object's centre
    of mass (object frame, metres), about which an object error rotates."""
    return EngineInputs(
        configurations(q0, draws),
        None if draws.palm is None else offset_transforms(draws.palm),
        None if draws.object is None else offset_transforms(draws.object, center),
        None if draws.friction is None else np.asarray(draws.friction, dtype=float))


def check_errors(n: int, palm, object_offset, friction, *,
                 static_hold: bool = False) -> dict[str, np.ndarray]:
    """The per-draw errors an engine's ``run`` is given (:meth:`~kinegrasp_env.montecarlo.
    engines.Engine.run`; n draws), as float arrays of the right shapes (ValueError otherwise:
    a bad shape, a non-finite entry, a negative mu, or a per-draw mu for an engine running
    the static hold check, ``static_hold``, which holds at the engine's one mu)."""
    if static_hold and friction is not None:
        raise ValueError("the static hold check holds at the engine's friction; a "
                         "per-draw friction is not checked (drop it or the check)")
    out = {}
    for name, value, shape in (("palm", palm, (n, 4, 4)),
                               ("object_offset", object_offset, (n, 4, 4)),
                               ("friction", friction, (n,))):
        if value is None:
            continue
        arr = np.asarray(value, dtype=float)
        if arr.shape != shape:
            raise ValueError(f"{name} must have shape {shape} (one per draw), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} has NaN or infinite entries")
        out[name] = arr
    if "friction" in out and np.any(out["friction"] < 0):
        raise ValueError(f"friction must be >= 0, got {float(out['friction'].min()):g}")
    return out
