"""Train a stable-baselines3 agent on a registered KineGrasp environment.

Example (the committed policy):
    python agents/train.py --env KineGraspSelect-v0 --algo ppo --seed 0 --out agents/models

The open-world policy (built-in + imported training objects, ``agents/prepare.py`` first):
    python agents/train.py --grasp-file agents/grasps/train.json --name openworld

The policy trained on the batch reward (one batch of closings per grasp, re-weighted):
    python agents/train.py --env-kwarg reward=batch --name batch

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` keyed by environment ID
(rl-baselines3-zoo format, ``env_kwargs`` included). Training uses the ``train`` split of the
shipped grasp sets (``agents/evaluate.py`` uses the held-out ``test`` split), or with
``--grasp-file`` every grasp of that file. Writes ``<out>/<env>_<algo>[_<name>].zip``,
checkpoints under ``<out>/checkpoints/`` and a JSON summary.
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ALGOS = ("ppo", "sac")


class UsageError(Exception):
    """A bad argument: reported in one line."""


def load_hyperparams(env_id: str, algo: str, folder: Path = HERE / "hyperparams") -> dict:
    import yaml

    path = folder / f"{algo}.yml"
    if not path.exists():
        raise UsageError(f"no hyperparameter file {path} for algorithm {algo!r}")
    data = yaml.safe_load(path.read_text()) or {}
    if env_id not in data:
        raise UsageError(f"{path} has no entry for {env_id!r} (it has: {', '.join(data)})")
    params = dict(data[env_id])
    if isinstance(params.get("policy_kwargs"), str):
        text = params["policy_kwargs"].strip()
        if not (text.startswith("dict(") and text.endswith(")")):
            raise UsageError(f"{path}: policy_kwargs must look like dict(...)")
        call = ast.parse(text, mode="eval").body
        params["policy_kwargs"] = {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords}
    return params


def make_env(env_id: str, env_kwargs: dict, split: str | None, seed: int,
             grasp_file: str | None = None):
    """The env, reset with ``seed``: the ``split`` of the shipped grasp sets, or with
    ``grasp_file`` every grasp of that file (``split`` then ignored)."""
    import gymnasium as gym

    import kinegrasp_env

    if env_id not in kinegrasp_env.ENV_IDS:
        raise UsageError(f"unknown environment {env_id!r}; registered: "
                         f"{', '.join(kinegrasp_env.ENV_IDS)}")
    if grasp_file is not None:
        if not Path(grasp_file).is_file():
            raise UsageError(f"--grasp-file: no file {grasp_file} (run agents/prepare.py)")
        try:
            env = gym.make(env_id, grasp_file=grasp_file, **env_kwargs)
        except ValueError as error:
            raise UsageError(f"--grasp-file: {error}; for agents/grasps/*.json, run "
                             "agents/prepare.py first") from None
    else:
        try:
            env = gym.make(env_id, split=split, **env_kwargs)
        except (TypeError, ValueError) as error:
            raise UsageError(f"{env_id}: {error}") from None
    env.reset(seed=seed)
    env.action_space.seed(seed)
    return env


#: Env arguments the script sets itself (``--grasp-file``, the train split).
OWN_ARGUMENTS = ("split", "grasp_file")


def env_overrides(pairs: list[str]) -> dict:
    """``KEY=VALUE`` strings as env keyword arguments, each value read as YAML (numbers,
    lists, strings; YAML 1.1: ``yes``, ``no``, ``on`` and ``off`` are booleans, quote them
    to keep a string)."""
    import yaml

    out = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key.isidentifier():
            raise UsageError(f"--env-kwarg takes KEY=VALUE, got {pair!r}")
        if key in OWN_ARGUMENTS:
            raise UsageError(f"--env-kwarg {key}: set by the script (--grasp-file, the train "
                             "split)")
        out[key] = yaml.safe_load(value)
    return out


def train(env_id: str, algo: str, seed: int, out: Path, total_timesteps: int | None = None,
          checkpoint_every: int = 1000, progress: bool = True, grasp_file: str | None = None,
          name: str | None = None, overrides: dict | None = None) -> dict:
    """Train and save; returns the summary written to ``<out>/<env>_<algo>[_<name>].json``
    (tasks: see :func:`make_env`; ``overrides``: env keyword arguments replacing the
    hyperparameter file's)."""
    if algo not in ALGOS:
        raise UsageError(f"unknown algorithm {algo!r}; choose from {', '.join(ALGOS)}")
    from kinegrasp_env.sampling.noise import is_integer_seed

    if not is_integer_seed(seed):
        raise UsageError(f"--seed must be an integer >= 0, got {seed}")
    if total_timesteps is not None and total_timesteps < 1:
        raise UsageError(f"--total-timesteps must be >= 1, got {total_timesteps}")
    params = load_hyperparams(env_id, algo)
    env_kwargs = {**params.pop("env_kwargs", {}), **(overrides or {})}
    steps = int(params.pop("n_timesteps") if total_timesteps is None else total_timesteps)
    params.pop("n_timesteps", None)
    policy = params.pop("policy", "MlpPolicy")
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback
    from stable_baselines3.common.monitor import Monitor

    env = Monitor(make_env(env_id, env_kwargs, "train", seed, grasp_file))
    model = {"ppo": PPO, "sac": SAC}[algo](policy, env, seed=seed, verbose=0, **params)
    out.mkdir(parents=True, exist_ok=True)
    tasks = env.unwrapped.tasks
    name = f"{env_id}_{algo}" + (f"_{name}" if name else "")

    class Bar(BaseCallback):
        def _on_training_start(self) -> None:
            from tqdm import tqdm

            self.bar = tqdm(total=steps, desc=f"training {name}", file=sys.stderr,
                            disable=not progress or None)

        def _on_step(self) -> bool:
            self.bar.update(1)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    callbacks = CallbackList([Bar(), CheckpointCallback(checkpoint_every,
                                                        str(out / "checkpoints"), name)])
    start = time.perf_counter()
    model.learn(total_timesteps=steps, callback=callbacks)
    wall = time.perf_counter() - start
    model.save(out / f"{name}.zip")
    rewards = [float(r) for r in env.get_episode_rewards()]
    tail = rewards[-100:]
    summary = {"env": env_id, "algo": algo, "seed": seed, "timesteps": steps,
               "wall_seconds": round(wall, 1), "episodes": len(rewards),
               "mean_reward_last_100": sum(tail) / len(tail) if tail else None,
               "mean_reward_first_100": (sum(rewards[:100]) / len(rewards[:100])
                                         if rewards else None),
               "hyperparams": {k: str(v) for k, v in params.items()},
               "env_kwargs": env_kwargs, "model": recorded_path(out / f"{name}.zip"),
               "grasp_file": grasp_file,
               "tasks": {obj: len(tasks[obj]) for obj in sorted(tasks)}}
    (out / f"{name}.json").write_text(json.dumps(summary, indent=1))
    env.close()
    return summary


def recorded_path(path: Path) -> str:
    """A file's path as a summary records it: relative to the repository root where it lies
    inside it (the same on every machine), else as given."""
    try:
        return str(path.resolve().relative_to(HERE.parent))
    except ValueError:
        return str(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="KineGraspSelect-v0")
    parser.add_argument("--algo", default="ppo")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--total-timesteps", type=int)
    parser.add_argument("--out", default=str(HERE / "models"))
    parser.add_argument("--grasp-file", help="train on every grasp of this file (e.g. "
                        "agents/grasps/train.json) instead of the shipped sets' train split")
    parser.add_argument("--name", help="suffix of the output files: <env>_<algo>_<name>")
    parser.add_argument("--env-kwarg", action="append", default=[], metavar="KEY=VALUE",
                        help="an env keyword argument replacing the hyperparameter file's "
                        "(repeatable; e.g. reward=batch)")
    args = parser.parse_args(argv)
    try:
        if args.name is not None and not args.name.replace("-", "").replace("_", "").isalnum():
            raise UsageError(f"--name must be letters, digits, '-' or '_', got {args.name!r}")
        summary = train(args.env, args.algo, args.seed, Path(args.out), args.total_timesteps,
                        grasp_file=args.grasp_file, name=args.name,
                        overrides=env_overrides(args.env_kwarg))
    except UsageError as exc:
        print(f"train: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
