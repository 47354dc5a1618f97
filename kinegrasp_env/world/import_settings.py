"""What an import is asked for, checked before any work, and the key its entry is reused by.

The request: the settings (scale to metres, the decomposition's threshold and number of
parts, the file's up axis), the object's name and its density. :class:`ImportSettings` holds
the settings (:meth:`ImportSettings.check` refuses a bad one); :func:`default_name` makes a
name from a file name, :func:`check_name` and :func:`check_density` refuse a bad name or
density. Each refusal is a :class:`~kinegrasp_env.world.store.CatalogError` naming the bad
value.

The key: :func:`entry_key` of the files' digest (:func:`source_digest`) and the settings;
:func:`same_import` tells whether an existing entry holds the same import (the scale to
within :data:`SCALE_RTOL`, relative), so that
:func:`kinegrasp_env.world.importer.import_object` reuses it.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from kinegrasp_env.world.decompose import (
    COACD_SEED,
    DEFAULT_MAX_PARTS,
    DEFAULT_THRESHOLD,
    HULL_TOLERANCE,
    MAX_HULL_VERTICES,
)
from kinegrasp_env.world.names import OBJECT_NAMES
from kinegrasp_env.world.store import FORMAT_VERSION, CatalogError, valid_name

if TYPE_CHECKING:
    from kinegrasp_env.world.meshfile import SourceMesh

#: Units a file may be in, and their factor to metres.
UNITS = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
#: The rotation that turns a file's up axis into the object frame's +z (right-handed, so
#: the winding stays outward): y-up (many OBJ and glTF files) by +90 degrees about x, x-up
#: by -90 degrees about y.
UP_ROTATIONS = {
    "x": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    "z": np.eye(3),
}


@dataclass(frozen=True)
class ImportSettings:
    """How a file is imported.

    Attributes:
        scale: factor from the file's units to metres.
        threshold: CoACD's concavity threshold (0.01 .. 1; smaller: more, closer parts).
        max_parts: most convex parts (>= 1).
        up: the file's up axis (``x``, ``y`` or ``z``), turned into +z at import
            (:data:`UP_ROTATIONS`).
    """

    scale: float = 1.0
    threshold: float = DEFAULT_THRESHOLD
    max_parts: int = DEFAULT_MAX_PARTS
    up: str = "z"

    def check(self) -> ImportSettings:
        """The settings, or :class:`CatalogError` naming the bad one."""
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise CatalogError(f"scale must be a finite number > 0, got {self.scale!r}")
        if not (np.isfinite(self.threshold) and 0.01 <= self.threshold <= 1.0):
            raise CatalogError(f"threshold must be between 0.01 and 1, got {self.threshold!r}")
        if isinstance(self.max_parts, bool) or int(self.max_parts) != self.max_parts \
                or self.max_parts < 1:
            raise CatalogError(f"max_parts must be an integer >= 1, got {self.max_parts!r}")
        if self.up not in UP_ROTATIONS:
            raise CatalogError(f"up must be one of {', '.join(UP_ROTATIONS)}, got {self.up!r}")
        return self

    def key_fields(self) -> dict:
        """The settings an entry's key is made of (``up`` only when not ``z``, so entries
        imported before the option existed keep their keys)."""
        fields = asdict(self)
        if fields["up"] == "z":
            del fields["up"]
        return fields


def default_name(path: str | Path) -> str:
    """An object name from a file name: its stem, lower case, other characters as ``_``."""
    stem = "".join(c if c.isalnum() or c in "_-." else "_" for c in Path(path).stem.lower())
    stem = stem.lstrip("_-.")[:64]
    return stem or "object"


def check_name(name: str) -> str:
    """``name`` if it can name an imported object, else :class:`CatalogError`."""
    if not valid_name(name):
        raise CatalogError(f"invalid object name {name!r}: use letters, digits, '_', '-', '.' "
                           "(starting with a letter or digit, 64 at most)")
    if name in OBJECT_NAMES:
        raise CatalogError(f"{name!r} is a built-in object; choose another name with --name")
    return name


def check_density(density: float | None) -> float | None:
    """``density`` (kg/m^3) if finite and > 0 (or None); :class:`CatalogError` otherwise."""
    if density is not None and not (np.isfinite(density) and density > 0):
        raise CatalogError(f"density must be a finite number of kg/m^3 > 0, got {density!r}")
    return None if density is None else float(density)


def source_digest(source: SourceMesh) -> str:
    """SHA-256 of the bytes of every file read (the mesh, or the URDF and its meshes)."""
    digest = hashlib.sha256()
    for path in source.files:
        digest.update(path.read_bytes())
    return digest.hexdigest()


def entry_key(digest: str, settings: ImportSettings) -> str:
    """The key an entry is reused by: the files' digest, the settings and the layout."""
    text = json.dumps({"files": digest, **settings.key_fields(), "seed": COACD_SEED,
                       "hull": [MAX_HULL_VERTICES, HULL_TOLERANCE], "format": FORMAT_VERSION},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


#: Relative tolerance within which a scale is the one an entry was imported with: a scale
#: typed again from a printout, or computed another way, differs in its last digits, and the
#: object it gives differs by less than a micrometre per metre.
SCALE_RTOL = 1e-6


def same_import(entry: dict, digest: str, settings: ImportSettings) -> bool:
    """Whether ``entry`` holds the import of the files of ``digest`` with ``settings``: its
    key is theirs, with the entry's own scale when the two scales agree to within
    :data:`SCALE_RTOL` (relative; no absolute tolerance)."""
    if entry.get("key") == entry_key(digest, settings):
        return True
    stored = entry.get("settings", {}).get("scale")
    if isinstance(stored, bool) or not isinstance(stored, (int, float)) or not np.isclose(
            stored, settings.scale, rtol=SCALE_RTOL, atol=0.0):
        return False
    return entry.get("key") == entry_key(digest, replace(settings, scale=stored))
