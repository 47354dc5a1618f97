"""Public names of a package that load their module on first use.

A room's ``__init__`` lists what it offers; importing the room stays cheap (no pybullet, numba
or matplotlib until a name that needs them is used).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable


def lazy_exports(package: str, modules: dict[str, tuple[str, ...]]
                 ) -> tuple[Callable, Callable, list[str]]:
    """``__getattr__``, ``__dir__`` and ``__all__`` for ``package``.

    Args:
        package: the package's dotted name (``__name__`` in its ``__init__``).
        modules: each submodule (relative to ``package``) -> the public names it defines.

    Returns:
        (``__getattr__``, ``__dir__``, the public names sorted: ``__all__``). The table,
        name -> submodule, stays on the package as ``_EXPORTS`` (where each name is defined,
        for the API reference: docs/gen_api.py).

    Raises:
        ValueError: a name listed under two modules.
    """
    exports: dict[str, str] = {}
    for module, names in modules.items():
        for name in names:
            if exports.setdefault(name, module) != module:
                raise ValueError(f"{package}: {name!r} listed under {exports[name]!r} and "
                                 f"{module!r}")
    sys.modules[package]._EXPORTS = exports

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

    return __getattr__, __dir__, sorted(exports)


def defining_modules(package) -> dict[str, str] | None:
    """Public name -> the submodule that defines it, of a package whose ``__init__`` uses
    :func:`lazy_exports` (None for any other module): where the API reference documents
    each name."""
    table = getattr(package, "_EXPORTS", None)
    return dict(table) if table is not None else None


class _AfterImport:
    """Meta path finder that runs ``callback(module)`` right after ``name`` is first imported
    (duck-typed: importing ``importlib.abc`` itself would slow the package's import)."""

    def __init__(self, name: str, callback: Callable) -> None:
        self.name, self.callback = name, callback

    def find_spec(self, fullname, path=None, target=None):
        if fullname != self.name:
            return None
        sys.meta_path.remove(self)  # one shot; the other finders locate the real module
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec
        loader, callback = spec.loader, self.callback

        class _Loader:
            def create_module(self, spec):
                return loader.create_module(spec)

            def exec_module(self, module):
                loader.exec_module(module)
                callback(module)

            def __getattr__(self, attr):  # the rest of the loader's interface
                return getattr(loader, attr)

        spec.loader = _Loader()
        return spec


def when_imported(name: str, callback: Callable) -> None:
    """Run ``callback(module)`` once top-level module ``name`` is imported: now if it already
    is, else right after its import completes (without importing it here)."""
    module = sys.modules.get(name)
    if module is not None:
        callback(module)
        return
    if not any(isinstance(f, _AfterImport) and f.name == name for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterImport(name, callback))
