"""One writer of the benchmark scripts' JSON results (``benchmarks/results/<script>.json``).

Every benchmark script prints its figures for the reader and writes the same figures as
JSON, which ``docs/gen_benchmarks.py`` renders on the benchmarks page: top-level scalars as a
figure/value table, top-level dicts of records as one table (a row per key), lists of records
as tables of their own, and the two keys this module adds, ``settings`` (the options the run
used) and ``machine`` (:func:`machine_facts`), as name/value tables of their own.

Scripts run as ``python benchmarks/<script>.py``, so this folder is on ``sys.path`` and they
import it as ``from results_file import ...``.

The load average "before" is the one at this module's import (scripts import it first,
before any work); "after" is the one when the result is written.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"

#: ``os.getloadavg()`` when this module was imported: the load before the script's work.
LOAD_AT_START = os.getloadavg()


def default_path(script_file: str | Path) -> Path:
    """``benchmarks/results/<script name>.json`` of a script (its ``__file__``)."""
    return RESULTS / f"{Path(script_file).stem}.json"


def add_options(parser: argparse.ArgumentParser, script_file: str | Path) -> None:
    """Add ``--json-out PATH`` (default :func:`default_path`) and ``--no-json``."""
    parser.add_argument("--json-out", type=Path, default=default_path(script_file),
                        help="write the figures as JSON here (default: %(default)s)")
    parser.add_argument("--no-json", action="store_true", help="write no JSON result")


def settings(args: argparse.Namespace) -> dict:
    """The run's options (``vars(args)``) without the two options of :func:`add_options`."""
    return {key: value for key, value in vars(args).items()
            if key not in ("json_out", "no_json")}


def cpu_model() -> str | None:
    """The CPU's model name from ``/proc/cpuinfo`` (None where there is none)."""
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.lower().startswith(("model name", "hardware", "cpu model")):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def git_commit() -> dict | None:
    """``{"commit": hash, "dirty": bool}`` of the checkout this script lives in (None outside
    a git checkout or without git)."""
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True, check=True, timeout=10).stdout.strip()
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                                cwd=ROOT, capture_output=True, text=True, check=True,
                                timeout=10).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    return {"commit": commit, "dirty": bool(status.strip())}


def machine_facts(load_before: tuple[float, float, float] | None = None) -> dict:
    """What a timing needs to be read: CPUs, CPU model, the 1/5/15-minute load averages before
    (``load_before``, default :data:`LOAD_AT_START`) and now, Python and numpy versions, the
    platform and the git commit."""
    try:
        import numpy
        numpy_version = numpy.__version__
    except ImportError:
        numpy_version = None
    git = git_commit()
    return {
        "cpu_count": os.cpu_count(),
        "cpu_model": cpu_model(),
        "load_before": [round(x, 2) for x in load_before or LOAD_AT_START],
        "load_after": [round(x, 2) for x in os.getloadavg()],
        "python": sys.version.split()[0],
        "numpy": numpy_version,
        "platform": platform.platform(),
        "git_commit": git["commit"] if git else None,
        "git_dirty": git["dirty"] if git else None,
    }


def plain(value: object) -> object:
    """A JSON-ready copy: numpy scalars and arrays as Python numbers and lists, paths and
    other objects as strings, tuples as lists, NaN and infinities as None (strict JSON)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set)):
        return [plain(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return plain(value.tolist())  # numpy scalar or array
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return str(value)


def write_result(script_file: str | Path, record: dict, path: str | Path | None = None
                 ) -> Path:
    """Write ``record`` (the script's figures, and its ``settings``) with ``script``, ``date``
    (UTC, ISO 8601) and ``machine`` (:func:`machine_facts`) to ``path`` (default
    :func:`default_path`); the folder is created. Returns the path written; says so on
    stderr (the script's stdout stays its printed figures)."""
    out = Path(path) if path is not None else default_path(script_file)
    result = {"script": Path(script_file).name,
              "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              **record, "machine": machine_facts()}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(plain(result), indent=1) + "\n")
    print(f"wrote {out}", file=sys.stderr)
    return out


def publish(script_file: str | Path, record: dict, args: argparse.Namespace, table: str,
            page: Path, markers: tuple[str, str]) -> None:
    """Print ``table`` (the script's Markdown figures); unless ``--no-json``, write ``record``
    to ``--json-out`` (:func:`write_result`) and ``table`` between ``markers`` (start, end)
    of the docs ``page`` (:func:`marked_section.write_between`)."""
    print(table)
    if not args.no_json:
        from marked_section import write_between

        write_result(script_file, record, args.json_out)
        write_between(page, *markers, table)
