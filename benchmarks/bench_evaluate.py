"""Monte Carlo evaluation throughput of the reference (pybullet) engine: one spray-flask grasp
at sigma = 0.0133.

Run: ``python benchmarks/bench_evaluate.py [--draws 10000] [--grasp 0]``. Prints wall time
and draws/s on 1 and 2 processes (same seed: identical statistics; the wall time includes
starting the worker processes), then where the time goes on one process (kinematics,
auto-close, quality; wall and CPU time per draw). Target: 10,000 draws in under 20 s on 2
processes on the 2-core machine.

The machine's load average is printed before and after: on a shared machine the wall times
scale with it, the CPU time per draw much less.

The figures (seconds, draws/s) also go to ``benchmarks/results/bench_evaluate.json``
(``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import time
from types import SimpleNamespace

import numpy as np
from results_file import add_options, settings, write_result

from kinegrasp_env.montecarlo.draws import OUTCOMES
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.evaluate import GraspEvaluation, evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import chunk_stream
from kinegrasp_env.threads import single_blas_thread
from kinegrasp_env.world.grasps import grasp_by_index

SIGMA = 0.0133
TARGET_DRAWS, TARGET_SECONDS = 10_000, 20.0


def load_line() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f} {five:.2f} {fifteen:.2f} on {os.cpu_count()} CPUs"


def statistics(stats: GraspEvaluation) -> dict:
    """Every statistic of an evaluation (not its draws), NaN as None (comparable)."""
    out = {f.name: getattr(stats, f.name) for f in dataclasses.fields(stats)
           if f.name != "draws"}
    return {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in out.items()}


def throughput(grasp, draws: int) -> dict:
    """Wall time and statistics on 1 and 2 processes."""
    results = {}
    for processes in (1, 2):
        start = time.perf_counter()
        with LocalExecutor(processes) as pool:  # one process: the run in this one
            stats = evaluate_grasp(grasp, sigma=SIGMA, n=draws, seed=0, engine="pybullet",
                                   executor=pool)
        wall = time.perf_counter() - start
        results[processes] = (stats, wall)
        print(f"{processes} process(es): {wall:7.2f} s  {draws / wall:8.0f} draws/s  "
              f"P(FC) = {stats.p_fc:.4f}  q_mean = {stats.q_mean:.5f}")
    same = statistics(results[1][0]) == statistics(results[2][0])
    print(f"identical statistics on 1 and 2 processes: {same}")
    wall = results[2][1] * TARGET_DRAWS / draws
    print(f"{TARGET_DRAWS} draws on 2 processes: {wall:.1f} s"
          f"{'' if draws == TARGET_DRAWS else ' (scaled from this run)'} "
          f"(target < {TARGET_SECONDS:.0f} s)")
    return {"processes": [{"processes": p, "draws": draws, "wall_s": w, "draws_per_s": draws / w,
                           "p_fc": st.p_fc, "q_mean": st.q_mean}
                          for p, (st, w) in results.items()],
            "identical_statistics_1_and_2_processes": same,
            f"wall_s_{TARGET_DRAWS}_draws_2_processes": wall,
            "wall_scaled_from_this_run": draws != TARGET_DRAWS,
            "target_s": TARGET_SECONDS}


def stage_split(object_name: str, grasp, draws: int) -> dict:
    """Stages on one process over the first ``draws`` draws of the run's first chunk."""
    engine = make_engine("pybullet", DEFAULT_ROBOT, object_name)
    q = np.repeat(grasp.q0[None], draws, axis=0)
    q[:, :7] += JointNoise(SIGMA).sample(draws, 7, chunk_stream(0, 0))  # chunk 0's stream
    engine.run(q[:5])  # warm: first calls, compiled kernels
    # what engine.run does, its stages timed apart, in the one BLAS thread run uses: the
    # closing (the fingers' kinematics is part of it: no kinematics stage of its own), then
    # the scoring
    cpu = time.process_time()
    with single_blas_thread():
        start = time.perf_counter()
        batch = engine.close_batch(engine.check(q))
        closed = time.perf_counter()
        out = engine.scored(q, batch)
        scored = time.perf_counter()
    cpu = time.process_time() - cpu
    t = SimpleNamespace(kinematics=0.0, autoclose=closed - start, quality=scored - closed)
    total = t.kinematics + t.autoclose + t.quality
    print(f"stage split over {draws} draws (1 process, wall): kinematics "
          f"{t.kinematics / draws * 1e6:7.1f} us/draw ({t.kinematics / total:.1%}), auto-close "
          f"{t.autoclose / draws * 1e6:7.1f} us/draw ({t.autoclose / total:.1%}), quality "
          f"{t.quality / draws * 1e6:7.1f} us/draw ({t.quality / total:.1%}); CPU time "
          f"{cpu / draws * 1e6:7.1f} us/draw for {total / draws * 1e6:7.1f} us/draw wall")
    counts = np.bincount(out.outcome, minlength=4)
    contacts = np.bincount(out.n_contacts, minlength=7)
    print("outcomes: " + ", ".join(f"{o} {c}" for o, c in zip(OUTCOMES, counts, strict=True)))
    print("contacts per draw: " + ", ".join(f"{k}: {c}" for k, c in enumerate(contacts) if c))
    engine.close()
    return {"stage_draws": draws, "kinematics_s_per_draw": t.kinematics / draws,
            "autoclose_s_per_draw": t.autoclose / draws, "quality_s_per_draw": t.quality / draws,
            "wall_s_per_draw": total / draws, "cpu_s_per_draw": cpu / draws,
            "outcomes": [{"outcome": o, "draws": int(c)}
                         for o, c in zip(OUTCOMES, counts, strict=True)],
            "contacts_per_draw": [{"contacts": k, "draws": int(c)}
                                  for k, c in enumerate(contacts) if c]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--draws", type=int, default=TARGET_DRAWS)
    parser.add_argument("--grasp", type=int, default=0)
    parser.add_argument("--object", default="spray_flask")
    add_options(parser, __file__)
    args = parser.parse_args()
    grasp = grasp_by_index(args.object, args.grasp)
    print(f"{args.object} grasp {args.grasp}, sigma {SIGMA}, {args.draws} draws; {load_line()}")
    record = throughput(grasp, args.draws)
    record.update(stage_split(args.object, grasp, min(args.draws, 2000)))
    print(f"after: {load_line()}")
    if not args.no_json:
        write_result(__file__, {**record, "settings": {**settings(args), "sigma": SIGMA}},
                     args.json_out)


if __name__ == "__main__":
    main()
