"""Compare elbow-angle choices on held-out grasps: nominal IK, random, trained policy, oracle.

Example (the committed table):
    python agents/evaluate.py --model agents/models/KineGraspSelect-v0_ppo.zip --seed 0 \
        --out agents/models/evaluation.json

For every grasp of the held-out ``test`` split (grasp index i % 4 == 3 of each object's
shipped set) at noise ``--sigma``, the arm configuration chosen by each method is evaluated
with ``--draws`` Monte Carlo draws (the same seed for every method: common random numbers).
Methods: ``nominal`` (the grasp's IK configuration), ``random`` (the mean over
``--random-angles`` uniformly drawn elbow angles, ``--draws`` in all: the expected P(FC)
of picking the elbow at random), ``spread`` (no learning: of the oracle's grid, the angle
with the smallest palm-position spread per unit joint noise, sqrt(trace(J_p J_p^T))),
``policy`` (the trained model, deterministic) and ``oracle`` (searches the grid of elbow
angles with ``--oracle-draws`` draws each, then is evaluated like the others). Prints a
table of mean P(FC) over the grasps with 95% intervals and the paired differences policy -
baseline; writes JSON. ``--quick`` shrinks everything.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

METHODS = ("nominal", "random", "spread", "policy", "oracle")


def _interval(values: np.ndarray) -> tuple[float, float, float]:
    mean = float(values.mean())
    half = 1.96 * float(values.std(ddof=1)) / math.sqrt(values.size) if values.size > 1 else \
        math.nan
    return mean, mean - half, mean + half


def palm_spread(env, q: np.ndarray) -> float:
    """Palm-position spread per unit joint noise at arm+hand configuration q (14,): the
    root of the trace of J_p J_p^T over the 7 arm joints (metres per radian)."""
    from kinegrasp_env.robot.model import PALM_LINK

    jac = env.kinematics.jacobian(q, PALM_LINK)[0][:3, :7]
    return float(np.sqrt(np.trace(jac @ jac.T)))


def evaluate(model_path: str, sigma: float, draws: int, oracle_draws: int, grid: int,
             seed: int, processes: int = 1, limit: int | None = None,
             random_angles: int = 4) -> dict:
    import gymnasium as gym
    from stable_baselines3 import PPO, SAC

    import kinegrasp_env  # noqa: F401
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.world.grasps import Grasp

    path = Path(model_path)
    if not path.exists():
        raise SystemExit(f"evaluate: error: no model at {path}")
    algo = SAC if "_sac" in path.stem else PPO
    model = algo.load(path, device="cpu")
    bins = getattr(model.action_space, "n", None)  # a policy over Discrete(bins) elbow angles
    env = gym.make("KineGraspSelect-v0", split="test", n_draws=1,
                   action_bins=None if bins is None else int(bins)).unwrapped
    noise = JointNoise(sigma)
    rng = np.random.default_rng(seed)
    tasks = [(name, i) for name in env.object_names for i in range(len(env.tasks[name]))]
    tasks = tasks[:limit] if limit else tasks
    rows = []

    def score(grasp: Grasp, q: np.ndarray, n: int) -> float:
        here = Grasp(grasp.object, q, grasp.palm_pose, grasp.points, grasp.normals,
                     grasp.fingers, grasp.links, grasp.q_nominal, grasp.id)
        return evaluate_grasp(here, noise, n, seed, executor=executor).p_fc

    from tqdm import tqdm

    from kinegrasp_env.montecarlo.execution import LocalExecutor

    # one pool for the whole run: its workers keep their engines between evaluations
    with LocalExecutor(processes) as executor:
        for name, index in tqdm(tasks, desc="held-out grasps", file=sys.stderr, disable=None):
            obs, _ = env.reset(seed=seed, options={"object": name, "grasp": index, "sigma": sigma})
            grasp, q0 = env.grasp, env.q.copy()

            def reach(psi: float, start: np.ndarray = q0) -> np.ndarray:
                return env.configuration_at(psi, start)[0]

            action, _ = model.predict(obs, deterministic=True)
            configs = {"nominal": q0,
                       "policy": reach(env.action_angle(action))}
            grid_psi = np.linspace(-math.pi, math.pi, grid, endpoint=False)
            candidates = [reach(p) for p in grid_psi]
            configs["spread"] = candidates[int(np.argmin([palm_spread(env, q)
                                                          for q in candidates]))]
            quick = [score(grasp, q, oracle_draws) for q in candidates]
            configs["oracle"] = candidates[int(np.argmax(quick))]
            row = {"object": name, "grasp": grasp.id,
                   "elbow_nominal": float(env.ik.elbow_angle(q0[None])[0])}
            for method in METHODS:
                if method == "random":
                    angles = rng.uniform(-math.pi, math.pi, random_angles)
                    share = max(draws // random_angles, 1)
                    row[method] = float(np.mean([score(grasp, reach(p), share)
                                                 for p in angles]))
                else:
                    row[method] = score(grasp, configs[method], draws)
                row[f"elbow_{method}"] = (float(env.ik.elbow_angle(configs[method][None])[0])
                                          if method in configs else None)
            rows.append(row)
    env.close()
    summary = {m: _interval(np.array([r[m] for r in rows])) for m in METHODS}
    diffs = {f"policy-{m}": _interval(np.array([r["policy"] - r[m] for r in rows]))
             for m in METHODS if m != "policy"}
    return {"model": str(path), "sigma": sigma, "draws": draws, "oracle_draws": oracle_draws,
            "grid": grid, "seed": seed, "random_angles": random_angles,
            "grasps": len(rows), "rows": rows,
            "mean_p_fc": summary, "paired_differences": diffs}


def table(result: dict) -> str:
    lines = [f"held-out grasps: {result['grasps']}, sigma = {result['sigma']}, "
             f"{result['draws']} draws per configuration",
             "", "| method | mean P(FC) | 95% CI |", "|---|---|---|"]
    for m, (mean, lo, hi) in result["mean_p_fc"].items():
        lines.append(f"| {m} | {mean:.3f} | {lo:.3f} .. {hi:.3f} |")
    lines += ["", "| paired difference | mean | 95% CI |", "|---|---|---|"]
    for m, (mean, lo, hi) in result["paired_differences"].items():
        lines.append(f"| {m} | {mean:+.3f} | {lo:+.3f} .. {hi:+.3f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default="agents/models/KineGraspSelect-v0_ppo.zip")
    parser.add_argument("--sigma", type=float, default=0.0283)
    parser.add_argument("--draws", type=int, default=2000)
    parser.add_argument("--oracle-draws", type=int, default=200)
    parser.add_argument("--grid", type=int, default=12)
    parser.add_argument("--random-angles", type=int, default=4,
                        help="random elbow angles averaged per grasp (--draws shared)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--quick", action="store_true", help="tiny run for tests")
    parser.add_argument("--out", help="write the result as JSON")
    args = parser.parse_args(argv)
    if args.sigma < 0 or args.draws < 1 or args.random_angles < 1:
        print("evaluate: error: --sigma must be >= 0, --draws and --random-angles >= 1",
              file=sys.stderr)
        return 2
    if args.quick:
        args.draws, args.oracle_draws, args.grid, args.processes = 20, 8, 3, 1
        args.random_angles = 2
    result = evaluate(args.model, args.sigma, args.draws, args.oracle_draws, args.grid,
                      args.seed, args.processes, limit=2 if args.quick else None,
                      random_angles=args.random_angles)
    print(table(result))
    if args.out:
        Path(args.out).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
