"""Ferrari-Canny cost as a function of the cone edges m: where each exact path pays off.

Run: ``python benchmarks/bench_quality_edges.py [--edges 3 4 6 8 ...] [--batch 400]
[--contacts 6] [--bound-edges 8 16 24 32 48]``. Single-threaded (BLAS threads pinned to 1);
every time is CPU time of this process (``time.process_time``), which on an idle machine is
the wall time and on a shared one is not inflated by the other processes.

1. Three contacts (points on a sphere, normals tilted ~0.3 rad, torque scale 1 / radius),
   per m, each exact path as the library runs it, including the qhull fallback for the
   grasps it cannot certify:

   * tables: :func:`~kinegrasp_env.quality.three_contacts.epsilon_three_contacts`;
   * expansion: :func:`~kinegrasp_env.quality.expansion.epsilon_epa_batch` (only while
     3 m <= ``expansion.MAX_POINTS``);
   * qhull: one ``scipy.spatial.ConvexHull`` per grasp (the reference).

   Each m runs in a fresh process. "build" is the one-off cost of the tables' constant
   tables (their first call in a process), "MB" the peak of the memory numpy allocates for
   the build plus one batched call (tracemalloc). "single" is the median over 7 grasps of a
   call with one grasp (us), "batch" the cost per grasp of one call with ``--batch`` grasps
   (us; qhull on the first 20). The paths are timed in turns, each figure the fastest of 3
   turns, so a shared machine's load drifts over all paths alike.
2. qhull on ``--contacts`` contacts per m (the path every grasp can fall back to): median and
   largest single-grasp time over 5 grasps, and the growth of the peak resident memory (MB;
   qhull allocates outside numpy), each m in a fresh process.
   ``quality.wrenches.MAX_EDGES`` is chosen from this table.
3. The L-infinity hull (``norm="linf"``: qhull of the (m + 1)^k Minkowski-sum points) per
   ``--linf`` pair k x m, likewise; ``qhull_quality.LINF_MAX_POINTS`` is chosen from this table.

The three tables (seconds, MB, certified shares) also go to
``benchmarks/results/bench_quality_edges.json`` (``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from results_file import add_options, settings, write_result  # noqa: E402
from scipy.spatial import ConvexHull, QhullError  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from quality_cases import sphere_contacts  # noqa: E402

from kinegrasp_env.quality.expansion import MAX_POINTS, epsilon_epa_batch  # noqa: E402
from kinegrasp_env.quality.three_contacts import (  # noqa: E402
    candidate_tables,
    epsilon_three_contacts,
)
from kinegrasp_env.quality.wrenches import edge_wrenches  # noqa: E402

RADIUS = 0.05
QHULL_SAMPLE = 20
SINGLE_GRASPS = 7
TURNS = 3


def contact_wrenches(k: int, m: int, batch: int, seed: int) -> np.ndarray:
    """(batch, k m, 6) edge wrenches of random sphere grasps (unchecked: any m)."""
    pts, nrm = sphere_contacts(np.random.default_rng(seed), batch, k, radius=RADIUS,
                               jitter=0.3)
    scale = np.full(batch, 1.0 / RADIUS)
    return np.ascontiguousarray(edge_wrenches(pts, nrm, 0.5, m, scale, np.zeros((batch, 3))))


def qhull_q(w: np.ndarray) -> float:
    """Q of one wrench set (N, 6) by scipy's ConvexHull (0 when qhull declines the set)."""
    try:
        return max(0.0, -float(ConvexHull(w).equations[:, -1].max()))
    except QhullError:
        return 0.0


def timed(path: str, w: np.ndarray, m: int) -> tuple[float, float]:
    """(seconds, certified fraction) of one call of ``path`` on wrench sets w (B, N, 6),
    the qhull fallback of the rows it cannot certify included."""
    start = time.process_time()
    if path == "qhull":
        for x in w:
            qhull_q(x)
        return time.process_time() - start, 1.0
    run = epsilon_three_contacts if path == "tables" else epsilon_epa_batch
    _, certified = run(w, m) if path == "tables" else run(w)
    for row in np.flatnonzero(~certified):
        qhull_q(w[row])
    return time.process_time() - start, float(certified.mean())


def three_contact_worker(m: int, batch: int, seed: int) -> dict:
    """Section 1 for one m, in this (fresh) process."""
    small = contact_wrenches(4, 3, 1, 99)
    epsilon_epa_batch(small)  # load the compiled kernel and qhull first
    qhull_q(small[0])
    w = contact_wrenches(3, m, batch, seed)
    start = time.process_time()
    candidate_tables(m)
    out = {"build": time.process_time() - start}
    candidate_tables.cache_clear()
    tracemalloc.start()  # again, traced (tracing slows the build down)
    candidate_tables(m)
    epsilon_three_contacts(w, m)
    out["mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    paths = ["tables", "qhull"] + (["expansion"] if 3 * m <= MAX_POINTS else [])
    best = {p: {"single": [np.inf] * SINGLE_GRASPS, "batch": np.inf} for p in paths}
    for _ in range(TURNS):
        for path in paths:
            for i in range(SINGLE_GRASPS):
                t, _ = timed(path, w[i:i + 1], m)
                best[path]["single"][i] = min(best[path]["single"][i], t)
            n = min(batch, QHULL_SAMPLE) if path == "qhull" else batch
            t, cert = timed(path, w[:n], m)
            best[path]["batch"] = min(best[path]["batch"], t / n)
            best[path]["cert"] = cert
    for path, res in best.items():
        out[path] = {"single": float(np.median(res["single"])), "batch": res["batch"],
                     "cert": res["cert"]}
    return out


def minkowski_points(w: np.ndarray, k: int) -> np.ndarray:
    """(m + 1)^k points: sums of one of {0, edge wrenches} per contact (w: (k m, 6))."""
    total = np.zeros((1, 6))
    for block in w.reshape(k, -1, 6):
        options = np.vstack([np.zeros((1, 6)), block])
        total = (total[:, None, :] + options[None, :, :]).reshape(-1, 6)
    return total


def qhull_worker(k: int, m: int, seed: int, linf: int = 0) -> dict:
    """Sections 2 and 3 for one (k, m), in this (fresh) process."""
    small = contact_wrenches(4, 3, 1, 99)
    qhull_q(small[0])
    w = contact_wrenches(k, m, 5, seed)
    if linf:
        w = np.stack([minkowski_points(x, k) for x in w])
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    times = []
    for x in w:
        start = time.process_time()
        qhull_q(x)
        times.append(time.process_time() - start)
    grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base  # KiB on Linux
    return {"median": float(np.median(times)), "max": max(times), "mb": grown / 1024}


def in_fresh_process(task: str, *args: int) -> dict:
    done = subprocess.run([sys.executable, __file__, "--worker", task, *map(str, args)],
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        return {"error": (done.stderr.strip().splitlines() or ["died"])[-1]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def three_contact_table(edges: list[int], batch: int, seed: int) -> list[dict]:
    print(f"1. three contacts, batch {batch}: us per grasp (single call / batched)")
    print(f"{'m':>3} | {'tables: build s':>15} {'MB':>5} {'single':>7} {'batch':>7} | "
          f"{'expansion: single':>17} {'batch':>7} {'cert':>5} | {'qhull: single':>13} "
          f"{'batch':>7} | fastest batched")
    rows = []
    for m in edges:
        res = in_fresh_process("three", m, batch, seed)
        if "error" in res:
            print(f"{m:3d} | failed: {res['error']}", flush=True)
            rows.append({"edges": m, "error": res["error"]})
            continue
        tab, hull = res["tables"], res["qhull"]
        if "expansion" in res:
            exp = res["expansion"]
            exp_text = (f"{exp['single'] * 1e6:17.0f} {exp['batch'] * 1e6:7.0f} "
                        f"{exp['cert']:5.0%}")
        else:
            exp_text = f"{'(3m > ' + str(MAX_POINTS) + ')':>17} {'-':>7} {'-':>5}"
        paths = [p for p in ("tables", "expansion", "qhull") if p in res]
        fastest = min(paths, key=lambda p: res[p]["batch"])
        print(f"{m:3d} | {res['build']:15.2f} {res['mb']:5.0f} {tab['single'] * 1e6:7.0f} "
              f"{tab['batch'] * 1e6:7.0f} | {exp_text} | {hull['single'] * 1e6:13.0f} "
              f"{hull['batch'] * 1e6:7.0f} | {fastest}", flush=True)
        row = {"edges": m, "tables_build_s": res["build"], "tables_mb": res["mb"]}
        for path in paths:
            row |= {f"{path}_single_s": res[path]["single"],
                    f"{path}_batch_s_per_grasp": res[path]["batch"]}
            if path == "expansion":
                row["expansion_certified"] = res[path]["cert"]
        rows.append({**row, "fastest_batched": fastest})
    return rows


def qhull_bound_table(k: int, edges: list[int], seed: int) -> list[dict]:
    print(f"\n2. qhull on {k} contacts: one grasp per call, 5 grasps")
    print(f"{'m':>3} {'points':>6} | {'median ms':>9} {'max ms':>9} | {'peak MB':>7}")
    rows = []
    for m in edges:
        res = in_fresh_process("qhull", k, m, seed)
        if "error" in res:
            print(f"{m:3d} {k * m:6d} | failed: {res['error']}", flush=True)
            rows.append({"contacts": k, "edges": m, "points": k * m, "error": res["error"]})
            continue
        print(f"{m:3d} {k * m:6d} | {res['median'] * 1e3:9.1f} {res['max'] * 1e3:9.1f} | "
              f"{res['mb']:7.0f}", flush=True)
        rows.append({"contacts": k, "edges": m, "points": k * m, "median_s": res["median"],
                     "max_s": res["max"], "peak_mb": res["mb"]})
    return rows


def linf_table(pairs: list[str], seed: int) -> list[dict]:
    print("\n3. L-infinity hull (qhull of the Minkowski sum): one grasp per call, 5 grasps")
    print(f"{'k x m':>6} {'points':>6} | {'median ms':>9} {'max ms':>9} | {'peak MB':>7}")
    rows = []
    for pair in pairs:
        k, m = (int(x) for x in pair.split("x"))
        row = {"pair": pair, "contacts": k, "edges": m, "points": (m + 1) ** k}
        res = in_fresh_process("qhull", k, m, seed, 1)
        if "error" in res:
            print(f"{pair:>6} {(m + 1) ** k:6d} | failed: {res['error']}", flush=True)
            rows.append({**row, "error": res["error"]})
            continue
        print(f"{pair:>6} {(m + 1) ** k:6d} | {res['median'] * 1e3:9.1f} "
              f"{res['max'] * 1e3:9.1f} | {res['mb']:7.0f}", flush=True)
        rows.append({**row, "median_s": res["median"], "max_s": res["max"],
                     "peak_mb": res["mb"]})
    return rows


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--worker":
        task, args = sys.argv[2], [int(a) for a in sys.argv[3:]]
        run = three_contact_worker if task == "three" else qhull_worker
        print(json.dumps(run(*args)))
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--edges", type=int, nargs="+",
                        default=[3, 4, 6, 8, 10, 12, 14, 16, 20, 24, 32])
    parser.add_argument("--batch", type=int, default=400)
    parser.add_argument("--contacts", type=int, default=6)
    parser.add_argument("--bound-edges", type=int, nargs="+",
                        default=[8, 12, 16, 20, 24, 28, 32, 40, 48])
    parser.add_argument("--linf", nargs="+", default=["3x4", "3x8", "3x10", "4x5", "3x12",
                                                      "6x3", "3x16"])
    parser.add_argument("--seed", type=int, default=0)
    add_options(parser, __file__)
    args = parser.parse_args()
    record = {"three_contacts": three_contact_table(args.edges, args.batch, args.seed),
              "qhull": qhull_bound_table(args.contacts, args.bound_edges, args.seed),
              "linf": linf_table(args.linf, args.seed)}
    if not args.no_json:
        write_result(__file__, {**record, "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
