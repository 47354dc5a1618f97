"""Adaptive ranking (``kinegrasp rank --adaptive``) against its fixed-n budget: draws used and
the errors of what its table shows, over seeded repetitions, on candidate sets.

Sets (joint noise sigma 0.0133 rad, the ``rank`` default; fast engine; friction 0.5, 8 cone
edges; chunks of 250 draws, as ``kinegrasp rank --engine fast`` runs them):

* ``a``: the README's drill plan with variants, ``kinegrasp plan --object drill --count 4
  --seed 0 --variants 2`` (the file ``notebooks/candidates.json``): 12 candidates, 4 grasps
  in 3 arm configurations each.
  Budget 2000 draws per candidate (the README's ``rank``), top 6; ``a3``: the same set cut
  at top 3 (one outcome cache for both).
* ``b``: 10 null-space variants of the drill's shipped grasp 0 along the arm's analytic
  self-motion (:func:`elbow_variants`; the same contacts, 10 arm configurations, as
  ``reproduce fig10`` compares). Budget 1000 draws (``reproduce fig10``'s).
* ``c``, ``d``, ``e`` (``--sets c,d,e``): the same on the cube, the spray flask and the mug
  (the rest of ``reproduce fig10``'s default objects): the cost of a certified top k is set by
  the boundary's gap and its discordant draws, so one set alone says little of it.

Ground truth: 20,000 draws per candidate (seed :data:`GT_SEED`, not a repetition seed), its
P(FC) per candidate. Repetition s runs ``rank_adaptive`` exactly as ``kinegrasp rank FILE
--sigma 0.0133 --samples N --seed s --adaptive --top-k K --epsilon E --engine fast`` does
(the same evaluator calls on the same draws: ``rank``'s rows of the seed's streams in chunks
of 250 are these chunks' draws, compared count for count), and scores what its table
shows: the rows it marks ``top-k`` are false when one of them has a ground-truth P(FC) at
or below the truth's k-th best minus epsilon (epsilon 0: below it), the rows it marks
``rest`` in a run that did not separate when one of them is above the k-th best (they
claim to be out of the top k).
"label errors" counts the runs with a false label (the promise: at most delta); "first-k
errors" the runs whose first k rows, read as a top k whatever their labels, are false by the
same rule (what a reader who ignores the labels would take away). The ground truth's own
error: a paired difference of 20,000 draws has a standard error of sqrt(d / 20000), d its
discordance (0.002 at d = 8%).

Each draw's force-closure outcome is cached per (set, seed, candidate) under
``<cache>/bench_ranking`` (``--cache``), in a folder named after the engine's compiled sources
as well (``jit.source_key``: a change of the closing or quality kernels starts afresh instead
of serving outcomes the engine no longer gives), so a rerun, or the same script on another
version of the ranking code with the same engine (``PYTHONPATH=/old/checkout python
benchmarks/bench_ranking.py``), costs little: chunk c of seed s is the same draws whoever
asks for it (common random numbers), and what is measured is exactly what ``rank_adaptive``
asks for. Per-draw Q is not cached: the
runs' moments are empty, which changes neither the decisions nor the top k (they use P(FC)).

Usage: ``nice -n 10 python benchmarks/bench_ranking.py [--sets a,a3] [--reps 100]
[--epsilon 0.01] [--processes 2]``.

The figures of each set (the ground truth's order and boundary, draws against the fixed-n
budget, error counts and rates, seconds) also go to ``benchmarks/results/bench_ranking.json``
(``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import hashlib
import multiprocessing
import os
import sys
import time
from pathlib import Path

import numpy as np
from results_file import add_options, settings, write_result

SIGMA = 0.0133
CHUNK = 250
GT_DRAWS = 20_000
GT_SEED = 1000
FRICTION, NUM_EDGES, METHOD = 0.5, 8, "mc"
ROOT = Path(__file__).resolve().parents[1]
SETS = {
    "a": {"label": "README drill plan with variants", "samples": 2000, "top_k": 6},
    "a3": {"label": "README drill plan with variants, top 3", "samples": 2000, "top_k": 3,
           "base": "a"},
    "b": {"label": "fig10-style: drill grasp 0 in 10 arm configurations", "samples": 1000,
          "top_k": 3, "object": "drill"},
    # the other objects of ``reproduce fig10``'s default set, under b's settings (declared
    # before they were run; the ranking code untouched since): how the cost depends on the
    # boundary's gap, not only on the one set b
    **{key: {"label": f"fig10-style: {name} grasp 0 in 10 arm configurations",
             "samples": 1000, "top_k": 3, "object": name}
       for key, name in (("c", "cube"), ("d", "spray_flask"), ("e", "mug"))},
}


def elbow_variants(grasp, count: int) -> list:
    """Up to ``count`` configurations of the default robot's ``grasp`` at elbow angles spread
    over its self-motion (the analytic walk, every 5 degrees, the arm clear of the object),
    each kept when the reference engine closes it in force closure: ids ``<id>v<k>``."""
    from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.montecarlo.nominal import grasp_from_draw
    from kinegrasp_env.toolkit.elbow import ArmWalk

    walk = ArmWalk(grasp.object)
    try:
        feasible = sorted(walk.elbow_range(np.asarray(grasp.q0, dtype=float), np.deg2rad(5.0)),
                          key=lambda item: item[0])
    finally:
        walk.close()
    if not feasible:
        return []
    engine = make_engine("pybullet", grasp.robot, grasp.object)
    out = []
    try:
        pick = np.unique(np.round(np.linspace(0, len(feasible) - 1, count)).astype(int))
        for j, index in enumerate(pick):
            psi, q = feasible[index]
            draw = engine.run(q[None])
            if draw.outcome[0] == FORCE_CLOSURE:
                out.append(grasp_from_draw(draw, grasp.object, q, grasp.palm_pose,
                                           grasp_id=f"{grasp.id}v{j + 1}",
                                           meta={"elbow_angle": psi, "variant_of": grasp.id}))
    finally:
        engine.close()
    return out


def candidates(name: str) -> tuple[list, str]:
    """The grasps of set ``name`` and a digest of their configurations (the cache key)."""
    from kinegrasp_env.world.grasps import load_grasps, shipped_grasps

    if SETS[name].get("base", name) == "a":
        grasps = load_grasps(ROOT / "notebooks" / "candidates.json")
    else:
        target = SETS[name]["object"]
        grasps = elbow_variants(shipped_grasps(target)[0], 10)
    digest = hashlib.sha256()
    for grasp in grasps:
        digest.update(grasp.id.encode() + np.round(grasp.q0, 12).tobytes())
    return grasps, digest.hexdigest()[:12]


def outcomes(grasp, seed: int, first: int, count: int, processes: int = 1) -> np.ndarray:
    """Force-closure outcome (draws,) bool of chunks ``first .. first + count - 1`` (rows
    ``first * CHUNK ..`` of the seed's run), each chunk a task of ``processes`` workers whose
    engines are built once per process."""
    from kinegrasp_env.montecarlo.chunks import RobotChunk, chunked_draws
    from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
    from kinegrasp_env.montecarlo.execution import LocalExecutor

    assert NUM_EDGES == 8  # the engines' friction cone (chunked runs take its default)
    task = RobotChunk(grasp.robot, grasp.object, "fast", tuple(np.asarray(grasp.q0, float)),
                      SIGMA, "gaussian", seed, first * CHUNK, count * CHUNK,
                      friction=FRICTION, method=METHOD)
    with LocalExecutor(processes) as executor:
        draws = chunked_draws(task, count * CHUNK, executor, chunk=CHUNK)
    return draws.outcome == FORCE_CLOSURE


def save_bits(path: Path, arrays: list[np.ndarray]) -> None:
    """Per-candidate bool arrays, packed, written atomically."""
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp.npz")
    np.savez(tmp, **{f"c{i}": np.packbits(a) for i, a in enumerate(arrays)},
             lengths=np.array([a.size for a in arrays]))
    os.replace(tmp, path)


def load_bits(path: Path, n: int) -> list[np.ndarray]:
    if not path.exists():
        return [np.zeros(0, dtype=bool) for _ in range(n)]
    with np.load(path) as data:
        return [np.unpackbits(data[f"c{i}"])[:int(data["lengths"][i])].astype(bool)
                for i in range(n)]


def ground_truth(grasps, folder: Path, processes: int) -> np.ndarray:
    """(candidates, GT_DRAWS) bool outcomes at :data:`GT_SEED`, cached."""
    path = folder / "ground_truth.npz"
    have = load_bits(path, len(grasps))
    if any(a.size != GT_DRAWS for a in have):
        have = [outcomes(g, GT_SEED, 0, GT_DRAWS // CHUNK, processes) for g in grasps]
        save_bits(path, have)
    return np.array(have)


def run_seed(task: tuple) -> dict:
    """One repetition: ``rank_adaptive`` on seed ``seed`` with cached per-draw outcomes."""
    grasps, folder, seed, samples, top_k, delta, epsilon, fixed = task
    from kinegrasp_env.sampling.stats import StreamingMoments
    from kinegrasp_env.toolkit import adaptive_ranking as ranking

    paired = hasattr(ranking, "PairedEvaluator")  # this version pairs per-draw outcomes
    path = Path(folder) / f"seed{seed}.npz"
    store = load_bits(path, len(grasps))
    fresh = 0

    def evaluator(index: int, first: int, count: int):
        nonlocal fresh
        have = store[index].size // CHUNK
        if have < first + count:
            store[index] = np.concatenate(
                [store[index], outcomes(grasps[index], seed, have, first + count - have)])
            fresh += (first + count - have) * CHUNK
        out = store[index][first * CHUNK:(first + count) * CHUNK]
        value = int(out.sum()), out.size, StreamingMoments(1)
        return (*value, out) if paired else value

    max_chunks = samples // CHUNK
    report = ranking.rank_adaptive(len(grasps), evaluator, max_chunks, CHUNK, top_k=top_k,
                                   delta=delta, epsilon=epsilon)
    fixed_top = None
    if fixed:  # the fixed-n run's top k: every candidate's whole budget, best P(FC) first
        p_hat = [evaluator(i, 0, max_chunks)[0] for i in range(len(grasps))]
        fixed_top = sorted(np.argsort(-np.array(p_hat), kind="stable")[:top_k].tolist())
    if fresh:
        save_bits(path, store)
    shown = [r.index for r in report.results]
    return {"seed": seed, "draws": report.draws, "fixed": report.fixed_draws,
            "first": shown[:top_k], "separated": report.separated, "fresh": fresh,
            "marked": [i for i, label in zip(shown, report.certified, strict=True)
                       if label == ranking.TOP],
            "rest": [i for i, label in zip(shown, report.certified, strict=True)
                     if label == ranking.REST],
            "paired": paired, "fixed_top": fixed_top}


def top_is_false(p: np.ndarray, members: list[int], top_k: int, epsilon: float) -> bool:
    """A claimed top k (or part of one) against the ground truth's P(FC) ``p`` (n,): a
    member at or below the k-th best minus epsilon (epsilon 0: below the k-th best)."""
    kth = np.sort(p)[::-1][top_k - 1]
    return any(p[i] <= kth - epsilon if epsilon > 0 else p[i] < kth for i in members)


def labels_are_false(row: dict, p: np.ndarray, top_k: int, epsilon: float) -> bool:
    """Whether a run's table shows a false label: its ``top-k`` rows (:func:`top_is_false`),
    or, unseparated, a ``rest`` row above the k-th best (claimed out of the top k)."""
    kth = np.sort(p)[::-1][top_k - 1]
    rest_false = not row["separated"] and any(p[i] > kth for i in row["rest"])
    return top_is_false(p, row["marked"], top_k, epsilon) or rest_false


def truth_figures(gt: np.ndarray, ids: list[str], top_k: int) -> dict:
    """The ground truth's order (id, P(FC)) and its top-k boundary pair (gap, discordance)."""
    p = gt.mean(axis=1)
    rank = np.argsort(-p, kind="stable")
    i, j = rank[top_k - 1], rank[top_k]
    return {"order": [{"id": ids[r], "p_fc": float(p[r])} for r in rank],
            "boundary": [ids[i], ids[j]], "boundary_gap": float(p[i] - p[j]),
            "boundary_discordant": float(np.mean(gt[i] != gt[j]))}


def truth_line(gt: np.ndarray, ids: list[str], top_k: int) -> str:
    """The ground truth's order and its top-k boundary pair (gap, discordance)."""
    t = truth_figures(gt, ids, top_k)
    order = ", ".join(f"{r['id']} {r['p_fc']:.4f}" for r in t["order"])
    first, second = t["boundary"]
    return (f"  ground truth ({GT_DRAWS} draws, seed {GT_SEED}): {order}\n"
            f"  top-{top_k} boundary {first} | {second}: gap {t['boundary_gap']:.4f}, "
            f"discordant on {t['boundary_discordant']:.1%} of the draws")


def summary_figures(rows: list[dict], p: np.ndarray, samples: int, top_k: int,
                    epsilon: float) -> dict:
    """The repetitions' figures of one set (see :func:`summary`)."""
    from kinegrasp_env.sampling.stats import wilson_interval

    used = np.array([r["draws"] / r["fixed"] for r in rows])
    errors = sum(labels_are_false(r, p, top_k, epsilon) for r in rows)
    lo, hi = wilson_interval(errors, len(rows))
    fixed_errors = None
    if rows[0]["fixed_top"] is not None:
        fixed_errors = sum(top_is_false(p, r["fixed_top"], top_k, epsilon) for r in rows)
    return {"candidates": len(p), "top_k": top_k, "samples": samples,
            "fixed_n": len(p) * samples, "mode": "paired" if rows[0]["paired"] else "unpaired",
            "reps": len(rows), "draws_over_fixed_n_mean": float(used.mean()),
            "draws_over_fixed_n_max": float(used.max()),
            "separated": sum(r["separated"] for r in rows), "label_errors": errors,
            "label_error_rate": errors / len(rows), "label_error_wilson_lo": lo,
            "label_error_wilson_hi": hi,
            "first_k_errors": sum(top_is_false(p, r["first"], top_k, epsilon) for r in rows),
            "fixed_n_top_k_errors": fixed_errors,
            "draws_computed": sum(r["fresh"] for r in rows)}


def summary(name: str, rows: list[dict], p: np.ndarray, samples: int, top_k: int,
            delta: float, epsilon: float, seconds: float) -> str:
    f = summary_figures(rows, p, samples, top_k, epsilon)
    reps = f["reps"]
    fixed = ("" if f["fixed_n_top_k_errors"] is None
             else f"; fixed-n top-k errors {f['fixed_n_top_k_errors']}/{reps}")
    return (f"set {name} ({f['candidates']} candidates, top {top_k}, {samples} draws each, "
            f"fixed n {f['fixed_n']}, delta {delta}, epsilon {epsilon}, {f['mode']}): "
            f"draws/fixed-n mean {f['draws_over_fixed_n_mean']:.3f} max "
            f"{f['draws_over_fixed_n_max']:.3f}; separated {f['separated']}/{reps}; "
            f"label errors {f['label_errors']}/{reps} = {f['label_error_rate']:.3f} (Wilson 95% "
            f"{f['label_error_wilson_lo']:.3f}..{f['label_error_wilson_hi']:.3f}); first-k "
            f"errors {f['first_k_errors']}/{reps}{fixed}; "
            f"{seconds:.0f} s, {f['draws_computed']} draws computed")


def bench_set(name: str, args, pool) -> dict:
    """Print one set's lines; return its figures (the ground truth's order as well)."""
    from kinegrasp_env.jit import source_key
    from kinegrasp_env.paths import cache_root
    from kinegrasp_env.toolkit import adaptive_ranking as ranking

    spec = SETS[name]
    samples = args.samples or spec["samples"]
    top_k = args.top_k or spec["top_k"]
    start = time.perf_counter()
    grasps, digest = candidates(name)
    folder = Path(args.cache or cache_root() / "bench_ranking") / \
        f"{spec.get('base', name)}_{digest}_sigma{SIGMA}_chunk{CHUNK}_engine{source_key()}"
    folder.mkdir(parents=True, exist_ok=True)
    gt = ground_truth(grasps, folder, args.processes)
    ids = [g.id for g in grasps]
    p = gt.mean(axis=1)
    kth = np.sort(p)[::-1][top_k - 1]
    print(f"set {name}: {spec['label']} ({ranking.__file__})")
    print(truth_line(gt, ids, top_k))
    acceptable = [ids[i] for i in np.argsort(-p, kind="stable")
                  if (p[i] > kth - args.epsilon if args.epsilon > 0 else p[i] >= kth)]
    print(f"  acceptable in a top {top_k} at epsilon {args.epsilon}: "
          + ", ".join(acceptable), flush=True)
    tasks = [(grasps, str(folder), seed, samples, top_k, args.delta, args.epsilon,
              args.fixed_n_errors) for seed in range(args.reps)]
    rows = list(pool.imap(run_seed, tasks)) if pool else [run_seed(t) for t in tasks]
    seconds = time.perf_counter() - start
    print(summary(name, rows, p, samples, top_k, args.delta, args.epsilon, seconds),
          flush=True)
    truth = truth_figures(gt, ids, top_k)
    return {"set": name, "label": spec["label"], "delta": args.delta, "epsilon": args.epsilon,
            **summary_figures(rows, p, samples, top_k, args.epsilon), "wall_s": seconds,
            "truth_boundary": " | ".join(truth["boundary"]),
            "truth_boundary_gap": truth["boundary_gap"],
            "truth_boundary_discordant": truth["boundary_discordant"],
            "acceptable": ", ".join(acceptable),
            "truth_order": ", ".join(f"{r['id']} {r['p_fc']:.4f}" for r in truth["order"])}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sets", default="a,a3,b", help="comma-separated: a (top 6), a3 (top "
                        "3), b; c, d, e: set b on the cube, spray flask and mug")
    parser.add_argument("--reps", type=int, default=100, help="seeds 0 .. reps-1")
    parser.add_argument("--processes", type=int, default=2, help="repetitions run at once")
    parser.add_argument("--samples", type=int, help="per-candidate budget (default: the set's)")
    parser.add_argument("--top-k", type=int, help="default: the set's")
    parser.add_argument("--delta", type=float, default=0.05)
    parser.add_argument("--epsilon", type=float, default=0.01,
                        help="indifference zone (kinegrasp rank --epsilon; 0: exact top k)")
    parser.add_argument("--cache", help="cache folder (default: <cache_root>/bench_ranking)")
    parser.add_argument("--fixed-n-errors", action="store_true",
                        help="also the fixed-n run's top-k errors (draws every candidate's "
                        "whole budget: slow where adaptive ranking saves much)")
    add_options(parser, __file__)
    args = parser.parse_args(argv)
    names = args.sets.split(",")
    if unknown := [n for n in names if n not in SETS]:
        parser.error(f"unknown set(s) {unknown}; choose from {sorted(SETS)}")
    print(f"bench_ranking: {args.reps} repetitions per set, {args.processes} processes, "
          f"python {sys.version.split()[0]}", flush=True)
    context = multiprocessing.get_context("spawn")
    pool = context.Pool(args.processes) if args.processes > 1 else None
    try:
        sets = [bench_set(name, args, pool) for name in names]
    finally:
        if pool:
            pool.close()
            pool.join()
    if not args.no_json:
        write_result(__file__, {"truth_draws": GT_DRAWS, "truth_seed": GT_SEED, "sigma": SIGMA,
                                "chunk": CHUNK, "sets": sets, "settings": settings(args)},
                     args.json_out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
