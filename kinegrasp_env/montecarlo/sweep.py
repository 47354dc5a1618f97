"""``kinegrasp sweep``: a grid of grasp evaluations, resumable, on any executor.

The grid is objects x grasps x sigmas x noise types x engines; each cell is ``samples``
draws split into chunks of ``chunk``. A *task* is one chunk of one cell. Chunk c of every
cell draws its noise from ``SeedSequence(seed, spawn_key=(c,))`` (the stream
:func:`kinegrasp_env.montecarlo.evaluate.evaluate_grasp` uses), so a cell's numbers equal
``evaluate_grasp`` with the same seed, whatever ran the task, and cells of the same noise
type share their draws (common random numbers make grasps comparable). A ``noise`` entry may
also be a noise model (a spec mapping or file: :mod:`kinegrasp_env.montecarlo.sweep_noise`),
whose joint sigma is the cell's sigma.

Grasps: a built-in object's come from its shipped set; ``grasp_files`` maps an object to a
grasp file (``kinegrasp plan``'s output, relative to the spec file) whose grasps replace
the shipped set, which is how an imported object (it has none) is swept. ``grasps`` indexes
each object's set. The store records every grasp file's SHA-256 and every imported object's
catalog version: a store made with other grasps or a re-imported object is not extended.

Results go to an SQLite file, ``DIR/results.sqlite``, one row per finished task, committed
as soon as the task finishes. SQLite because it ships with Python (nothing to install on a
cluster's head node), a committed transaction survives the process being killed, and the
task key is the table's primary key, so the store holds each task at most once by
construction; only the driver writes, so there is no write contention. Re-running the
same command reads the finished keys and submits only the others. The summary merges
each cell's chunks in chunk order, so it is bit-identical however the tasks were run.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import sqlite3
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from kinegrasp_env.montecarlo.engines import OUTCOMES
from kinegrasp_env.montecarlo.evaluate import ENGINES, MAX_SIGMA, chunk_sizes, run_chunk
from kinegrasp_env.montecarlo.evaluate import summarize as grasp_stats
from kinegrasp_env.montecarlo.sweep_noise import cell_noise, noise_entries
from kinegrasp_env.sampling.noise_spec import spec_loader
from kinegrasp_env.sampling.stats import StreamingMoments
from kinegrasp_env.world.grasps import Grasp, write_atomic
from kinegrasp_env.world.objects import OBJECT_NAMES, object_names, object_version

#: ``plot(rows, path, title=...) -> path``: draws one P(FC)-vs-sigma figure of summary rows.
SweepPlot = Callable[..., Path]

SPEC_KEYS = ("objects", "grasps", "grasp_files", "sigmas", "noise", "engines", "samples",
             "chunk", "seed")
#: Settings that fix the random streams: a store made with others cannot be extended.
STREAM_KEYS = ("seed", "chunk")
SUMMARY_COLUMNS = ("object", "grasp", "sigma", "noise", "engine", "p_fc", "p_fc_lo", "p_fc_hi",
                   "q_mean", "q_std", "q_skew", "q_nominal", "samples", *OUTCOMES)


class SpecError(ValueError):
    """A sweep specification that cannot run (raised before any work starts)."""


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep grid (see the module docstring)."""

    objects: tuple[str, ...]
    grasps: tuple[int, ...] | None  # None: every shipped grasp
    sigmas: tuple[float, ...]
    noise: tuple[str, ...] = ("gaussian",)
    engines: tuple[str, ...] = ("pybullet",)
    samples: int = 1000
    chunk: int = 250
    seed: int = 0
    #: (label, spec JSON) of the noise models among ``noise``
    models: tuple[tuple[str, str], ...] = ()
    #: (object, absolute path, SHA-256) of each grasp file replacing a shipped set
    grasp_files: tuple[tuple[str, str, str], ...] = ()

    @classmethod
    def from_dict(cls, data: Any, where: str = "spec",
                  base: str | Path | None = None) -> SweepSpec:
        """Validate every entry; one :class:`SpecError` naming the first bad one (``base``:
        the folder noise spec files are relative to)."""
        if not isinstance(data, dict):
            raise SpecError(f"{where}: expected a mapping of {', '.join(SPEC_KEYS)}")
        unknown = sorted(set(data) - set(SPEC_KEYS))
        if unknown:
            raise SpecError(f"{where}: unknown key {unknown[0]!r}; allowed keys: "
                            f"{', '.join(SPEC_KEYS)}")
        for key in ("objects", "sigmas"):
            if key not in data:
                raise SpecError(f"{where}: missing key {key!r}")
        objects = _names(data["objects"], object_names(), "objects", where)
        files = _grasp_files(data.get("grasp_files", {}), objects, where, base)
        _check_grasp_sets(objects, files, where)
        noise, models = _noise(data.get("noise", ["gaussian"]), where, base)
        engines = _names(data.get("engines", ["pybullet"]), ENGINES, "engines", where)
        sigmas = _unique(tuple(_sigma(s, where) for s in _list(data["sigmas"], "sigmas", where)),
                         "sigmas", where)
        grasps = data.get("grasps", "all")
        if grasps == "all":
            indices = None
        else:
            indices = _unique(tuple(_integer(g, "grasps", where, low=0)
                                    for g in _list(grasps, "grasps", where)), "grasps", where)
            _check_grasp_indices(objects, indices, files, where)
        samples = _integer(data.get("samples", 1000), "samples", where, low=1)
        chunk = _integer(data.get("chunk", 250), "chunk", where, low=1)
        seed = _integer(data.get("seed", 0), "seed", where, low=0)
        return cls(objects, indices, sigmas, noise, engines, samples, chunk, seed, models,
                   files)

    @classmethod
    def from_file(cls, path: str | Path) -> SweepSpec:
        """Read a YAML (or JSON) spec file (numbers as YAML 1.2 reads them: ``1e-2`` is a
        number); a syntax error is one :class:`SpecError` line: file, line, column, what."""
        path = Path(path)
        if not path.is_file():
            raise SpecError(f"spec file {path} not found")
        import yaml

        try:
            data = yaml.load(path.read_text(), Loader=spec_loader())  # a SafeLoader
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
            what = exc.problem or exc.context or "syntax error"
            raise SpecError(f"{where}: not valid YAML: {what}") from None
        except yaml.YAMLError as exc:
            raise SpecError(f"{path}: not valid YAML: {' '.join(str(exc).split())}") from None
        return cls.from_dict(data, where=str(path), base=path.parent)

    def grasp_set(self, object_name: str) -> tuple[Grasp, ...]:
        """The grasps of ``object_name`` the sweep indexes: its grasp file's, else its
        shipped set."""
        return _grasp_set(object_name, self.grasp_files)

    def grasp(self, object_name: str, index: int) -> Grasp:
        return self.grasp_set(object_name)[index]

    def grasp_indices(self, object_name: str) -> tuple[int, ...]:
        if self.grasps is None:
            return tuple(range(len(self.grasp_set(object_name))))
        return self.grasps

    def sources(self) -> dict[str, str]:
        """What the store must have been made with besides the streams: per object, its
        grasp file's SHA-256 (or ``shipped``) and its catalog version."""
        files = {name: digest for name, _, digest in self.grasp_files}
        out = {}
        for name in self.objects:
            out[f"grasps:{name}"] = files.get(name, "shipped")
            out[f"object:{name}"] = object_version(name)
        return out

    def cells(self) -> list[tuple[str, int, float, str, str]]:
        """(object, grasp, sigma, noise, engine) in a fixed order."""
        return [(o, g, s, n, e) for o in self.objects for g in self.grasp_indices(o)
                for s in self.sigmas for n in self.noise for e in self.engines]

    def tasks(self) -> list[SweepTask]:
        """Every task, carrying its grasp's q0 (a worker needs no grasp file)."""
        sizes = chunk_sizes(self.samples, self.chunk)
        models = dict(self.models)
        return [SweepTask(o, g, s, n, e, c, size, self.seed, models.get(n),
                          tuple(self.grasp(o, g).q0.tolist()))
                for (o, g, s, n, e) in self.cells() for c, size in enumerate(sizes)]


def _noise(value: Any, where: str, base: str | Path | None
           ) -> tuple[tuple[str, ...], tuple[tuple[str, str], ...]]:
    """``noise``: distribution names and noise models (labels, models)."""
    from kinegrasp_env.sampling.noise_model import NoiseSpecError

    try:
        labels, models = noise_entries(_list(value, "noise", where), base)
    except NoiseSpecError as exc:
        raise SpecError(f"{where}: noise: {exc}") from None
    return _unique(labels, "noise", where), models


#: Numbers YAML 1.1 reads as strings but YAML 1.2 (and every reader of the spec) as floats:
#: an exponent without a decimal point or without a sign (``1e-2``, ``5E3``, ``1.5e3``).


def _unique(values: tuple, key: str, where: str) -> tuple:
    """``values`` if no entry repeats; else a :class:`SpecError` naming the first repeat."""
    for i, value in enumerate(values):
        if value in values[:i]:
            raise SpecError(f"{where}: {value!r} appears twice in {key!r}; list each "
                            "entry once")
    return values


def _list(value: Any, key: str, where: str) -> list:
    values = list(value) if isinstance(value, (list, tuple)) else [value]
    if not values:
        raise SpecError(f"{where}: {key!r} is empty")
    return values


def _names(value: Any, known: tuple[str, ...], key: str, where: str) -> tuple[str, ...]:
    names = _list(value, key, where)
    for name in names:
        if name not in known:
            raise SpecError(f"{where}: unknown {key[:-1] if key.endswith('s') else key} "
                            f"{name!r} in {key!r}; known: {', '.join(known)}")
    return _unique(tuple(names), key, where)


def _sigma(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(f"{where}: sigma {value!r} is not a number")
    if not math.isfinite(value) or value < 0:
        raise SpecError(f"{where}: sigma must be finite and >= 0, got {value}")
    if value > MAX_SIGMA:
        raise SpecError(f"{where}: sigma must be <= pi ({MAX_SIGMA:.5f} rad), got {value}")
    return float(value)


def _integer(value: Any, key: str, where: str, low: int) -> int:
    """An integer >= ``low``; a float with no fractional part counts (``samples: 1e4``)."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise SpecError(f"{where}: {key!r} must be an integer >= {low}, got {value!r}")
    return value


def _grasp_files(value: Any, objects: tuple[str, ...], where: str,
                 base: str | Path | None) -> tuple[tuple[str, str, str], ...]:
    """``grasp_files``: (object, absolute path, SHA-256) per entry, each file read and
    checked (grasps of that object, at least one)."""
    if not isinstance(value, dict):
        raise SpecError(f"{where}: 'grasp_files' must map objects to grasp files, e.g. "
                        "{duck: duck_grasps.json}")
    out = []
    for name, text in value.items():
        if name not in objects:
            raise SpecError(f"{where}: grasp_files names {name!r}, which is not in 'objects'")
        if not isinstance(text, str) or not text:
            raise SpecError(f"{where}: grasp_files: {name}: expected a file name, got {text!r}")
        path = (Path(base or ".") / text).absolute()
        try:
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
            grasps = _file_grasps(str(path), digest)
        except FileNotFoundError:
            raise SpecError(f"{where}: grasp_files: {name}: no such file {path}") from None
        except (OSError, ValueError) as exc:
            raise SpecError(f"{where}: grasp_files: {name}: {exc}") from None
        if not grasps:
            raise SpecError(f"{where}: grasp_files: {name}: {path} holds no grasps")
        other = next((g for g in grasps if g.object != name), None)
        if other is not None:
            raise SpecError(f"{where}: grasp_files: {name}: grasp {other.id} of {path} is a "
                            f"grasp of {other.object}")
        out.append((name, str(path), digest))
    return tuple(out)


@lru_cache(maxsize=16)
def _file_grasps(path: str, digest: str) -> tuple[Grasp, ...]:
    """The grasps of a grasp file whose bytes have SHA-256 ``digest`` (a file changed since
    the spec was read is a :class:`SpecError`)."""
    from kinegrasp_env.world.grasps import load_grasps

    if hashlib.sha256(Path(path).read_bytes()).hexdigest() != digest:
        raise SpecError(f"{path} changed since the sweep spec was read")
    return tuple(load_grasps(path))


def _grasp_set(name: str, files: tuple[tuple[str, str, str], ...]) -> tuple[Grasp, ...]:
    from kinegrasp_env.world.grasps import shipped_grasps

    for object_name, path, digest in files:
        if object_name == name:
            return _file_grasps(path, digest)
    return tuple(shipped_grasps(name))


def _check_grasp_sets(objects: tuple[str, ...], files: tuple[tuple[str, str, str], ...],
                      where: str) -> None:
    """An imported object (no shipped set) needs a grasp file: one line saying how."""
    given = {name for name, _, _ in files}
    for name in objects:
        if name not in OBJECT_NAMES and name not in given:
            raise SpecError(
                f"{where}: {name!r} is an imported object and has no shipped grasp set; give "
                f"its grasp file in 'grasp_files' (e.g. grasp_files: {{{name}: "
                f"{name}_grasps.json}}, written by `kinegrasp plan --object {name} --out "
                f"{name}_grasps.json`)")


def _check_grasp_indices(objects: tuple[str, ...], indices: tuple[int, ...],
                         files: tuple[tuple[str, str, str], ...], where: str) -> None:
    for name in objects:
        count = len(_grasp_set(name, files))
        bad = [i for i in indices if i >= count]
        if bad:
            kind = "grasp file" if any(f[0] == name for f in files) else "shipped set"
            raise SpecError(f"{where}: grasp {bad[0]} does not exist for {name} "
                            f"(its {kind} has grasps 0..{count - 1})")


@dataclass(frozen=True)
class SweepTask:
    """One chunk of one cell; ``key`` is its identity in the store."""

    object: str
    grasp: int
    sigma: float
    noise: str
    engine: str
    chunk: int
    size: int
    seed: int
    model: str | None = None  # the spec JSON of a noise-model cell
    q0: tuple[float, ...] | None = None  # the grasp's (14,); None: shipped grasp ``grasp``

    @property
    def key(self) -> str:
        return (f"{self.object}/{self.grasp}/{self.sigma!r}/{self.noise}/{self.engine}/"
                f"{self.chunk}")


def run_task(task: SweepTask) -> dict:
    """Evaluate one task (in a worker): outcome counts and Q moments of its chunk."""
    from kinegrasp_env.world.grasps import grasp_by_index

    start = time.perf_counter()
    q0 = (grasp_by_index(task.object, task.grasp).q0 if task.q0 is None
          else np.asarray(task.q0, dtype=float))
    key = (task.engine, task.object, 0.5, 8)
    counts, moments, _ = run_chunk((key, q0, cell_noise(task.sigma, task.noise, task.model),
                                    task.seed, task.chunk, task.size, "mc", False))
    return {"counts": [int(c) for c in counts], "q_n": int(moments.n),
            "q_mean": float(moments.mean[0]), "q_m2": float(moments.m2[0, 0]),
            "q_m3": float(moments.m3[0]), "seconds": time.perf_counter() - start}


class SweepStore:
    """``DIR/results.sqlite``: the spec it was made for and one row per finished task."""

    def __init__(self, directory: str | Path, spec: SweepSpec):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.path = self.directory / "results.sqlite"
        self._db = sqlite3.connect(self.path)
        outcome_columns = ", ".join(f"{name} INTEGER NOT NULL" for name in OUTCOMES)
        with self._db:
            self._db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, "
                             "value TEXT NOT NULL)")
            self._db.execute(
                "CREATE TABLE IF NOT EXISTS tasks (key TEXT PRIMARY KEY, object TEXT NOT NULL, "
                "grasp INTEGER NOT NULL, sigma REAL NOT NULL, noise TEXT NOT NULL, "
                "engine TEXT NOT NULL, chunk INTEGER NOT NULL, size INTEGER NOT NULL, "
                f"{outcome_columns}, q_n INTEGER NOT NULL, q_mean REAL NOT NULL, "
                "q_m2 REAL NOT NULL, q_m3 REAL NOT NULL, seconds REAL NOT NULL)")
        self._check_streams(spec)

    def _check_streams(self, spec: SweepSpec) -> None:
        stored = dict(self._db.execute("SELECT key, value FROM meta").fetchall())
        wanted = {key: json.dumps(getattr(spec, key)) for key in STREAM_KEYS}
        for key, value in wanted.items():
            if key in stored and stored[key] != value:
                self.close()
                raise SpecError(f"{self.directory} holds a sweep run with {key} = "
                                f"{stored[key]}, the spec says {value}: its random streams "
                                "differ; use another --out")
        sources = spec.sources()
        self._check_sources(stored, sources)
        wanted.update(sources)
        with self._db:
            self._db.executemany("INSERT OR IGNORE INTO meta VALUES (?, ?)", wanted.items())
            self._db.execute("INSERT OR REPLACE INTO meta VALUES ('last_spec', ?)",
                             (json.dumps(asdict(spec)),))

    def _check_sources(self, stored: dict[str, str], sources: dict[str, str]) -> None:
        """Refuse a store made with another grasp file or object version (see
        :meth:`SweepSpec.sources`) for an object of the spec."""
        why = {"grasps": "other grasps (its grasp file changed)",
               "object": "another version of the object (re-imported since)"}
        for key, value in sources.items():
            if key in stored and stored[key] != value:
                self.close()
                what, name = key.split(":", 1)
                raise SpecError(f"{self.directory} holds a sweep of {name} with {why[what]}; "
                                "use another --out")

    def finished(self) -> set[str]:
        return {row[0] for row in self._db.execute("SELECT key FROM tasks")}

    def add(self, task: SweepTask, result: dict) -> None:
        """Record a finished task (committed at once; a second copy is ignored)."""
        with self._db:
            self._db.execute(
                f"INSERT OR IGNORE INTO tasks VALUES ({', '.join('?' * (13 + len(OUTCOMES)))})",
                (task.key, task.object, task.grasp, task.sigma, task.noise, task.engine,
                 task.chunk, task.size, *result["counts"], result["q_n"], result["q_mean"],
                 result["q_m2"], result["q_m3"], result["seconds"]))

    def results(self) -> dict[str, tuple[np.ndarray, StreamingMoments]]:
        """(outcome counts (4,), moments of Q) of every stored task, by key."""
        cursor = self._db.execute(
            f"SELECT key, {', '.join(OUTCOMES)}, q_n, q_mean, q_m2, q_m3 FROM tasks")
        out = {}
        for key, *values in cursor:
            counts = np.array(values[:len(OUTCOMES)], dtype=np.int64)
            out[key] = (counts, StreamingMoments.from_state(*values[len(OUTCOMES):]))
        return out

    def close(self) -> None:
        self._db.close()


def summarize(spec: SweepSpec, store: SweepStore) -> list[dict]:
    """One row per cell of ``spec``: P(FC), Wilson interval, moments of Q, outcomes (the
    statistics of :func:`kinegrasp_env.montecarlo.evaluate.summarize`, chunks merged in order)."""
    results = store.results()
    models = dict(spec.models)
    n_chunks = len(chunk_sizes(spec.samples, spec.chunk))
    summary = []
    for obj, grasp, sigma, noise, engine in spec.cells():
        counts = np.zeros(len(OUTCOMES), dtype=np.int64)
        moments = StreamingMoments(1)
        for c in range(n_chunks):
            chunk_counts, chunk_moments = results[
                SweepTask(obj, grasp, sigma, noise, engine, c, 0, spec.seed).key]
            counts += chunk_counts
            moments.merge(chunk_moments)
        stats = grasp_stats(spec.grasp(obj, grasp),
                            cell_noise(sigma, noise, models.get(noise)), spec.seed, engine,
                            counts, moments, None)
        summary.append({
            "object": obj, "grasp": grasp, "sigma": sigma, "noise": noise, "engine": engine,
            "p_fc": stats.p_fc, "p_fc_lo": stats.p_fc_ci[0], "p_fc_hi": stats.p_fc_ci[1],
            "q_mean": stats.q_mean, "q_std": stats.q_std, "q_skew": stats.q_skew,
            "q_nominal": stats.q_nominal, "samples": stats.samples, **stats.outcomes})
    return summary


def summary_csv(rows: list[dict]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(SUMMARY_COLUMNS)
    for row in rows:
        writer.writerow(["" if isinstance(row[c], float) and math.isnan(row[c]) else
                         (repr(row[c]) if isinstance(row[c], float) else row[c])
                         for c in SUMMARY_COLUMNS])
    return buffer.getvalue()


def summary_table(rows: list[dict]) -> str:
    """Console table of the summary."""
    lines = [f"{'object':<12} {'grasp':>5} {'sigma':>7} {'noise':<10} {'engine':<8} "
             f"{'P(FC)':>6} {'95% CI':>13} {'Q mean':>8} {'draws':>6}"]
    for r in rows:
        q = "-" if math.isnan(r["q_mean"]) else f"{r['q_mean']:.5f}"
        lines.append(f"{r['object']:<12} {r['grasp']:>5} {r['sigma']:>7.4f} {r['noise']:<10} "
                     f"{r['engine']:<8} {r['p_fc']:>6.3f} {r['p_fc_lo']:>6.3f}.."
                     f"{r['p_fc_hi']:<5.3f} {q:>8} {r['samples']:>6}")
    return "\n".join(lines) + "\n"


def figure_names(spec: SweepSpec) -> list[tuple[str, str, str]]:
    """``(noise, engine, file name)`` of each P(FC)-vs-sigma figure a sweep writes."""
    return [(noise, engine, f"pfc_vs_sigma_{noise}_{engine}.png")
            for noise in spec.noise for engine in spec.engines]


def write_outputs(spec: SweepSpec, rows: list[dict], directory: Path,
                  plot: SweepPlot | None = None) -> list[Path]:
    """``summary.csv``, ``summary.txt`` and, given ``plot``, one P(FC)-vs-sigma figure per
    noise x engine (``plot(rows, path, title=...)`` returns the path it wrote)."""
    write_atomic(directory / "summary.csv", summary_csv(rows))
    write_atomic(directory / "summary.txt", summary_table(rows))
    written = [directory / "summary.csv", directory / "summary.txt"]
    if plot is None:
        return written
    for noise, engine, name in figure_names(spec):
        sub = [r for r in rows if r["noise"] == noise and r["engine"] == engine]
        written.append(plot(sub, directory / name, title=f"{noise} noise, {engine} engine, "
                                  f"{spec.samples} draws per cell"))
    return written


def run_sweep(spec: SweepSpec, directory: str | Path, executor, *, progress: bool = True,
              plot: SweepPlot | None = None) -> tuple[list[dict], int, int]:
    """Run the tasks of ``spec`` that ``directory``'s store lacks, then summarize (see
    :func:`write_outputs` for what is written and ``plot``).

    Returns (summary rows, tasks run now, tasks found finished).
    """
    store = SweepStore(directory, spec)
    try:
        tasks = spec.tasks()
        finished = store.finished()
        todo = [t for t in tasks if t.key not in finished]
        from tqdm import tqdm

        bar = tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc="sweep", unit="task",
                   disable=None if progress else True)
        try:
            for index, result in executor.as_completed(run_task, todo):
                store.add(todo[index], result)
                bar.update(1)
        finally:
            bar.close()
        rows = summarize(spec, store)
    finally:
        store.close()
    write_outputs(spec, rows, Path(directory), plot)
    return rows, len(todo), len(tasks) - len(todo)
