"""Cold start: what a user feels when a fresh process runs kinegrasp.

Every measurement runs in a NEW Python process (users run the CLI as fresh processes), side by
side in one run, each the best of ``--repeat`` runs (the machine's other load only adds):

* ``python -c pass``: the interpreter's own start, the floor of every figure below;
* ``kinegrasp --help``, ``kinegrasp evaluate --help``: building the parser;
* ``kinegrasp objects``: the catalog listing;
* ``kinegrasp evaluate --engine fast --samples 10``: a small evaluation with the compiled
  kernels already in the cache (every run after the first on a machine);
* the same evaluation with an EMPTY cache (``KINEGRASP_CACHE`` pointed at a new folder: the
  first run on a machine compiles every kernel its path needs, and builds the object's distance
  grid): its wall time, and how soon its first line reaches stderr (the notice that it is
  compiling). Run once (it takes a minute or more).

``--all`` adds the library-level figures: ``import kinegrasp_env``, the first 10 draws and the
first env step beyond imports (empty and warm cache), and a 10,000-draw ``evaluate`` with two
processes.

    python benchmarks/bench_coldstart.py [--json-out result.json | --no-json] [--skip-cold] [--all]

The figures (seconds) go to ``benchmarks/results/bench_coldstart.json`` (``--json-out``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_file import add_options, settings, write_result

FIRST_DRAWS = """
import json, time
t0 = time.perf_counter()
from kinegrasp_env import evaluate_grasp, shipped_grasps
from kinegrasp_env.world.sdf import object_grid
t1 = time.perf_counter()
object_grid("spray_flask")
t2 = time.perf_counter()
evaluate_grasp(shipped_grasps("spray_flask")[2], sigma=0.0133, n=10, seed=0, engine="fast")
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

#: The 10-draw evaluation of the figures (the issue's "a 10-draw fast evaluate").
EVALUATE_10 = ["evaluate", "--object", "spray_flask", "--grasp", "2", "--sigma", "0.0133",
               "--samples", "10", "--seed", "0", "--engine", "fast"]


def kinegrasp() -> list[str]:
    """The command that runs ``kinegrasp``: the console script next to this interpreter if
    installed (what a user types), else ``python -m kinegrasp_env.cli``."""
    script = Path(sys.executable).with_name("kinegrasp")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "kinegrasp_env.cli"]


def run_json(code: str, env: dict) -> dict:
    out = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                         capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def wall(args: list[str], env: dict) -> float:
    start = time.perf_counter()
    subprocess.run(args, env=env, check=True, capture_output=True)
    return time.perf_counter() - start


def best(args: list[str], env: dict, repeat: int) -> float:
    wall(args, env)  # the first run warms the OS file cache
    return min(wall(args, env) for _ in range(repeat))


def first_run(args: list[str], env: dict) -> dict:
    """Wall time of ``args`` and the time its first stderr line arrived (None: none came)."""
    start = time.perf_counter()
    proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first_line = proc.stderr.readline()
    first = time.perf_counter() - start if first_line else None
    _, err = proc.communicate()
    total = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed: {(first_line + err).decode()[-2000:]}")
    return {"wall_s": total, "first_stderr_line_s": first,
            "first_stderr_line": first_line.decode().strip()[:200]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per figure (best kept)")
    parser.add_argument("--skip-cold", action="store_true",
                        help="skip the empty-cache run (a minute or more)")
    parser.add_argument("--all", action="store_true", help="add the library-level figures")
    parser.add_argument("--samples", type=int, default=10000,
                        help="draws of the --all evaluate run")
    add_options(parser, __file__)
    args = parser.parse_args()
    env = dict(os.environ)
    cli = kinegrasp()
    figures: dict[str, float | dict] = {
        "python -c pass": best([sys.executable, "-c", "pass"], env, args.repeat),
        "kinegrasp --help": best([*cli, "--help"], env, args.repeat),
        "kinegrasp evaluate --help": best([*cli, "evaluate", "--help"], env, args.repeat),
        "kinegrasp objects": best([*cli, "objects"], env, args.repeat),
        "kinegrasp evaluate --engine fast --samples 10 (warm cache)":
            best(cli + EVALUATE_10, env, args.repeat),
    }
    if not args.skip_cold:
        with tempfile.TemporaryDirectory() as cache:
            figures["first run, empty cache"] = first_run(
                cli + EVALUATE_10, {**env, "KINEGRASP_CACHE": cache})
    print(f"{'fresh process (best of ' + str(args.repeat) + ')':<60} {'wall':>8}")
    for name, value in figures.items():
        if isinstance(value, dict):
            print(f"{'evaluate --samples 10, ' + name:<60} {value['wall_s']:>6.2f} s")
            first = value["first_stderr_line_s"]
            print(f"{'  its first line on stderr after':<60} "
                  + (f"{first:>6.2f} s" if first is not None else "  none"))
            print(f"    {value['first_stderr_line']}")
        else:
            print(f"{name:<60} {value:>6.3f} s")
    if args.all:
        figures.update(library_figures(env, args.samples))
    if not args.no_json:
        write_result(__file__, {**figures, "settings": settings(args)}, args.json_out)


def library_figures(env: dict, samples: int) -> dict:
    """The library-level figures of ``--all`` (printed, and returned for the JSON result)."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**env, "KINEGRASP_CACHE": cache}
        imports = min(wall([sys.executable, "-c", "import kinegrasp_env"], env)
                      for _ in range(3))
        cold = run_json(FIRST_DRAWS, env)
        warm = run_json(FIRST_DRAWS, env)
        step_cold = run_json(FIRST_STEP, env)  # compiles what the env's path adds
        step_warm = run_json(FIRST_STEP, env)
        cli = [*kinegrasp(), "evaluate", "--object", "spray_flask", "--grasp", "2",
               "--sigma", "0.0133", "--samples", str(samples), "--seed", "0", "--engine",
               "fast", "--processes", "2", "--json"]
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
    print(f"{f'  {samples} --processes 2, wall':<44} {cli_first:>10.2f} s {cli_warm:>9.2f} s")
    print("(the first env step and the first evaluate run compile the kernels their paths add "
          "to those the\n 10 draws compiled: they show the cost once per machine; the warm "
          "column is every later run)")
    return {"import kinegrasp_env": imports, "first draws": {"empty": cold, "warm": warm},
            "first env step": {"empty": step_cold, "warm": step_warm},
            f"evaluate {samples} --processes 2": {"empty": cli_first, "warm": cli_warm}}


if __name__ == "__main__":
    main()
