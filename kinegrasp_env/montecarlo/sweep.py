"""``kinegrasp sweep``: a grid of grasp evaluations, resumable, on any executor.

The grid is objects x grasps x sigmas x noise types x engines; each cell is ``samples``
draws split into chunks of ``chunk``. A *task* is one chunk of one cell: rows ``c * chunk
..`` of the cell's run, the rows ``kinegrasp evaluate`` draws with the same seed
(:data:`~kinegrasp_env.sampling.noise_model.DRAW_LAYOUT`: the same draws whatever the chunk
and whatever ran the task), so a cell's numbers equal ``evaluate``'s, and cells of the same
noise type share their draws (common random numbers make grasps comparable). A ``noise`` entry may
also be a noise model (a spec mapping or file: :mod:`kinegrasp_env.montecarlo.sweep_noise`),
whose joint sigma is the cell's sigma. The spec, its checks and its tasks:
:mod:`kinegrasp_env.montecarlo.sweep_spec`.

Grasps: a built-in object's come from its shipped set; ``grasp_files`` maps an object to a
grasp file (``kinegrasp plan``'s output, relative to the spec file) whose grasps replace
the shipped set, which is how an imported object (it has none) is swept. ``grasps`` indexes
each object's set. The store records every grasp file's SHA-256 and every imported object's
catalog version: a store made with other grasps or a re-imported object is not extended.

Robot: the spec's ``robot`` (default ``kuka_sdh``): its cells are joint noise on its arm
joints closed by its own engines, a cell equal to ``kinegrasp evaluate --robot`` with the
same seed (:func:`run_task`, every robot's); another robot's
summary has a first column ``robot``, and a store made for another robot is not extended.

Results go to an SQLite file, ``DIR/results.sqlite``, one row per finished task, committed
as soon as the task finishes. SQLite because it ships with Python (nothing to install on a
cluster's head node), a committed transaction survives the process being killed, and the
task key is the table's primary key, so the store holds each task at most once by
construction; only the driver writes, so there is no write contention. Re-running the
same command reads the finished tasks and submits only the others (and a cell's last chunk
again where a larger ``samples`` grew it). The summary merges
each cell's chunks in chunk order, so it is bit-identical however the tasks were run.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sqlite3
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.montecarlo.draws import OUTCOMES
from kinegrasp_env.montecarlo.grasp_stats import chunk_sizes, tally
from kinegrasp_env.montecarlo.grasp_stats import summarize as grasp_stats
from kinegrasp_env.montecarlo.sweep_noise import cell_noise
from kinegrasp_env.montecarlo.sweep_spec import SpecError, SweepSpec, SweepTask
from kinegrasp_env.physics.simulators import PHYSICS_MODEL
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.sampling.noise_model import DRAW_LAYOUT, STREAM_CHUNK
from kinegrasp_env.sampling.stats import StreamingMoments

#: ``plot(rows, path, title=...) -> path``: draws one P(FC)-vs-sigma figure of summary rows.
SweepPlot = Callable[..., Path]

#: Settings that fix the draws (the seed) and the tasks (the chunk): a store made with others
#: cannot be extended.
STREAM_KEYS = ("seed", "chunk")
#: The layout a store records: every robot's cells rows of one run. A value of its own, so
#: that an older kinegrasp, which drew the default robot's cells otherwise, refuses the store.
SWEEP_LAYOUT = f"{DRAW_LAYOUT}, every robot"
SUMMARY_COLUMNS = ("object", "grasp", "sigma", "noise", "engine", "p_fc", "p_fc_lo", "p_fc_hi",
                   "q_mean", "q_std", "q_skew", "q_nominal", "samples", *OUTCOMES)


def run_task(task: SweepTask) -> dict:
    """Evaluate one task (in a worker): outcome counts and Q moments of its chunk, rows
    ``task.offset .. task.offset + task.size`` of its cell's run
    (:func:`~kinegrasp_env.montecarlo.chunks.close_chunk`: the rows of the seed's
    chunked streams, so a cell's counts equal ``kinegrasp evaluate --robot R`` with the same
    seed whatever the chunk size). Each process keeps its engines for its later tasks."""
    from kinegrasp_env.montecarlo.chunks import RobotChunk, close_chunk

    start = time.perf_counter()
    q0 = task.q0
    if q0 is None:  # the robot's shipped grasp
        from kinegrasp_env.world.grasps import shipped_grasps

        q0 = tuple(shipped_grasps(task.object, task.robot)[task.grasp].q0.tolist())
    # a model cell's model has the cell's sigma as its joints'
    model = None if task.model is None else cell_noise(task.sigma, task.noise, task.model)
    draws = close_chunk(RobotChunk(task.robot, task.object, task.engine, q0, task.sigma,
                                   task.noise, task.seed, task.offset, task.size,
                                   task.friction), model)
    counts, moments = tally(draws)
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
        try:
            with self._db:
                self._db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, "
                                 "value TEXT NOT NULL)")
                self._db.execute(
                    "CREATE TABLE IF NOT EXISTS tasks (key TEXT PRIMARY KEY, object TEXT NOT "
                    "NULL, grasp INTEGER NOT NULL, sigma REAL NOT NULL, noise TEXT NOT NULL, "
                    "engine TEXT NOT NULL, chunk INTEGER NOT NULL, size INTEGER NOT NULL, "
                    f"{outcome_columns}, q_n INTEGER NOT NULL, q_mean REAL NOT NULL, "
                    "q_m2 REAL NOT NULL, q_m3 REAL NOT NULL, seconds REAL NOT NULL)")
            self._check_streams(spec)
        except sqlite3.DatabaseError as exc:  # a damaged file, or another program's
            self.close()
            raise SpecError(f"{self.path} is not a sweep store kinegrasp can read ({exc}); "
                            "use another --out, or remove the file to start afresh") from None

    def _check_streams(self, spec: SweepSpec) -> None:
        stored = dict(self._db.execute("SELECT key, value FROM meta").fetchall())
        wanted = {key: json.dumps(getattr(spec, key)) for key in STREAM_KEYS}
        for key, value in wanted.items():
            if key in stored and stored[key] != value:
                self.close()
                what = "random draws" if key == "seed" else "tasks"
                raise SpecError(f"{self.directory} holds a sweep run with {key} = "
                                f"{stored[key]}, the spec says {value}: its {what} differ; "
                                "use another --out")
        self._check_layout(stored)
        # an older store without a robot (accepted above) is the default robot's
        robot = json.loads(stored.get("robot", json.dumps(DEFAULT_ROBOT)))
        if stored and robot != spec.robot:
            self.close()
            raise SpecError(f"{self.directory} holds a sweep of robot {robot!r}, this one's "
                            f"is {spec.robot!r} (the spec's robot, or --robot); use another "
                            "--out")
        wanted["robot"] = json.dumps(spec.robot)
        friction = json.loads(stored.get("friction", "0.5"))
        if stored and friction != spec.friction:
            self.close()
            raise SpecError(f"{self.directory} holds a sweep at friction {friction:g}, this "
                            f"one's is {spec.friction:g} (the spec's friction, or --friction); "
                            "use another --out")
        if spec.friction != 0.5:
            wanted["friction"] = json.dumps(spec.friction)
        sources = spec.sources()
        self._check_sources(stored, sources)
        wanted.update(sources)
        self._check_physics(stored)
        if "physics" in spec.engines:
            wanted["physics_model"] = json.dumps(PHYSICS_MODEL)
        with self._db:
            self._db.executemany("INSERT OR IGNORE INTO meta VALUES (?, ?)", wanted.items())
            self._db.execute("INSERT OR REPLACE INTO meta VALUES ('draw_layout', ?)",
                             (json.dumps(SWEEP_LAYOUT),))
            self._db.execute("INSERT OR REPLACE INTO meta VALUES ('last_spec', ?)",
                             (json.dumps(asdict(spec)),))

    def _check_physics(self, stored: dict[str, str]) -> None:
        """Refuse a store whose physics-engine cells another version's physics made
        (:data:`~kinegrasp_env.physics.simulators.PHYSICS_MODEL` not recorded, or another)."""
        made = self._db.execute("SELECT COUNT(*) FROM tasks WHERE engine = 'physics'")
        if made.fetchone()[0] and stored.get("physics_model") != json.dumps(PHYSICS_MODEL):
            self.close()
            raise SpecError(f"{self.directory} holds physics-engine cells of another "
                            "physics model (made by an older kinegrasp); use another --out")

    def _check_layout(self, stored: dict[str, str]) -> None:
        """Refuse a store whose draws were laid out otherwise (it is then marked
        :data:`SWEEP_LAYOUT`): a store of the default robot by an older kinegrasp (it records
        no robot) whose draws came in the spec's chunks (its chunk is not
        :data:`~kinegrasp_env.sampling.noise_model.STREAM_CHUNK`, whose chunks are the rows),
        or one that records another layout (a description robot's from before its rows came
        in chunks records none)."""
        if not stored:
            return
        if "robot" not in stored:
            if json.loads(stored.get("chunk", "null")) == STREAM_CHUNK:
                return  # its chunks of 250 are the rows of the run: the same draws
            self.close()
            raise SpecError(f"{self.directory} holds a sweep of the default robot whose "
                            "random draws came in the spec's chunks (made by an older "
                            "kinegrasp; every robot's draws are now rows of one run); use "
                            "another --out")
        layout = stored.get("draw_layout")
        if layout in (json.dumps(SWEEP_LAYOUT), json.dumps(DRAW_LAYOUT)):
            return
        self.close()
        raise SpecError(f"{self.directory} holds a sweep whose random draws are laid out "
                        f"otherwise ({'not recorded' if layout is None else layout}, now "
                        f"{SWEEP_LAYOUT!r}: made by an older kinegrasp); use another --out")

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

    def finished(self) -> dict[str, int]:
        """The stored tasks' draws, by key."""
        return dict(self._db.execute("SELECT key, size FROM tasks").fetchall())

    def add(self, task: SweepTask, result: dict) -> None:
        """Record a finished task (committed at once), in place of a stored one of the same
        key (a cell's last chunk grown with its ``samples``)."""
        with self._db:
            self._db.execute(
                f"INSERT OR REPLACE INTO tasks VALUES "
                f"({', '.join('?' * (13 + len(OUTCOMES)))})",
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
    statistics of :func:`kinegrasp_env.montecarlo.grasp_stats.summarize`, chunks merged in
    order)."""
    results = store.results()
    models = dict(spec.models)
    n_chunks = len(chunk_sizes(spec.samples, spec.chunk))
    nominal = nominal_qualities(spec)
    summary = []
    for obj, grasp, sigma, noise, engine in spec.cells():
        counts = np.zeros(len(OUTCOMES), dtype=np.int64)
        moments = StreamingMoments(1)
        for c in range(n_chunks):
            chunk_counts, chunk_moments = results[
                SweepTask(obj, grasp, sigma, noise, engine, c, 0, spec.seed,
                          robot=spec.robot).key]
            counts += chunk_counts
            moments.merge(chunk_moments)
        q_nominal = nominal[obj, grasp, nominal_closing(engine)]
        stats = grasp_stats(spec.grasp(obj, grasp),
                            cell_noise(sigma, noise, models.get(noise)), spec.seed, engine,
                            counts, moments, None, q_nominal=q_nominal)
        summary.append({
            **({} if spec.robot == DEFAULT_ROBOT else {"robot": spec.robot}),
            "object": obj, "grasp": grasp, "sigma": sigma, "noise": noise, "engine": engine,
            "p_fc": stats.p_fc, "p_fc_lo": stats.p_fc_ci[0], "p_fc_hi": stats.p_fc_ci[1],
            "q_mean": stats.q_mean, "q_std": stats.q_std, "q_skew": stats.q_skew,
            "q_nominal": stats.q_nominal, "samples": stats.samples, **stats.outcomes})
    return summary


def nominal_closing(engine: str) -> str:
    """The engine whose nominal closing gives a cell of ``engine`` its nominal Q: the physics
    engine its own (as ``evaluate`` takes each engine's own), the kinematic engines the
    reference's (the fast one closes as it does)."""
    return "physics" if engine == "physics" else "pybullet"


def nominal_qualities(spec: SweepSpec) -> dict[tuple[str, int, str], float]:
    """(object, grasp index, closing engine: :func:`nominal_closing`) -> the grasp's nominal
    Q at the spec's friction, by that engine's nominal closing."""
    from kinegrasp_env.montecarlo.evaluate import make_engine, nominal_robot_quality

    out = {}
    for o in spec.objects:
        for closing in dict.fromkeys(map(nominal_closing, spec.engines)):
            with make_engine(closing, spec.robot, o, friction=spec.friction) as engine:
                for g in spec.grasp_indices(o):
                    out[o, g, closing] = nominal_robot_quality(spec.grasp(o, g), engine)
    return out


def summary_csv(rows: list[dict]) -> str:
    """The summary CSV: :data:`SUMMARY_COLUMNS`, after a column ``robot`` when the rows
    are another robot's than the default."""
    columns = (("robot",) if rows and "robot" in rows[0] else ()) + SUMMARY_COLUMNS
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow(["" if isinstance(row[c], float) and math.isnan(row[c]) else
                         (repr(row[c]) if isinstance(row[c], float) else row[c])
                         for c in columns])
    return buffer.getvalue()


def summary_table(rows: list[dict]) -> str:
    """Console table of the summary (another robot's than the default: a first line naming
    it); the object and noise columns as wide as their longest entry."""
    head = [f"robot {rows[0]['robot']}"] if rows and "robot" in rows[0] else []
    obj = max([12, *(len(r["object"]) for r in rows)])
    noise = max([10, *(len(r["noise"]) for r in rows)])
    lines = [*head, f"{'object':<{obj}} {'grasp':>5} {'sigma':>7} {'noise':<{noise}} "
             f"{'engine':<8} {'P(FC)':>6} {'95% CI':>13} {'Q mean':>8} {'draws':>6}"]
    for r in rows:
        q = "-" if math.isnan(r["q_mean"]) else f"{r['q_mean']:.5f}"
        lines.append(f"{r['object']:<{obj}} {r['grasp']:>5} {r['sigma']:>7.4f} "
                     f"{r['noise']:<{noise}} {r['engine']:<8} {r['p_fc']:>6.3f} "
                     f"{r['p_fc_lo']:>6.3f}..{r['p_fc_hi']:<5.3f} {q:>8} {r['samples']:>6}")
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
        written.append(plot(sub, directory / name, title=f"robot {spec.robot}, {noise} noise, "
                                  f"{engine} engine, {spec.samples} draws per cell"))
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
        # a stored chunk of another size is a cell's last chunk before samples grew: again
        todo = [t for t in tasks if finished.get(t.key) != t.size]
        from kinegrasp_env.progress_bar import progress_bar

        bar = progress_bar(total=len(tasks), initial=len(tasks) - len(todo), desc="sweep",
                           unit="task", enabled=bool(progress))
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
