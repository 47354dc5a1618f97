"""What the multi-step KineGrasp-v0 could gain over the one-step KineGraspSelect-v0, measured.

Example (after the open-world evaluation):
    python agents/multistep.py --result agents/models/evaluation_openworld.json

KineGrasp-v0 moves the elbow by ``step_size * a`` radians per step, at most ``max_steps``
steps (the values of ``agents/hyperparams/ppo.yml``), and pays P(FC) at every step. Its
observation is a function of the task and the current elbow angle alone (the reward's draws
are never observed), so whatever a multi-step policy does, the episode ends at one elbow
angle a one-step policy could have asked for directly: its final configuration can be no
better than the one-step optimum. This script measures the two things that remain:

1. **Reach.** From the optimizer's P(FC) curves over the whole reachable self-motion (the
   result's rows, ``optimizer_curve``: [psi, P(FC)] per angle, on the optimizer's selection
   draws), per grasp the best P(FC) within the multi-step reach, |psi - psi_nominal| <=
   max_steps * step_size, against the best anywhere: what the multi-step formulation gives
   up, and on how many grasps the best angle lies beyond its reach.
2. **Cost.** Wall time and Monte Carlo draws per episode of each env with the
   hyperparameters' settings (``--episodes`` episodes each, random elbow moves, fast engine,
   grasps of the shipped training split); KineGrasp-v0's episodes run their whole horizon
   (done signal never raised), as a policy must to reach the ends of its reach.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def wrap(angle: float) -> float:
    """An angle wrapped to (-pi, pi] (radians)."""
    return float(math.remainder(angle, 2.0 * math.pi))


def multistep_reach() -> float:
    """max_steps * step_size (radians) of KineGrasp-v0 with the ppo.yml env_kwargs (the env's
    defaults for what they leave out)."""
    import inspect

    import yaml

    from kinegrasp_env.envs.kinegrasp import KineGraspEnv

    kwargs = yaml.safe_load((HERE / "hyperparams" / "ppo.yml").read_text())["KineGrasp-v0"]
    defaults = inspect.signature(KineGraspEnv).parameters
    given = kwargs.get("env_kwargs", {})
    return float(given.get("max_steps", defaults["max_steps"].default)
                 * given.get("step_size", defaults["step_size"].default))


def reach_loss(rows: list[dict], reach: float) -> dict:
    """Per grasp, the best curve P(FC) within ``reach`` radians of the nominal elbow and
    anywhere; their mean difference and the grasps whose best lies beyond reach.

    Raises:
        ValueError: a row without ``optimizer_curve``.
    """
    within, anywhere = [], []
    for row in rows:
        curve = row.get("optimizer_curve")
        if not curve:
            raise ValueError(f"row {row.get('object')}/{row.get('grasp')} has no "
                             "optimizer_curve (run agents/evaluate.py with the optimizer)")
        psi0 = row["elbow_nominal"]
        near = [p for psi, p in curve if abs(wrap(psi - psi0)) <= reach + 1e-9]
        within.append(max(near))
        anywhere.append(max(p for _, p in curve))
    within_a, anywhere_a = np.array(within), np.array(anywhere)
    return {"reach_rad": reach, "grasps": len(rows),
            "best_within_reach": float(within_a.mean()),
            "best_anywhere": float(anywhere_a.mean()),
            "loss_mean": float((anywhere_a - within_a).mean()),
            "loss_max": float((anywhere_a - within_a).max()),
            "grasps_best_beyond_reach": int((anywhere_a > within_a).sum())}


def episode_cost(env_id: str, episodes: int, seed: int) -> dict:
    """Mean wall time (s) and draws per episode of ``env_id`` with the ppo.yml env_kwargs,
    random actions (KineGrasp-v0: the done signal held at -1, whole horizon), shipped
    training grasps."""
    import gymnasium as gym
    import yaml

    import kinegrasp_env  # noqa: F401

    kwargs = yaml.safe_load((HERE / "hyperparams" / "ppo.yml").read_text())[env_id]
    env = gym.make(env_id, split="train", **kwargs["env_kwargs"])
    env.action_space.seed(seed)
    env.reset(seed=seed)
    env.step(env.action_space.sample())  # engines built and compiled before timing
    draws, start = 0, time.perf_counter()
    for _ in range(episodes):
        env.reset()
        done = False
        while not done:
            action = env.action_space.sample()
            if env_id == "KineGrasp-v0":
                action[1] = -1.0  # never end early
            _, _, terminated, truncated, info = env.step(action)
            draws += info["draws"]
            done = terminated or truncated
    seconds = (time.perf_counter() - start) / episodes
    env.close()
    return {"env": env_id, "seconds_per_episode": seconds, "draws_per_episode": draws / episodes}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--result", default=str(HERE / "models" / "evaluation_openworld.json"))
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    try:
        if args.episodes < 1:
            raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
        path = Path(args.result)
        if not path.is_file():
            raise ValueError(f"--result: no file {path}")
        reach = multistep_reach()
        out = {"reach": reach_loss(json.loads(path.read_text())["rows"], reach),
               "cost": [episode_cost(e, args.episodes, args.seed)
                        for e in ("KineGraspSelect-v0", "KineGrasp-v0")]}
    except (ValueError, KeyError) as error:
        print(f"multistep: error: {error}", file=sys.stderr)
        return 2
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
