"""SB3 agents: training pipeline end to end, reload, evaluation, bad input."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
ROOT = Path(__file__).resolve().parents[1]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"agents_{name}", ROOT / "agents" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


train = _load("train")


@pytest.mark.expensive
def test_train_reload_predict_and_evaluate(tmp_path):
    from stable_baselines3 import PPO

    summary = train.train("KineGraspSelect-v0", "ppo", seed=1, out=tmp_path,
                          total_timesteps=128, checkpoint_every=64, progress=False)
    # one-step episodes; PPO collects whole rollouts of n_steps
    n_steps = train.load_hyperparams("KineGraspSelect-v0", "ppo")["n_steps"]
    assert summary["timesteps"] == 128
    assert summary["episodes"] == -(-128 // n_steps) * n_steps
    model_path = tmp_path / "KineGraspSelect-v0_ppo.zip"
    assert json.loads((tmp_path / "KineGraspSelect-v0_ppo.json").read_text())["seed"] == 1
    assert list((tmp_path / "checkpoints").glob("*.zip"))
    model = PPO.load(model_path, device="cpu")
    action, _ = model.predict(np.zeros(44, dtype=np.float32), deterministic=True)
    assert model.action_space.contains(action)  # one of the hyperparameters' elbow bins
    env = train.make_env("KineGraspSelect-v0", {"action_bins": int(model.action_space.n)},
                         "test", 0)
    assert -np.pi <= env.unwrapped.action_angle(action) < np.pi
    env.close()
    evaluate = _load("evaluate")
    result = evaluate.evaluate(str(model_path), 0.0283, draws=10, oracle_draws=5, grid=3, seed=0,
                               limit=1)
    assert set(result["mean_p_fc"]) == {"nominal", "random", "spread", "policy", "oracle"}
    assert result["rows"][0]["oracle"] >= 0.0


@pytest.mark.expensive
def test_sac_on_the_continuous_action_trains_reloads_and_evaluates(tmp_path):
    from stable_baselines3 import SAC

    train.train("KineGraspSelect-v0", "sac", seed=2, out=tmp_path, total_timesteps=40,
                checkpoint_every=1000, progress=False)
    model_path = tmp_path / "KineGraspSelect-v0_sac.zip"
    model = SAC.load(model_path, device="cpu")
    action, _ = model.predict(np.zeros(44, dtype=np.float32), deterministic=True)
    assert action.shape == (1,) and -1 <= action[0] <= 1
    result = _load("evaluate").evaluate(str(model_path), 0.0283, draws=10, oracle_draws=5,
                                        grid=3, seed=0, limit=1, random_angles=2)
    row = result["rows"][0]
    # the evaluated policy configuration is where the continuous action psi = pi a leads
    import gymnasium as gym

    env = gym.make("KineGraspSelect-v0", split="test", n_draws=1).unwrapped
    obs, _ = env.reset(seed=0, options={"object": row["object"], "grasp": 0, "sigma": 0.0283})
    action, _ = model.predict(obs, deterministic=True)
    q, _ = env.configuration_at(np.pi * float(action[0]))
    assert row["elbow_policy"] == pytest.approx(float(env.ik.elbow_angle(q[None])[0]),
                                                abs=1e-9)
    assert 0.0 <= row["policy"] <= 1.0
    env.close()


@pytest.mark.parametrize(("kwargs", "needle"), [
    ({"env_id": "Pong-v0", "algo": "ppo"}, "no entry for 'Pong-v0'"),
    ({"env_id": "KineGraspSelect-v0", "algo": "dqn"}, "unknown algorithm 'dqn'"),
])
def test_train_bad_input(tmp_path, kwargs, needle):
    with pytest.raises(train.UsageError, match=needle):
        train.train(seed=0, out=tmp_path, total_timesteps=8, **kwargs)


def test_hyperparams_missing_file(tmp_path):
    with pytest.raises(train.UsageError, match="no hyperparameter file"):
        train.load_hyperparams("KineGraspSelect-v0", "ppo", folder=tmp_path)


def test_train_cli_one_line_error(capsys):
    assert train.main(["--env", "KineGraspSelect-v0", "--algo", "a2c"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown algorithm 'a2c'" in err


def test_unregistered_env_id():
    with pytest.raises(train.UsageError, match="unknown environment 'Nope-v0'"):
        train.make_env("Nope-v0", {}, "train", 0)
