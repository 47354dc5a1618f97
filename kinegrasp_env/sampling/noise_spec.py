"""Noise-model specs: YAML/JSON files or mappings <-> :class:`NoiseModel`.

The shape (every section optional; a missing one is an exact source)::

    preset: dexnet                                # optional: start from a preset
    joints:   {sigma: 0.0133, distribution: gaussian}   # sigma: scalar or one per arm joint
              # (radians); or covariance: d x d for d arm joints (rad^2, symmetric PSD);
              # optional bias: scalar or one per arm joint (radians)
    hand:     {spread_sigma: 0.0, closing_sigma: 0.0}   # radians; closing: scalar or one per finger
    palm:     {translation_sigma: 0.0, rotation_sigma: 0.0}    # metres, radians; scalar or 3
    object:   {translation_sigma: 0.01, rotation_sigma: 0.01}  # metres, radians; scalar or 3
    friction: {distribution: gaussian, mean: 0.5, sigma: 0.1}  # truncated at mu = 0;
              # or {distribution: uniform, low: 0.3, high: 0.7}, {distribution: fixed, value: 0.5}

A section given next to ``preset`` replaces the preset's section. :data:`PRESETS`:
``dexnet`` is Dex-Net's robust-quality noise (object pose 1 cm / 0.01 rad, gripper pose
5 mm / 0.001 rad, friction sigma 0.1 around 0.5). Every error is one
:class:`~kinegrasp_env.sampling.noise_model.NoiseSpecError` line naming the bad value, raised
before any draw is made.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import (
    SOURCES,
    FrictionSource,
    HandSource,
    JointsSource,
    NoiseModel,
    NoiseSpecError,
    PoseSource,
)
from kinegrasp_env.spec_yaml import read_spec

SECTION_KEYS = {
    "joints": ("sigma", "distribution", "covariance", "bias"),
    "hand": ("spread_sigma", "closing_sigma"),
    "palm": ("translation_sigma", "rotation_sigma"),
    "object": ("translation_sigma", "rotation_sigma"),
}
FRICTION_KEYS = {"gaussian": ("mean", "sigma"), "uniform": ("low", "high"),
                 "fixed": ("value",)}
#: The keys a friction section must give, by distribution: those whose default would
#: silently be another model (a uniform on [0, 0] is mu 0 on every draw; a gaussian of sigma
#: 0 and a fixed mu of the default are no distribution the section asked for).
FRICTION_REQUIRED = {"gaussian": ("sigma",), "uniform": ("low", "high"), "fixed": ("value",)}
TOP_KEYS = ("preset", *SOURCES)
PRESETS: dict[str, dict] = {
    "dexnet": {
        "palm": {"translation_sigma": 0.005, "rotation_sigma": 0.001},
        "object": {"translation_sigma": 0.01, "rotation_sigma": 0.01},
        "friction": {"distribution": "gaussian", "mean": 0.5, "sigma": 0.1},
    },
}


def noise_model_from_spec(data: Any, where: str = "noise spec") -> NoiseModel:
    """The :class:`NoiseModel` of a spec mapping (module docstring); ``where`` prefixes
    every error (a file name)."""
    try:
        return _model(data)
    except NoiseSpecError as exc:
        raise NoiseSpecError(f"{where}: {exc}") from None


#: Why a spec of no source is refused (an empty file, ``{}``, only empty sections).
NO_SOURCE = ("names no source of error (a section of joints, hand, palm, object or "
             "friction, or a preset); an evaluation without noise is sigma 0")


def _model(data: Any) -> NoiseModel:
    if data is None or data == {}:
        raise NoiseSpecError(NO_SOURCE)
    if not isinstance(data, dict):
        raise NoiseSpecError(f"expected a mapping of sources ({', '.join(TOP_KEYS)}), got "
                             f"{data!r}")
    for key in data:
        if key not in TOP_KEYS:
            raise NoiseSpecError(f"unknown source {key!r}; known: {', '.join(TOP_KEYS)}")
    sections = {}
    preset = data.get("preset")
    if preset is not None:
        if preset not in PRESETS:
            raise NoiseSpecError(f"unknown preset {preset!r}; known: {', '.join(PRESETS)}")
        sections.update(PRESETS[preset])
    sections.update({k: v for k, v in data.items() if k != "preset"})
    built = {name: _section(name, body) for name, body in sections.items()}
    if all(v is None for v in built.values()):
        raise NoiseSpecError(NO_SOURCE)
    return NoiseModel(**{k: v for k, v in built.items() if v is not None})


def _section(name: str, body: Any):
    """One source from its mapping (None for an empty YAML section: exact)."""
    if body is None:
        return None
    if not isinstance(body, dict):
        raise NoiseSpecError(f"{name} must be a mapping of its settings, got {body!r}")
    if name == "friction":
        return _friction(body)
    _known_keys(name, body, SECTION_KEYS[name])
    if name == "joints":
        if "covariance" in body and "sigma" in body:
            raise NoiseSpecError("joints: give sigma or covariance, not both")
        return JointsSource(**body)
    if name == "hand":
        return HandSource(**body)
    return PoseSource(**body, name=name)


def _friction(body: dict) -> FrictionSource:
    """The friction section: its distribution (default gaussian) and the parameters of it
    that have no meaningful default (:data:`FRICTION_REQUIRED`; a gaussian's mean defaults
    to 0.5, the default mu)."""
    kind = body.get("distribution", "gaussian")
    if kind not in FRICTION_KEYS:
        raise NoiseSpecError(f"friction.distribution {kind!r} is unknown; choose from "
                             f"{', '.join(FRICTION_KEYS)}")
    given = "" if "distribution" in body else ", the default"
    for key in body:
        other = [d for d, keys in FRICTION_KEYS.items() if key in keys and d != kind]
        if key != "distribution" and key not in FRICTION_KEYS[kind] and other:
            raise NoiseSpecError(f"friction.{key} is a key of distribution {other[0]}, not of "
                                 f"{kind}{given}: give distribution: {other[0]}")
    _known_keys("friction", body, ("distribution", *FRICTION_KEYS[kind]),
                f" (with distribution {kind}{given})")
    missing = [k for k in FRICTION_REQUIRED[kind] if k not in body]
    if missing:
        raise NoiseSpecError(f"friction with distribution {kind}{given}{',' if given else ''} "
                             f"needs {' and '.join(missing)}")
    return FrictionSource(distribution=kind, **{k: v for k, v in body.items()
                                                if k != "distribution"})


def _known_keys(name: str, body: dict, known: tuple[str, ...], note: str = "") -> None:
    for key in body:
        if key not in known:
            raise NoiseSpecError(f"unknown key {name}.{key}{note}; known: {', '.join(known)}")


def spec_of(model: NoiseModel) -> dict:
    """The spec mapping of ``model`` (JSON-ready; reads back to an equal model)."""
    out: dict[str, dict] = {}
    joints = model.joints
    if joints is not None:
        section: dict = {"distribution": joints.distribution}
        if joints.covariance is not None:
            section["covariance"] = [list(row) for row in joints.covariance]
        else:
            section["sigma"] = _plain(joints.sigma)
        if joints.bias is not None:
            section["bias"] = _plain(joints.bias)
        out["joints"] = section
    if model.hand is not None:
        out["hand"] = {"spread_sigma": model.hand.spread_sigma,
                       "closing_sigma": _plain(model.hand.closing_sigma)}
    for name in ("palm", "object"):
        pose = getattr(model, name)
        if pose is not None:
            out[name] = {"translation_sigma": _plain(pose.translation_sigma),
                         "rotation_sigma": _plain(pose.rotation_sigma)}
    friction = model.friction
    if friction is not None:
        out["friction"] = {"distribution": friction.distribution,
                           **{k: getattr(friction, k)
                              for k in FRICTION_KEYS[friction.distribution]}}
    return out


def _plain(value):
    return list(value) if isinstance(value, tuple) else value


# ----------------------------------------------------------------------------- files
def read_spec_file(path: str | Path) -> Any:
    """The parsed content of a YAML or JSON spec file; a file that cannot be read or does
    not parse is one :class:`NoiseSpecError` line (:func:`~kinegrasp_env.spec_yaml.
    read_spec`: file, line, column, what)."""
    try:
        return read_spec(path)
    except ValueError as exc:
        raise NoiseSpecError(str(exc)) from None


def load_noise_model(path: str | Path) -> NoiseModel:
    """The :class:`NoiseModel` of a YAML or JSON spec file."""
    return noise_model_from_spec(read_spec_file(path), where=str(path))


def noise_model_from(value: Any, base: str | Path | None = None) -> NoiseModel:
    """A model from a model, a ``JointNoise``, a spec mapping or a spec file path (relative
    to the folder ``base`` when given)."""
    from kinegrasp_env.sampling.noise_model import as_noise_model

    if isinstance(value, (NoiseModel, JointNoise)):
        return as_noise_model(value)
    if isinstance(value, dict):
        return noise_model_from_spec(value)
    if isinstance(value, (str, Path)):
        path = Path(value)
        return load_noise_model(path if base is None or path.is_absolute() else
                                Path(base) / path)
    raise NoiseSpecError(f"a noise model is a spec mapping or a spec file path, got {value!r}")
