"""Locate the files shipped in ``assets/`` (robots, objects, grasp sets).

In a wheel the folder is installed as ``kinegrasp_env/assets``; in an editable install or a
source checkout it is the repository's top-level ``assets/``. :func:`asset_path` is the one
place that knows this.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent


@lru_cache(maxsize=1)
def assets_dir() -> Path:
    """Return the directory holding the shipped assets.

    Raises:
        FileNotFoundError: if neither the installed nor the source-tree location exists.
    """
    for candidate in (_PACKAGE_DIR / "assets", _PACKAGE_DIR.parent / "assets"):
        if (candidate / "robots").is_dir():
            return candidate
    raise FileNotFoundError(
        f"kinegrasp assets not found next to {_PACKAGE_DIR} (looked for 'assets/robots'); "
        "reinstall the package"
    )


def asset_path(*parts: str) -> Path:
    """Path of a shipped asset, e.g. ``asset_path("robots", "kuka_sdh.urdf")``.

    Raises:
        FileNotFoundError: naming the missing file.
    """
    path = assets_dir().joinpath(*parts)
    if not path.exists():
        raise FileNotFoundError(f"asset not found: {'/'.join(parts)} (in {assets_dir()})")
    return path
