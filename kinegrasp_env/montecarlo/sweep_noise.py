"""The ``noise`` entries of a sweep spec: joint-noise distributions and noise models.

An entry is a distribution name (``gaussian``, ``uniform``, ``triangular``: joint noise of the
cell's sigma, as ``--sigma/--noise``), a noise-model spec mapping, or the path of a spec file
(YAML/JSON, relative to the sweep spec's folder). A model's cell noise is the model with its
joint sigma set to the cell's sigma (its joints distribution and bias kept; a covariance is
refused, the sweep's sigmas would not apply). A model is labelled ``<file stem or "model">-<the
first 8 hex digits of the SHA-256 of its spec>``: the summary's noise column and the task keys
name it, so results of an edited model are never mixed with those of another.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any

from kinegrasp_env.sampling.noise import DISTRIBUTIONS, JointNoise
from kinegrasp_env.sampling.noise_model import JointsSource, NoiseModel, NoiseSpecError
from kinegrasp_env.sampling.noise_spec import noise_model_from, noise_model_from_spec, spec_of

SPEC_SUFFIXES = (".yaml", ".yml", ".json")


def noise_entries(entries: list, base: str | Path | None = None
                  ) -> tuple[tuple[str, ...], tuple[tuple[str, str], ...]]:
    """(labels of every entry, (label, spec JSON) of the models); NoiseSpecError (one line)
    for an entry that is neither a distribution nor a valid model."""
    labels, models = [], []
    for entry in entries:
        if isinstance(entry, str) and entry in DISTRIBUTIONS:
            labels.append(entry)
            continue
        label, text = _model_entry(entry, base)
        labels.append(label)
        models.append((label, text))
    return tuple(labels), tuple(models)


def _model_entry(entry: Any, base: str | Path | None) -> tuple[str, str]:
    if (isinstance(entry, str) and Path(entry).suffix.lower() not in SPEC_SUFFIXES
            and not (Path(base or ".") / entry).is_file()):  # a spec file of any name, as
        # --noise-spec takes it; else a name the list of choices should have held
        raise NoiseSpecError(f"unknown noise {entry!r}: give a distribution "
                             f"({', '.join(DISTRIBUTIONS)}), a noise spec file "
                             f"({', '.join(SPEC_SUFFIXES)}, or any existing file) or a noise "
                             "spec mapping")
    if not isinstance(entry, (str, dict)):
        raise NoiseSpecError(f"noise entry {entry!r} is neither a distribution nor a noise "
                             "model (a spec mapping or a spec file)")
    model = noise_model_from(entry, base)
    if model.joints is not None and model.joints.covariance is not None:
        raise NoiseSpecError("a noise model in a sweep takes its joint sigma from 'sigmas'; "
                             "its joints section cannot give a covariance")
    text = json.dumps(spec_of(model), sort_keys=True)
    stem = Path(entry).stem if isinstance(entry, str) else "model"
    return f"{stem}-{hashlib.sha256(text.encode()).hexdigest()[:8]}", text


def replaced_joint_sigmas(models: tuple[tuple[str, str], ...]) -> list[tuple[str, object]]:
    """(label, joints sigma) of each model (``(label, spec JSON)``, :func:`noise_entries`)
    whose joints section gives a sigma other than 0: the cells replace it with theirs."""
    out = []
    for label, text in models:
        sigma = json.loads(text).get("joints", {}).get("sigma", 0.0)
        if any(float(s) != 0.0 for s in (sigma if isinstance(sigma, list) else [sigma])):
            out.append((label, sigma))
    return out


def cell_noise(sigma: float, noise: str, model: str | None) -> JointNoise | NoiseModel:
    """The noise of a cell: ``JointNoise(sigma, noise)``, or the model of spec JSON ``model``
    with its joint sigma set to ``sigma``."""
    if model is None:
        return JointNoise(sigma, noise)
    parsed = noise_model_from_spec(json.loads(model))
    joints = dataclasses.replace(parsed.joints or JointsSource(), sigma=sigma)
    return dataclasses.replace(parsed, joints=joints)
