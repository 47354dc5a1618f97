"""Where imported objects live on disk, and how an entry is read.

The catalog folder is ``<data_root>/objects`` (:func:`kinegrasp_env.paths.data_root`:
``$KINEGRASP_HOME`` or the platform's user data folder). One sub-folder per object, named as
the object, holding:

- ``entry.json``: what the object is and where it came from (:data:`ENTRY_FILE`; fields in
  :func:`kinegrasp_env.world.importer.import_object`), including ``pose``: the object frame in
  the world frame (4x4), or null for the default placement;
- ``mesh.obj``: the cleaned source mesh in the object frame, metres;
- ``parts.json``: the convex parts, ``{"parts": [[[x, y, z], ...], ...]}`` (the format of the
  built-in objects' ``assets/objects/<name>_parts.json``);
- ``<name>-<key>.npz``: the fast engine's distance grid (:mod:`kinegrasp_env.world.sdf`).

An entry appears only complete: it is written in a hidden folder (``.tmp-...``) next to the
others and renamed into place (:mod:`kinegrasp_env.world.importer`). Folders whose name starts
with a dot are never entries.
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

from kinegrasp_env.paths import data_root

ENTRY_FILE = "entry.json"
MESH_FILE = "mesh.obj"
PARTS_FILE = "parts.json"
#: Bump when the entry layout changes in a way old readers cannot follow.
FORMAT_VERSION = 1
#: Object names: a letter or digit, then letters, digits, ``_``, ``-``, ``.`` (64 at most).
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class CatalogError(ValueError):
    """A catalog request refused (a name taken, unknown or invalid; bad settings; an
    unreadable entry): one line naming the problem."""


def catalog_dir() -> Path:
    """The folder holding one sub-folder per imported object (not created here)."""
    return data_root() / "objects"


def valid_name(name: str) -> bool:
    return bool(NAME_PATTERN.match(name))


def imported_folder(name: str) -> Path | None:
    """The entry folder of an imported object, or None if there is no such entry."""
    if not isinstance(name, str) or not valid_name(name):
        return None
    folder = catalog_dir() / name
    return folder if (folder / ENTRY_FILE).is_file() else None


def imported_names() -> tuple[str, ...]:
    """Names of the imported objects, sorted."""
    root = catalog_dir()
    if not root.is_dir():
        return ()
    return tuple(sorted(p.name for p in root.iterdir()
                        if valid_name(p.name) and (p / ENTRY_FILE).is_file()))


def entry_digest(folder: Path) -> str:
    """SHA-256 (16 hex digits) of an entry's ``entry.json`` bytes: it changes whenever the
    entry is written again (a re-import with ``--force``, another file or setting), so
    caches keyed by it never serve an entry replaced under the same name.

    Raises:
        CatalogError: the file cannot be read.
    """
    path = Path(folder) / ENTRY_FILE
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CatalogError(f"catalog entry {path} is unreadable ({exc}); remove it with "
                           f"`kinegrasp objects remove {Path(folder).name}`") from None
    return hashlib.sha256(data).hexdigest()[:16]


def read_entry(folder: Path) -> dict:
    """The ``entry.json`` of an entry folder.

    Raises:
        CatalogError: unreadable, or written by a newer layout.
    """
    path = Path(folder) / ENTRY_FILE
    try:
        entry = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CatalogError(f"catalog entry {path} is unreadable ({exc}); remove it with "
                         f"`kinegrasp objects remove {Path(folder).name}`") from None
    if not isinstance(entry, dict) or entry.get("format", 0) > FORMAT_VERSION:
        raise CatalogError(f"catalog entry {path} was written by a newer kinegrasp "
                         f"(format {entry.get('format') if isinstance(entry, dict) else '?'})")
    return entry
