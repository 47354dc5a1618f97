"""Every source of error of a grasp in one model: arm joints, hand, palm pose, object pose and
friction.

A :class:`NoiseModel` holds up to five sources; a missing source is exact, and a model with
every sigma zero is the nominal grasp. Per draw (units: radians, metres):

* ``joints`` (:class:`JointsSource`): eps added to the arm joints (the robot's arm_dof):
  independent, with one sigma per joint and any distribution of
  :class:`~kinegrasp_env.sampling.noise.JointNoise` (the same numbers for the same stream), or
  Gaussian with a full covariance; plus an optional constant bias (a calibration offset).
* ``hand`` (:class:`HandSource`): Gaussian offsets of the hand's pre-shape: one per finger
  added to the joints that close it, and one spread offset added to every other hand joint
  (the angles at which closing starts; :mod:`kinegrasp_env.montecarlo.noise_rows`).
* ``palm`` (:class:`PoseSource`): a Gaussian rigid error of the hand relative to the flange,
  in the flange frame: hand root = flange @ T.
* ``object`` (:class:`PoseSource`): a Gaussian rigid error of the object relative to where
  the planner believed it was, in the object frame, rotating about its centre of mass: true
  pose = believed pose @ T.
* ``friction`` (:class:`FrictionSource`): one mu per draw, used at every contact of it.

A pose error is (translation (3) m, rotation vector (3) rad), each component independent
N(0, sigma^2) with its own sigma; the transform is [exp([r]x), t] (:func:`offset_transforms`).
The source classes and their checks are in :mod:`kinegrasp_env.sampling.noise_sources`
(re-exported here).

Random streams (docs/conventions.md; drawn by :func:`stream_rows`): in chunk c of a run with
seed s the joints draw from the chunk's stream ``SeedSequence(s, spawn_key=(c,))`` exactly as
``JointNoise`` does, and every other source from its own child ``SeedSequence(s, spawn_key=(c,
k))`` with the fixed k of :data:`STREAM_KEYS`, so adding or removing a source never changes the
others' draws.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_sources import (
    FRICTION_DISTRIBUTIONS,
    FrictionSource,
    HandSource,
    JointsSource,
    NoiseSpecError,
    PoseSource,
)

SOURCES = ("joints", "hand", "palm", "object", "friction")
#: The spawn-key suffix k of each non-joint source's stream: ``SeedSequence(s, spawn_key=(c, k))``.
STREAM_KEYS = {"hand": 1, "palm": 2, "object": 3, "friction": 4}
#: Rows per chunk of a run's streams (docs/conventions.md, "Random streams").
STREAM_CHUNK = 250
#: The layout of a run's random rows, as the resumable records (``rank``'s log, a sweep's
#: store) keep it: a record of another layout is not extended.
DRAW_LAYOUT = f"rows of chunks of {STREAM_CHUNK}"

__all__ = ["DRAW_LAYOUT", "FRICTION_DISTRIBUTIONS", "SOURCES", "STREAM_CHUNK", "STREAM_KEYS",
           "FrictionSource", "HandSource", "JointsSource", "NoiseModel",
           "NoiseSpecError", "PoseSource", "as_noise_model", "chunk_stream",
           "offset_transforms", "skew", "stream_rows"]


def chunk_stream(seed: int | np.random.SeedSequence, index: int,
                 source: str = "joints") -> np.random.Generator:
    """The generator ``source`` draws from in chunk ``index`` of a run with ``seed`` (an
    integer, or a SeedSequence whose spawn key the chunk's key extends)."""
    key = (index,) if source == "joints" else (index, STREAM_KEYS[source])
    if isinstance(seed, np.random.SeedSequence):
        return np.random.default_rng(np.random.SeedSequence(
            seed.entropy, spawn_key=(*seed.spawn_key, *key), pool_size=seed.pool_size))
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


def stream_rows(seed: int | np.random.SeedSequence, source: str, offset: int, size: int,
                draw: Callable[[np.random.Generator, int], np.ndarray],
                chunk: int = STREAM_CHUNK) -> np.ndarray:
    """Rows ``offset .. offset + size`` of ``source``'s draws in a run of ``seed`` whose
    chunks hold ``chunk`` rows each: row r is row ``r % chunk`` of chunk ``r // chunk``'s
    stream (:func:`chunk_stream`), so any span of rows is what the run's chunks draw, in
    whichever pieces it is asked for. ``draw(generator, m)`` gives a chunk's first m rows
    (a sampler that fills rows in order, as every Monte Carlo sampler here does).

    Raises:
        ValueError: a negative ``offset`` or ``size``, or a ``chunk`` < 1 (named).
    """
    for name, value, low in (("offset", offset, 0), ("size", size, 0), ("chunk", chunk, 1)):
        if value < low:
            raise ValueError(f"stream rows: {name} must be >= {low}, got {value}")
    if size == 0:
        return draw(chunk_stream(seed, 0, source), 0)
    parts = []
    for index in range(offset // chunk, (offset + size - 1) // chunk + 1):
        start = index * chunk
        stop = min(offset + size, start + chunk) - start
        parts.append(draw(chunk_stream(seed, index, source), stop)[max(offset - start, 0):])
    return np.concatenate(parts)


def skew(v: np.ndarray) -> np.ndarray:
    """(n, 3, 3) cross-product matrices of vectors (n, 3)."""
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def offset_transforms(offsets: np.ndarray, center=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Rigid transforms (n, 4, 4) of pose errors (n, 6) (translation t (3) metres, rotation
    vector r (3) radians): x -> R (x - c) + c + t with R = exp([r]x) (Rodrigues) rotating
    about the point ``center`` c (3,)."""
    offsets = np.asarray(offsets, dtype=float)
    t, r = offsets[:, :3], offsets[:, 3:]
    angle = np.linalg.norm(r, axis=1)
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0 - angle**2 / 6.0, np.sin(angle) / safe)
    b = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(angle)) / safe**2)
    k = skew(r)
    rot = np.eye(3) + a[:, None, None] * k + b[:, None, None] * (k @ k)
    c = np.asarray(center, dtype=float)
    out = np.zeros((offsets.shape[0], 4, 4))
    out[:, :3, :3] = rot
    out[:, :3, 3] = c - rot @ c + t
    out[:, 3, 3] = 1.0
    return out


def nominal_friction(noise, friction: float) -> float:
    """The mu of the noise-free grasp (its nominal Q, the cones a page draws) under ``noise``
    (a :class:`NoiseModel`, joint noise or None): a model's friction source's nominal mu
    (:attr:`~kinegrasp_env.sampling.noise_sources.FrictionSource.nominal`; the source draws
    each draw's mu), else ``friction``."""
    source = getattr(noise, "friction", None)
    return float(friction) if source is None else source.nominal


# ----------------------------------------------------------------------------- the model
@dataclass(frozen=True)
class NoiseModel:
    """The sources of error of an evaluation (module docstring); None = exact.

    Build one from a spec, a YAML/JSON file or mapping
    (:mod:`kinegrasp_env.sampling.noise_spec`, which also writes one back: ``spec_of``), or
    from a :class:`JointNoise` (:func:`as_noise_model`).
    ``sigma``, ``kind`` and ``sigma_vector`` describe the joint part, as ``JointNoise``'s do.
    """

    joints: JointsSource | None = None
    hand: HandSource | None = None
    palm: PoseSource | None = None
    object: PoseSource | None = None
    friction: FrictionSource | None = None

    def __post_init__(self) -> None:
        kinds = {"joints": JointsSource, "hand": HandSource, "palm": PoseSource,
                 "object": PoseSource, "friction": FrictionSource}
        for name, kind in kinds.items():
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise NoiseSpecError(f"{name} must be a {kind.__name__}, got "
                                     f"{type(value).__name__}")

    @property
    def sources(self) -> tuple[str, ...]:
        """Names of the sources present, in :data:`SOURCES` order."""
        return tuple(s for s in SOURCES if getattr(self, s) is not None)

    def only(self, *keep: str) -> NoiseModel:
        """The model with every source outside ``keep`` exact."""
        unknown = [s for s in keep if s not in SOURCES]
        if unknown:
            raise ValueError(f"unknown noise source {unknown[0]!r}; sources: {', '.join(SOURCES)}")
        return replace(self, **{s: None for s in SOURCES if s not in keep})

    def without(self, source: str) -> NoiseModel:
        """The model with ``source`` exact."""
        return self.only(*(s for s in SOURCES if s != source))

    @property
    def sigma(self) -> float | tuple[float, ...]:
        """Joint sigma as ``JointNoise.sigma`` (scalar or one per arm joint; 0 without joint
        noise)."""
        if self.joints is None:
            return 0.0
        if self.joints.covariance is not None:
            return tuple(self.joints.sigma_vector(self.joints.count).tolist())
        return self.joints.sigma

    @property
    def kind(self) -> str:
        """The joints' distribution (``gaussian`` without joint noise)."""
        return "gaussian" if self.joints is None else self.joints.distribution

    def sigma_vector(self, dim: int) -> np.ndarray:
        """(dim,) joint standard deviations, as :meth:`JointNoise.sigma_vector` (ValueError
        where the joints source describes another arm)."""
        if self.joints is None:
            return np.zeros(dim)
        return self.joints.sigma_vector(dim)


def as_noise_model(noise: JointNoise | NoiseModel) -> NoiseModel:
    """A :class:`NoiseModel` from either noise type (a ``JointNoise`` is the joints-only
    model: the same draws for the same seed)."""
    if isinstance(noise, NoiseModel):
        return noise
    if isinstance(noise, JointNoise):
        return NoiseModel(joints=JointsSource(noise.sigma, noise.kind))
    raise TypeError(f"noise must be a JointNoise or a NoiseModel, got {type(noise).__name__}")
