"""Compiled kernels: ``@jit.kernel`` is numba's ``njit`` with an on-disk cache that cannot go stale.

numba keys a cached function on its own source file only: a kernel that calls a kernel of
another module, or reads another module's constant, would keep its old machine code after
that other file changes. Here every kernel of the package is cached under one key, the SHA-256
of the source of every module that defines a kernel and of every package module those import
(transitively). Any change to any of them gives a new key, so all kernels compile afresh once;
nothing can be served from code that no longer matches the source.

The cache lives in ``cache_root()/numba/<key>`` (see :mod:`kinegrasp_env.paths`): one file per
kernel and signature (numba's index and data files). Folders of other keys that have not been
used for an hour are removed when a new one is made, so the cache stays bounded (the hour
spares a process still running an older checkout).

With ``NUMBA_DISABLE_JIT=1`` the kernels run as plain Python (the tests use this to check a
kernel against its own logic, interpreted).
"""

from __future__ import annotations

import ast
import hashlib
import os
import shutil
import tempfile
import time
from functools import lru_cache
from pathlib import Path

import numba
from numba.core import caching

from kinegrasp_env.paths import cache_root

PACKAGE_DIR = Path(__file__).resolve().parent
#: Unused key folders older than this (seconds) are removed when a new key folder is made.
STALE_AFTER = 3600.0


def _package_imports(path: Path) -> set[Path]:
    """Files of package modules that ``path`` imports (``kinegrasp_env.x.y`` -> x/y.py)."""
    tree = ast.parse(path.read_text())
    found: set[Path] = set()
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names:
            parts = name.split(".")
            if parts[0] != "kinegrasp_env":
                continue
            base = PACKAGE_DIR.joinpath(*parts[1:])
            for candidate in (base.with_suffix(".py"), base / "__init__.py"):
                if candidate.is_file():
                    found.add(candidate)
    return found


def kernel_sources() -> list[Path]:
    """Every module that defines a kernel, and every package module they import, sorted."""
    roots = [p for p in PACKAGE_DIR.rglob("*.py") if "jit.kernel" in p.read_text()]
    seen: set[Path] = set()
    todo = list(roots)
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        todo.extend(_package_imports(path) - seen)
    return sorted(seen)


@lru_cache(maxsize=1)
def source_key() -> str:
    """SHA-256 (hex, 16 characters) of the kernel sources and the numba version."""
    digest = hashlib.sha256(numba.__version__.encode())
    for path in kernel_sources():
        digest.update(str(path.relative_to(PACKAGE_DIR)).encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def kernel_cache_dir() -> Path:
    """The folder of the current key's compiled kernels."""
    return cache_root() / "numba" / source_key()


def _remove_stale_keys(current: Path) -> None:
    now = time.time()
    for other in current.parent.iterdir():
        if other != current and other.is_dir() and now - other.stat().st_mtime > STALE_AFTER:
            shutil.rmtree(other, ignore_errors=True)


class _PackageCacheLocator(caching._CacheLocator):
    """numba cache locator for the package's kernels (see the module docstring)."""

    def __init__(self, py_func, py_file):
        self._lineno = py_func.__code__.co_firstlineno
        # fixed when the kernel is defined: a later change of $KINEGRASP_CACHE does not move it
        self._key_dir = kernel_cache_dir()
        self._path = self._key_dir / Path(py_file).resolve().relative_to(PACKAGE_DIR).parent

    def ensure_cache_path(self):
        fresh = not self._key_dir.exists()
        os.makedirs(self._path, exist_ok=True)
        tempfile.TemporaryFile(dir=self._path).close()
        if fresh:
            _remove_stale_keys(self._key_dir)

    def get_cache_path(self):
        return str(self._path)

    def get_source_stamp(self):
        return source_key()

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            Path(py_file).resolve().relative_to(PACKAGE_DIR)
        except ValueError:
            return None
        return cls(py_func, py_file)


_IMPL = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # renamed in numba 0.6x
if _PackageCacheLocator not in _IMPL._locator_classes:
    _IMPL._locator_classes.insert(0, _PackageCacheLocator)


def kernel(*args, **kwargs):
    """``numba.njit(cache=True, ...)`` with the package's cache (use as ``@jit.kernel``)."""
    kwargs["cache"] = True
    return numba.njit(*args, **kwargs)
