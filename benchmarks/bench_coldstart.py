"""Cold start: what a user feels when a fresh process runs kinegrasp.

Every measurement runs in a NEW Python process (users run the CLI as fresh processes), side by
side in one run:

* ``import kinegrasp_env`` (and ``gym.make``), seconds;
* the first 10 fast-engine draws beyond imports, with an EMPTY compiled-kernel cache (the first
  run on a machine: numba compiles every kernel) and again with the cache that run left (every
  later run: the kernels are loaded from disk);
* the same for the first step of ``KineGrasp-v0`` with the fast engine;
* ``kinegrasp evaluate --engine fast --samples 10000 --processes 2`` wall time, start-up
  included, warm cache (pool workers are forked after the parent loaded the kernels, so they
  compile nothing).

The cold figures use a temporary ``KINEGRASP_CACHE``, so they also rebuild the object's distance
grid; the grid build is timed separately and reported.

    python benchmarks/bench_coldstart.py
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

FIRST_DRAWS = """
import json, time
t0 = time.perf_counter()
from kinegrasp_env import JointNoise, evaluate_grasp, shipped_grasps
from kinegrasp_env.world.sdf import object_grid
t1 = time.perf_counter()
object_grid("spray_flask")
t2 = time.perf_counter()
evaluate_grasp(shipped_grasps("spray_flask")[2], JointNoise(0.0133), 10, seed=0, engine="fast")
t3 = time.perf_counter()
print(json.dumps({"imports": t1 - t0, "grid": t2 - t1, "draws": t3 - t2}))
"""

FIRST_STEP = """
import json, time
t0 = time.perf_counter()
import gymnasium as gym
import kinegrasp_env
env = gym.make("KineGrasp-v0", n_draws=64, engine="fast")
t1 = time.perf_counter()
env.reset(seed=0, options={"object": "spray_flask", "grasp": 2})
t2 = time.perf_counter()
env.step(env.action_space.sample())
t3 = time.perf_counter()
print(json.dumps({"make": t1 - t0, "reset": t2 - t1, "first_step": t3 - t2}))
"""


def run_json(code: str, env: dict) -> dict:
    out = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                         capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def wall(args: list[str], env: dict) -> float:
    start = time.perf_counter()
    subprocess.run(args, env=env, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=10000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "KINEGRASP_CACHE": cache}
        imports = min(wall([sys.executable, "-c", "import kinegrasp_env"], env)
                      for _ in range(3))
        cold = run_json(FIRST_DRAWS, env)
        warm = run_json(FIRST_DRAWS, env)
        step_cold = run_json(FIRST_STEP, env)  # compiles what the env's path adds
        step_warm = run_json(FIRST_STEP, env)
        cli = [sys.executable, "-m", "kinegrasp_env.cli", "evaluate", "--object", "spray_flask",
               "--grasp", "2", "--sigma", "0.0133", "--samples", str(args.samples), "--seed",
               "0", "--engine", "fast", "--processes", "2", "--json"]
        cli_first = wall(cli, env)  # compiles what 10,000 draws add (e.g. 4+ contacts)
        cli_warm = wall(cli, env)
    print(f"python -c 'import kinegrasp_env' (whole process, best of 3): {imports:.2f} s")
    print(f"{'fresh process':<44} {'first run':>12} {'warm cache':>11}")
    print(f"{'imports':<44} {cold['imports']:>10.2f} s {warm['imports']:>9.2f} s")
    print(f"{'distance grid of spray_flask':<44} {cold['grid']:>10.2f} s {warm['grid']:>9.2f} s")
    print(f"{'first 10 fast-engine draws, beyond imports':<44} {cold['draws']:>10.2f} s "
          f"{warm['draws']:>9.2f} s")
    print(f"{'env first 64-draw step (gym.make, reset before)':<44} "
          f"{step_cold['first_step']:>10.2f} s {step_warm['first_step']:>9.2f} s")
    print(f"{'kinegrasp evaluate --engine fast --samples':<44}")
    print(f"{f'  {args.samples} --processes 2, wall':<44} {cli_first:>10.2f} s {cli_warm:>9.2f} s")
    print("(the first env step and the first evaluate run compile the kernels their paths add "
          "to those the\n 10 draws compiled: they show the cost once per machine; the warm "
          "column is every later run)")


if __name__ == "__main__":
    main()
