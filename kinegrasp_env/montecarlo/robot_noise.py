"""A noise model's draws for a description robot: joints, palm, object and friction.

Draw i of a run with seed s is row i of each source's own stream: the arm joints' of
``default_rng(s)`` (so a joints-only model draws exactly what ``--sigma``/``--noise`` draw),
every other source's of ``default_rng(SeedSequence(s, spawn_key=(k,)))`` with the source's
fixed k (:data:`~kinegrasp_env.sampling.noise_model.STREAM_KEYS`): adding or removing a source
never changes another's draws, and a chunk of rows is the same whichever process draws it.

What each source does (:mod:`~kinegrasp_env.sampling.noise_model`): joint errors on the arm
joints; a palm error moves the palm link and every link below it relative to the flange; an
object error moves the object about its centre of mass; friction sets each draw's mu. The
hand source (the SDH pre-shape's spread and per-finger offsets) is the default robot's.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import STREAM_KEYS, NoiseModel, offset_transforms
from kinegrasp_env.sampling.noise_sources import ARM_JOINTS


def check_robot_noise(model: NoiseModel, robot: str, arm_dof: int, engine: str,
                      static_hold: bool = False) -> None:
    """ValueError (one line) for what a description robot's run cannot take: the hand
    source, a joints covariance, bias or per-joint sigma of another length than its arm's,
    palm, object or friction errors in the physics engine, a per-draw mu beside the static
    hold check."""
    if model.hand is not None:
        raise ValueError(f"the hand source (the SDH pre-shape's spread and per-finger offsets) "
                         f"is kuka_sdh's; robot {robot!r} closes from its pre-shape exactly: "
                         "drop the spec's hand section")
    joints = model.joints
    if joints is not None and arm_dof != ARM_JOINTS:
        given = [name for name, value in (("covariance", joints.covariance),
                                          ("bias", joints.bias)) if value is not None]
        if np.ndim(joints.sigma) == 1 and len(joints.sigma) != arm_dof:
            given.append(f"{len(joints.sigma)} sigmas")
        if given:
            raise ValueError(f"robot {robot!r} has {arm_dof} arm joints; the spec's joints "
                             f"{' and '.join(given)} describe {ARM_JOINTS} (give one sigma, "
                             "or one per arm joint)")
    other = [s for s in ("palm", "object", "friction") if getattr(model, s) is not None]
    if other and engine == "physics":
        raise ValueError(f"the physics engine of robot {robot!r} takes joint noise only "
                         f"(it simulates at one mu), not {', '.join(other)} errors (use "
                         "pybullet or fast)")
    if model.friction is not None and static_hold:
        raise ValueError("the static hold check holds at one mu; the spec's friction source "
                         "draws one per draw: drop one of them")


def source_stream(seed: int, source: str) -> np.random.Generator:
    """The stream of ``source``'s rows in a run of ``seed`` (module docstring)."""
    if source == "joints":
        return np.random.default_rng(seed)
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(STREAM_KEYS[source],)))


def joint_rows(model: NoiseModel, arm_dof: int, seed: int, offset: int,
               size: int) -> np.ndarray:
    """(size, arm_dof) joint errors (radians): rows ``offset .. offset + size`` of the run's
    joint stream (zeros without joint noise)."""
    joints = model.joints
    if joints is None or joints.exact:
        return np.zeros((size, arm_dof))
    rng = source_stream(seed, "joints")
    if arm_dof == ARM_JOINTS:
        return joints.sample(rng, offset + size)[offset:]
    return JointNoise(joints.sigma, joints.distribution).sample(offset + size, arm_dof,
                                                                rng)[offset:]


def model_rows(model: NoiseModel, q0: np.ndarray, arm_dof: int, seed: int, offset: int,
               size: int, center: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(configurations (size, dof): q0 (dof,) with :func:`joint_rows` on its arm joints,
    :func:`error_rows`) of rows ``offset .. offset + size``."""
    q = np.repeat(np.asarray(q0, dtype=float)[None], size, axis=0)
    q[:, :arm_dof] += joint_rows(model, arm_dof, seed, offset, size)
    return q, error_rows(model, seed, offset, size, center)


def error_rows(model: NoiseModel, seed: int, offset: int, size: int,
               center: np.ndarray) -> dict[str, np.ndarray]:
    """The per-draw errors of rows ``offset .. offset + size`` as a robot engine's ``run``
    takes them: ``palm`` and ``object_offset`` (size, 4, 4) (the object's rotating about
    ``center`` (3,), its centre of mass), ``friction`` (size,); only the sources present."""
    out = {}
    for source, key in (("palm", "palm"), ("object", "object_offset")):
        pose = getattr(model, source)
        if pose is not None and not pose.exact:
            rows = pose.sample(source_stream(seed, source), offset + size)[offset:]
            out[key] = offset_transforms(rows, center if source == "object" else (0, 0, 0))
    if model.friction is not None:
        out["friction"] = model.friction.sample(source_stream(seed, "friction"),
                                                offset + size)[offset:]
    return out
