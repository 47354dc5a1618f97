"""Sweep throughput on the local pool (1 and 2 processes) and on Ray, and Ray's per-task cost.

Run: ``python benchmarks/bench_scale.py [--samples 500] [--chunk 50] [--engine fast]``
(needs the ``ray`` extra).

1. The same sweep (2 objects x 2 grasps x 2 sigmas, ``--samples`` draws per cell in chunks of
   ``--chunk``) into a fresh store on: local 1 process, local 2 processes, Ray (a local
   instance with 2 CPUs) with cold workers, and Ray again with the workers warm. Prints
   wall time and tasks/s, checks that all summaries are byte-identical.
2. Per-task overhead: ``--trivial`` no-op tasks through the inline executor and through Ray
   (its scheduling, serialization and result transfer; one CPU busy per task).

The figures (seconds, tasks/s, ratios) also go to ``benchmarks/results/bench_scale.json``
(``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from results_file import add_options, settings, write_result

from kinegrasp_env.montecarlo.execution import LocalExecutor, RayExecutor
from kinegrasp_env.montecarlo.sweep import SweepSpec, run_sweep


def _noop(task: int) -> int:
    return task


def _sweep(spec: SweepSpec, executor, folder: Path) -> tuple[float, bytes]:
    start = time.perf_counter()
    run_sweep(spec, folder, executor, progress=False)
    return time.perf_counter() - start, (folder / "summary.csv").read_bytes()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=500)
    parser.add_argument("--chunk", type=int, default=50)
    parser.add_argument("--engine", default="fast")
    parser.add_argument("--trivial", type=int, default=2000)
    add_options(parser, __file__)
    args = parser.parse_args()
    spec_dict = {"objects": ["cube", "spray_flask"], "grasps": [0, 1],
                 "sigmas": [0.0133, 0.0266], "engines": [args.engine],
                 "samples": args.samples, "chunk": args.chunk}
    spec = SweepSpec.from_dict(spec_dict)
    tasks = len(spec.tasks())
    print(f"sweep: {len(spec.cells())} cells x {args.samples} draws ({args.engine} engine) = "
          f"{tasks} tasks of {args.chunk} draws")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        # warm-up in this process: distance grids loaded, numba kernels compiled (forked
        # local workers inherit them; Ray workers are fresh processes and load them again)
        with LocalExecutor(1) as ex:
            run_sweep(SweepSpec.from_dict({**spec_dict, "grasps": [0], "sigmas": [0.01],
                                           "noise": ["gaussian"], "samples": args.chunk}),
                      root / "warm", ex, progress=False)
        timings: dict[str, float] = {}
        summaries: dict[str, bytes] = {}
        for name, processes in (("local, 1 process", 1), ("local, 2 processes", 2)):
            with LocalExecutor(processes) as ex:
                timings[name], summaries[name] = _sweep(spec, ex, root / name)
        with RayExecutor(num_cpus=2) as ex:
            for name in ("ray (2 CPUs), cold workers", "ray (2 CPUs), warm workers"):
                timings[name], summaries[name] = _sweep(spec, ex, root / name)
            start = time.perf_counter()
            list(ex.map(_noop, range(args.trivial)))
            ray_trivial = (time.perf_counter() - start) / args.trivial
        with LocalExecutor(1) as ex:
            start = time.perf_counter()
            list(ex.map(_noop, range(args.trivial)))
            inline_trivial = (time.perf_counter() - start) / args.trivial
    base = timings["local, 1 process"]
    print(f"{'backend':<30} {'wall [s]':>9} {'tasks/s':>8} {'vs local 1':>10}")
    for name, seconds in timings.items():
        print(f"{name:<30} {seconds:>9.2f} {tasks / seconds:>8.1f} {base / seconds:>9.2f}x")
    identical = len(set(summaries.values())) == 1
    print(f"summaries byte-identical on every backend: {identical}")
    per_task = base / tasks
    print(f"per-task cost: work {per_task * 1e3:.1f} ms (local, 1 process); overhead: ray "
          f"{ray_trivial * 1e3:.2f} ms, inline {inline_trivial * 1e6:.1f} us "
          f"({args.trivial} no-op tasks)")
    print(f"ray overhead / task work: {ray_trivial / per_task:.1%}")
    if not args.no_json:
        write_result(__file__, {
            "cells": len(spec.cells()), "tasks": tasks,
            "summaries_byte_identical": identical,
            "work_s_per_task_local_1_process": per_task,
            "ray_overhead_s_per_task": ray_trivial, "inline_overhead_s_per_task": inline_trivial,
            "ray_overhead_over_task_work": ray_trivial / per_task,
            "backends": [{"backend": name, "wall_s": seconds, "tasks_per_s": tasks / seconds,
                          "speed_vs_local_1_process": base / seconds}
                         for name, seconds in timings.items()],
            "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
