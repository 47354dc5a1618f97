"""The compiled kernels' disk cache (kinegrasp_env/jit.py): reused, never stale, bounded.

Each test runs its processes in a temporary ``KINEGRASP_CACHE`` and, where the key matters,
on a temporary copy of the package's sources (an edit elsewhere in the checkout while the
test runs must not change the key between its processes); the user's cache is neither read
nor changed.
"""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kinegrasp_env import jit
from kinegrasp_env.assets import assets_dir
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.sdf import cache_dir, grid_file_name, object_grid

# one fast-engine chunk of 10 draws; prints every package kernel's cache statistics, the
# number of numba compilations (numba's own event) and the draws' results
DRAWS = """
import json, sys
import numpy as np
from numba.core import event
from numba.core.dispatcher import Dispatcher
from kinegrasp_env import jit
from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.world.grasps import shipped_grasps

with event.install_recorder("numba:compile") as compiles:
    engine = make_engine("fast", DEFAULT_ROBOT, "cube")
    q = chunk_configurations(shipped_grasps("cube")[0].q0, 7, 0.0266, "gaussian", 0, 0, 10)
    out = engine.run(q)
stats = {}
for name, module in list(sys.modules.items()):
    for attr, value in list(vars(module).items()):
        if (name.startswith("kinegrasp_env") and isinstance(value, Dispatcher)
                and value.py_func.__module__ == name):
            s = value.stats
            stats[name + "." + attr] = [sum(s.cache_hits.values()), sum(s.cache_misses.values())]
print(json.dumps({"stats": stats, "compiles": len(compiles.buffer), "key": jit.source_key(),
                  "outcome": out.outcome.tolist(), "quality": out.quality.tolist(),
                  "points": np.nan_to_num(out.points, nan=9.0).tolist()}))
"""

# the key of the package imported from PYTHONPATH (argv[1]), then of the copies argv[2:]
# (the same function with its package folder pointed at each), and the modules each covers
KEYS = """
import json, sys
from pathlib import Path
import kinegrasp_env.jit as jit
out = {"imported": str(jit.PACKAGE_DIR)}
for root in sys.argv[1:]:
    jit.PACKAGE_DIR = Path(root) / "kinegrasp_env"
    jit.source_key.cache_clear()
    out[root] = {"key": jit.source_key(), "sources": [
        str(p.relative_to(jit.PACKAGE_DIR)) for p in jit.kernel_sources()]}
print(json.dumps(out))
"""

# compile one small package kernel under the key argv[1], stale after argv[2] seconds
COMPILE_UNDER_KEY = """
import sys
import numpy as np
import kinegrasp_env.jit as jit
jit.source_key = lambda: sys.argv[1]
jit.STALE_AFTER = float(sys.argv[2])
from kinegrasp_env.closing.capsule_gap import trilinear
trilinear(np.zeros(8), np.array([2, 2, 2]), np.zeros(3), 1.0, 0.5, 0.5, 0.5)
"""


def run_python(code: str, *args: str, env: dict | None = None, cwd: Path | None = None) -> str:
    """stdout of ``python -c code args`` (fails the test, with stderr, on an error)."""
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          env={**os.environ, **(env or {})}, cwd=cwd, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def copy_sources(dest: Path) -> Path:
    """The package's Python sources copied to dest/kinegrasp_env; returns dest."""
    for path in jit.PACKAGE_DIR.rglob("*.py"):
        target = dest / "kinegrasp_env" / path.relative_to(jit.PACKAGE_DIR)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(path, target)
    return dest


def keys_of(*roots: Path) -> list[dict]:
    """source_key and kernel_sources of the package in each root folder, computed by a fresh
    process that imports the first (not the installed package)."""
    out = json.loads(run_python(KEYS, *map(str, roots), env={"PYTHONPATH": str(roots[0])},
                                cwd=roots[0]))
    assert Path(out["imported"]) == roots[0] / "kinegrasp_env"
    return [out[str(root)] for root in roots]


def edited(root: Path, module: str, old: str, new: str) -> Path:
    """root with one exact text replacement in kinegrasp_env/<module> (must occur)."""
    path = root / "kinegrasp_env" / module
    text = path.read_text()
    assert old in text, f"{old!r} not in {module}: update the test's edit"
    path.write_text(text.replace(old, new, 1))
    return root


@pytest.mark.expensive
def test_a_second_process_loads_every_kernel_from_the_cache_and_compiles_nothing(tmp_path):
    src = copy_sources(tmp_path / "src")
    (src / "assets").symlink_to(assets_dir())
    cache = tmp_path / "cache"
    grid = grid_file_name(load_object("cube"))
    object_grid("cube")  # the grid (not what is tested here) is copied, not rebuilt
    (cache / "sdf").mkdir(parents=True)
    shutil.copy(cache_dir() / grid, cache / "sdf" / grid)
    env = {"KINEGRASP_CACHE": str(cache), "NUMBA_DISABLE_JIT": "0", "PYTHONPATH": str(src)}
    first = json.loads(run_python(DRAWS, env=env, cwd=src))
    second = json.loads(run_python(DRAWS, env=env, cwd=src))

    compiled = {k for k, (_, misses) in first["stats"].items() if misses}
    assert "kinegrasp_env.closing.close_kernel.close_all" in compiled
    assert first["compiles"] > 0
    # the second process compiles nothing: every kernel the draws call comes from the disk
    # cache (with its callees, compiled into it: those are not loaded on their own)
    assert second["compiles"] == 0
    assert sum(misses for _, misses in second["stats"].values()) == 0
    loaded = {k for k, (hits, _) in second["stats"].items() if hits}
    assert "kinegrasp_env.closing.close_kernel.close_all" in loaded
    assert loaded <= compiled
    assert second["stats"]["kinegrasp_env.closing.close_kernel.close_all"] == [1, 0]
    # ... and gives the same draws, bit for bit
    for field in ("outcome", "quality", "points"):
        assert second[field] == first[field]
    # the files are under the key (nothing written next to the sources)
    assert first["key"] == second["key"]
    assert (cache / "numba" / first["key"] / "closing").is_dir()
    assert not list(src.rglob("*.nbi"))


def test_the_key_changes_with_every_kernel_source_and_only_with_them(tmp_path):
    # a constant of a kernel module; a module of close_kernel's import chain (the tolerance
    # passed to segment_one); a module no kernel module imports
    original, capsule, polytope, unrelated, installed = keys_of(
        copy_sources(tmp_path / "same"),
        edited(copy_sources(tmp_path / "capsule"), "closing/capsule_gap.py", "NEAR = 2e-3",
               "NEAR = 2.5e-3"),
        edited(copy_sources(tmp_path / "polytope"), "world/polytope.py", "INSIDE_TOL = ",
               "INSIDE_TOL = 2 * "),
        edited(copy_sources(tmp_path / "arms"), "cli/arms.py", '"""', '"""Edited. '),
        jit.PACKAGE_DIR.parent)
    # content, not place: an identical copy has the installed package's key
    assert original["key"] == installed["key"]
    assert {"closing/capsule_gap.py", "world/polytope.py"} <= set(original["sources"])
    assert "cli/arms.py" not in original["sources"]
    assert capsule["key"] != original["key"]
    assert polytope["key"] != original["key"]
    assert capsule["key"] != polytope["key"]
    assert unrelated["key"] == original["key"]


def test_every_module_with_a_compiled_function_is_covered_by_the_key():
    # the key covers the files that say "jit.kernel"; a kernel declared any other way
    # (numba.njit, a renamed import) would be cached under a key blind to its source
    covered = set(jit.kernel_sources())
    for path in jit.PACKAGE_DIR.rglob("*.py"):
        tree = ast.parse(path.read_text())
        compilers = {"jit", "numba"}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module in ("numba", "kinegrasp_env.jit"):
                compilers |= {a.asname or a.name for a in node.names}
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef):
                for deco in node.decorator_list:
                    root = deco.func if isinstance(deco, ast.Call) else deco
                    while isinstance(root, ast.Attribute):
                        root = root.value
                    if isinstance(root, ast.Name) and root.id in compilers:
                        assert path in covered, f"{path.name}:{node.name} is not in the key"


@pytest.mark.expensive
def test_stale_key_folders_are_removed_when_a_new_key_is_made(tmp_path):
    numba_dir = tmp_path / "numba"
    env = {"KINEGRASP_CACHE": str(tmp_path)}
    stale_after = 60.0  # seconds (jit.STALE_AFTER, set in the child processes)

    def age(folder: Path, seconds: float) -> None:
        then = time.time() - seconds
        os.utime(folder, (then, then))

    for name, seconds in (("old", 2 * stale_after), ("recent", 0.5 * stale_after)):
        (numba_dir / name).mkdir(parents=True)
        age(numba_dir / name, seconds)
    run_python(COMPILE_UNDER_KEY, "key_a", str(stale_after), env=env)
    assert {p.name for p in numba_dir.iterdir()} == {"key_a", "recent"}
    assert list((numba_dir / "key_a" / "closing").glob("*.nbi"))  # the kernel was saved
    age(numba_dir / "key_a", 2 * stale_after)
    run_python(COMPILE_UNDER_KEY, "key_b", str(stale_after), env=env)
    assert {p.name for p in numba_dir.iterdir()} == {"key_b", "recent"}
