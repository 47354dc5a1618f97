"""The catalog listing without loading any geometry:
:func:`kinegrasp_env.world.catalog_listing.catalog` remembered on disk.

A listing depends only on files: the built-in objects' assets, every imported entry's
``entry.json`` and the code that computes the rows. :func:`cached_catalog` keys a copy of the
rows by a digest of all of them (``cache_root()/catalog/rows-<key>.json``) and serves it when
nothing changed, so ``kinegrasp objects`` needs neither NumPy nor trimesh; anything changed
(an import, a removal, a new placement, an edited asset or an upgrade) gives a new key and the
rows are computed afresh by :func:`~kinegrasp_env.world.catalog_listing.catalog`, the one
definition.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

from kinegrasp_env.assets import asset_path
from kinegrasp_env.paths import cache_root
from kinegrasp_env.world.names import OBJECT_NAMES
from kinegrasp_env.world.store import ENTRY_FILE, catalog_dir, imported_names

_HERE = Path(__file__).resolve().parent
#: The modules whose code computes a row (a change of any gives a new key).
ROW_SOURCES = ("catalog_listing.py", "objects.py", "names.py", "store.py", "support.py",
               "catalog_cache.py")


def catalog_key() -> str:
    """SHA-256 (16 hex digits) of what the listing depends on (see the module docstring).

    Raises:
        OSError: an entry's ``entry.json`` cannot be read (then the caller lists the
            catalog afresh, which reports the entry).
    """
    digest = hashlib.sha256()
    for name in ROW_SOURCES:
        digest.update((_HERE / name).read_bytes() + b"\0")
    for name in OBJECT_NAMES:
        for path in (asset_path("objects", f"{name}.obj"),
                     asset_path("objects", f"{name}_parts.json")):
            stat = path.stat()
            digest.update(f"{path}\0{stat.st_size}\0{stat.st_mtime_ns}\0".encode())
    root = catalog_dir()
    digest.update(f"{root.absolute()}\0".encode())
    for name in imported_names():
        digest.update(name.encode() + b"\0" + (root / name / ENTRY_FILE).read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def cached_catalog() -> list[dict]:
    """The rows of :func:`~kinegrasp_env.world.catalog_listing.catalog`, from the disk copy when
    nothing they depend on changed.

    Raises:
        CatalogError: an unreadable entry (from ``catalog``).
    """
    try:
        key = catalog_key()
    except OSError:
        key = None
    path = cache_root() / "catalog" / f"rows-{key}.json"
    if key is not None and path.is_file():
        try:
            return json.loads(path.read_text())
        except (OSError, ValueError):
            pass
    from kinegrasp_env.world.catalog_listing import catalog

    rows = catalog()
    if key is not None:
        _store(path, rows)
    return rows


def _store(path: Path, rows: list[dict]) -> None:
    """Write the rows atomically, dropping older copies (a cache: failures are ignored)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".rows-")
        with os.fdopen(fd, "w") as fh:
            json.dump(rows, fh)
        os.replace(tmp, path)
        for old in path.parent.glob("rows-*.json"):
            if old != path:
                old.unlink(missing_ok=True)
    except OSError:
        pass
