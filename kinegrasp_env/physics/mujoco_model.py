"""MuJoCo, imported on first use (an optional dependency: ``pip install kinegrasp-env[mujoco]``).
"""

from __future__ import annotations

from types import ModuleType


def import_mujoco() -> ModuleType:
    """The ``mujoco`` module; ImportError with a one-line hint when it is not installed."""
    try:
        import mujoco
    except ImportError as exc:
        raise ImportError("MuJoCo is not installed: pip install 'kinegrasp-env[mujoco]' "
                          "(or pip install mujoco)") from exc
    return mujoco
