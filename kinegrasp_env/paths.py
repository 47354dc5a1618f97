"""Where kinegrasp keeps files between runs.

``cache_root()``: rebuildable caches (distance grids, compiled kernels):
``$KINEGRASP_CACHE`` if set, else ``~/.cache/kinegrasp``. Deleting it costs only time.
"""

from __future__ import annotations

import os
from pathlib import Path


def cache_root() -> Path:
    """The cache folder (not created here)."""
    return Path(os.environ.get("KINEGRASP_CACHE", Path.home() / ".cache" / "kinegrasp"))
