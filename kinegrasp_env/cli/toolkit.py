"""Toolkit commands: ``plan`` (grasp planning), ``rank`` (candidates by robustness, resumable) and
``sweep`` (a grid of evaluations on a process pool or Ray).
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path

from kinegrasp_env.cli.common import (
    CLIError,
    add_execution_args,
    add_noise_args,
    engine_name,
    executor_from,
    noise_from,
    parse_seed,
    positive_int,
)
from kinegrasp_env.sampling.stats import StreamingMoments
from kinegrasp_env.toolkit.ranking import (
    CRITERIA,
    CandidateResult,
    order,
    rank_adaptive,
    rank_fixed,
)
from kinegrasp_env.world.grasps import load_grasps, save_grasps, write_atomic

CSV_COLUMNS = ("id", "p_fc", "p_fc_lo", "p_fc_hi", "q_mean", "q_std", "q_skew", "q_nominal",
               "error", "samples")
CHUNK = 250


def cmd_plan(args) -> int:
    from kinegrasp_env.toolkit.planner import GraspPlanner

    count = positive_int(args.count, "--count")
    variants = int(args.variants)
    if variants < 0:
        raise CLIError(f"--variants must be >= 0, got {variants}")
    budget = float(args.time_budget) if args.time_budget else None
    planner = GraspPlanner(args.object)
    try:
        grasps = planner.plan(count, seed=parse_seed(args.seed), time_budget=budget,
                              max_attempts=int(args.max_attempts) if args.max_attempts else None,
                              progress=True)
        if not grasps:
            raise CLIError(f"no force-closure grasp of {args.object} found within the budget; "
                           "nothing written")
        out = list(grasps)
        for grasp in grasps if variants else []:
            out += planner.variants(grasp, variants)
    finally:
        planner.close()
    save_grasps(out, args.out, planner_seed=parse_seed(args.seed))
    print(f"{len(grasps)} grasps ({len(out) - len(grasps)} null-space variants) of {args.object}"
          f" written to {args.out}")
    return 0


def _moments_to_json(m: StreamingMoments | None) -> dict | None:
    if m is None:
        return None
    return {"n": m.n, "mean": m.mean.tolist(), "m2": m.m2.tolist(), "m3": m.m3.tolist()}


def _moments_from_json(data: dict | None) -> StreamingMoments | None:
    if data is None:
        return None
    return StreamingMoments.from_state(data["n"], data["mean"], data["m2"], data["m3"])


def _fmt(value: float) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else \
        f"{value:.6g}"


def _fixed(value: float) -> str:
    """Five decimals for the console table ('-' where undefined)."""
    return "-" if value is None or math.isnan(value) else f"{value:.5f}"


def cmd_rank(args) -> int:
    from kinegrasp_env.montecarlo import evaluate

    try:
        grasps = load_grasps(args.candidates)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    if not grasps:
        raise CLIError(f"{args.candidates}: the file holds no grasps")
    noise, sigma, samples, seed = noise_from(args)
    if args.criterion not in CRITERIA:
        raise CLIError(f"--criterion must be one of {', '.join(CRITERIA)}")
    engine = engine_name(args.engine)
    chunk = min(CHUNK, samples)
    layout = evaluate.chunk_sizes(samples, chunk)

    def evaluator(index: int, first: int, count: int):
        counts, moments, _ = evaluate.run_chunks(
            grasps[index], noise, seed, sizes=layout[first:first + count], first_chunk=first,
            engine=engine, executor=executor)
        return int(counts[evaluate.FORCE_CLOSURE]), int(counts.sum()), moments

    out = Path(args.out)
    partial = out.with_name(out.name + ".partial.jsonl")
    settings = {"candidates": str(Path(args.candidates).resolve()), "sigma": sigma,
                "noise": noise.kind, "samples": samples, "seed": seed,
                "ids": [g.id for g in grasps]}
    top_k = positive_int(args.top_k, "--top-k") if args.adaptive else 0
    if args.adaptive and top_k >= len(grasps):
        raise CLIError(f"--top-k must be below the number of candidates ({len(grasps)})")
    with executor_from(args) as executor:
        results = _rank(args, grasps, evaluator, layout, chunk, top_k, partial, settings)
    _write_ranking(grasps, results, out, partial)
    return 0


def _rank(args, grasps, evaluator, layout, chunk, top_k, partial: Path,
          settings: dict) -> list[CandidateResult]:
    """Fixed-n (resumable from ``partial``) or adaptive ranking, best first."""
    from tqdm import tqdm

    bar = tqdm(total=len(grasps), desc="ranking", unit="grasp", file=sys.stderr, disable=None)
    if args.adaptive:
        report = rank_adaptive(len(grasps), evaluator, len(layout), chunk, top_k=top_k,
                               criterion=args.criterion,
                               progress=lambda r, n: bar.set_postfix_str(f"round {r}/{n}"))
        results = report.results
        print(f"adaptive: {report.draws} draws against {report.fixed_draws} for fixed n "
              f"({report.draws / report.fixed_draws:.0%}); top {top_k} "
              f"{'separated' if report.separated else 'NOT separated'} after {report.rounds} "
              "rounds", file=sys.stderr)
    else:
        done = _read_partial(partial, settings)
        with partial.open("a") as log:
            if not done:
                log.write(json.dumps({"settings": settings}) + "\n")

            def record(index: int) -> None:
                bar.update(1)
                if index in done:
                    return
                r = results_so_far[index]
                log.write(json.dumps({"index": index, "successes": r.successes,
                                      "trials": r.trials, "chunks": r.chunks,
                                      "moments": _moments_to_json(r.moments)}) + "\n")
                log.flush()

            results_so_far: dict[int, CandidateResult] = {}

            def tracked(index: int, first: int, count: int):
                value = evaluator(index, first, count)
                result = CandidateResult(index)
                result.add(*value, count)
                results_so_far[index] = result
                return value

            results = order(rank_fixed(len(grasps), tracked, len(layout), progress=record,
                                       done=done), args.criterion)
    bar.close()
    return results


def _write_ranking(grasps, results: list[CandidateResult], out: Path, partial: Path) -> None:
    """The ranking as CSV (atomically), then as a console table."""
    rows = []
    for r in results:
        g = grasps[r.index]
        lo, hi = r.interval()
        mean, std, skew = r.q_stats()
        rows.append({"id": g.id, "p_fc": r.p_fc, "p_fc_lo": lo, "p_fc_hi": hi, "q_mean": mean,
                     "q_std": std, "q_skew": skew, "q_nominal": g.q_nominal,
                     "error": g.q_nominal - mean if not math.isnan(mean) else math.nan,
                     "samples": r.trials})
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for row in rows:
        writer.writerow([row["id"], *(_fmt(row[c]) for c in CSV_COLUMNS[1:-1]), row["samples"]])
    write_atomic(out, buffer.getvalue())
    if partial.exists():
        partial.unlink()
    print(f"{'rank':>4} {'id':>8} {'P(FC)':>7} {'95% CI':>15} {'Q mean':>9} {'Q nominal':>9} "
          f"{'draws':>6}")
    for i, row in enumerate(rows, 1):
        print(f"{i:>4} {row['id']:>8} {row['p_fc']:>7.3f} "
              f"{row['p_fc_lo']:>7.3f}..{row['p_fc_hi']:<6.3f} {_fixed(row['q_mean']):>9} "
              f"{row['q_nominal']:>9.5f} {row['samples']:>6}")
    print(f"written to {out}")


def cmd_sweep(args) -> int:
    from kinegrasp_env.montecarlo.sweep import SweepSpec, run_sweep, summary_table
    from kinegrasp_env.toolkit.plots import plot_sweep

    spec = SweepSpec.from_file(args.spec)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CLIError(f"--out {out} exists and is not a folder")
    with executor_from(args) as executor:
        print(f"sweep: {len(spec.cells())} cells x {spec.samples} draws on "
              f"{executor.description}", file=sys.stderr)
        rows, ran, skipped = run_sweep(spec, out, executor, plot=plot_sweep)
    print(summary_table(rows), end="")
    print(f"{ran} tasks run, {skipped} found finished in {out / 'results.sqlite'}; "
          f"written: {out}/summary.csv, summary.txt, pfc_vs_sigma_<noise>_<engine>.png")
    return 0


def _read_partial(path: Path, settings: dict) -> dict[int, CandidateResult]:
    """Finished candidates of an interrupted run with the same settings (else start over)."""
    if not path.exists():
        return {}
    lines = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    if not lines or lines[0].get("settings") != settings:
        path.unlink()
        return {}
    done = {}
    for item in lines[1:]:
        r = CandidateResult(int(item["index"]), int(item["successes"]), int(item["trials"]),
                            int(item["chunks"]), _moments_from_json(item["moments"]))
        done[r.index] = r
    print(f"resuming: {len(done)} candidates already ranked in {path}", file=sys.stderr)
    return done


def add_commands(sub) -> None:
    """Register ``plan``, ``rank`` and ``sweep``."""
    p = sub.add_parser("plan", help="plan force-closure grasps of an object")
    p.add_argument("--object", default="drill")
    p.add_argument("--count", default="20")
    p.add_argument("--seed", default="0")
    p.add_argument("--out", default="grasps.json")
    p.add_argument("--variants", default="0",
                   help="null-space variants per grasp (same palm pose, other elbow angles)")
    p.add_argument("--time-budget", help="seconds at most")
    p.add_argument("--max-attempts", help="palm poses to try at most")
    p.set_defaults(func=cmd_plan)

    p = sub.add_parser("rank", help="rank candidate grasps by robustness under joint noise")
    p.add_argument("candidates", help="grasp file (from `kinegrasp plan`)")
    add_noise_args(p, 0.0133)
    p.set_defaults(samples="2000")
    p.add_argument("--criterion", default="pfc", help="pfc, q_mean, pfc_lcb or weighted")
    p.add_argument("--adaptive", action="store_true",
                   help="successive elimination: stop when the top k is separated")
    p.add_argument("--top-k", default="3")
    add_execution_args(p, 1)
    p.add_argument("--engine", default="pybullet", help="pybullet (reference) or fast")
    p.add_argument("--out", default="ranked.csv")
    p.set_defaults(func=cmd_rank)

    p = sub.add_parser("sweep", help="a grid of evaluations (objects x grasps x sigmas x noise "
                       "x engines), resumable, on a process pool or Ray")
    p.add_argument("spec", help="YAML file with objects, grasps, sigmas, noise, engines, "
                   "samples, chunk, seed")
    p.add_argument("--out", required=True, help="folder of the results store and summary")
    add_execution_args(p, 1)
    p.set_defaults(func=cmd_sweep)
