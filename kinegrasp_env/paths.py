"""Where kinegrasp keeps files between runs.

``cache_root()``: rebuildable caches (distance grids, compiled kernels):
``$KINEGRASP_CACHE`` if set, else ``~/.cache/kinegrasp``. Deleting it costs only time.

``data_root()``: the user's own data (imported objects, :mod:`kinegrasp_env.world.importer`):
``$KINEGRASP_HOME`` if set, else the platform's user data folder
(``platformdirs.user_data_dir("kinegrasp")``, e.g. ``~/.local/share/kinegrasp`` on Linux).
Deleting it loses what was imported.
"""

from __future__ import annotations

import os
from pathlib import Path


def cache_root() -> Path:
    """The cache folder (not created here)."""
    return Path(os.environ.get("KINEGRASP_CACHE", Path.home() / ".cache" / "kinegrasp"))


def data_root() -> Path:
    """The user's data folder (not created here)."""
    home = os.environ.get("KINEGRASP_HOME")
    if home:
        return Path(home)
    from platformdirs import user_data_dir

    return Path(user_data_dir("kinegrasp", appauthor=False))
