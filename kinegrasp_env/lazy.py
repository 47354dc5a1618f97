"""Public names of a package that load their module on first use.

A room's ``__init__`` lists what it offers; importing the room stays cheap (no pybullet, numba
or matplotlib until a name that needs them is used).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable


def lazy_exports(package: str, exports: dict[str, str]) -> tuple[Callable, Callable]:
    """``__getattr__`` and ``__dir__`` for ``package``.

    Args:
        package: the package's dotted name (``__name__`` in its ``__init__``).
        exports: public name -> the submodule (relative to ``package``) that defines it.
    """

    def __getattr__(name: str):
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        try:
            loaded = importlib.import_module(f"{package}.{module}")
        except AttributeError as exc:  # would otherwise read as "no attribute {name}"
            raise ImportError(f"importing {package}.{module} failed: {exc}") from exc
        value = getattr(loaded, name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(exports))

    return __getattr__, __dir__
