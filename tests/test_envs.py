"""Gymnasium environments: API checks, determinism, the self-motion action, the reward."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

import kinegrasp_env
from kinegrasp_env import ENV_IDS
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.robot.kinematics import pose_error
from kinegrasp_env.robot.model import ELBOW_LINK, PALM_LINK
from kinegrasp_env.world.grasps import Grasp

SMALL = {"n_draws": 8}
#: every registered env, and the discrete-action variant of the one-step env
VARIANTS = [(env_id, {}) for env_id in ENV_IDS] + [("KineGraspSelect-v0", {"action_bins": 6})]


@pytest.mark.parametrize(("env_id", "extra"), VARIANTS)
def test_gymnasium_and_sb3_checkers(env_id, extra):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, **SMALL, **extra)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # the render check runs in test_gymnasium_check_env_with_its_render_check, in a
        # subprocess (a GUI connect without a display would end this process)
        check_env(env.unwrapped, skip_render_check=True)
    env.close()
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id, **SMALL, **extra)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env.unwrapped, warn=True)
    env.close()
    env.close()  # closing twice is fine


RENDER_CHECK = """
import sys, warnings
import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import kinegrasp_env
from kinegrasp_env.envs.render import NoDisplayWarning, SceneViewer
from kinegrasp_env.world.sim import BulletWorld, NoDisplayError

for kind in ("BulletWorld", "SceneViewer"):
    try:
        BulletWorld(gui=True) if kind == "BulletWorld" else SceneViewer("cube", gui=True)
    except NoDisplayError as exc:
        print(kind, "refused:", exc)
variants = [(i, {}) for i in kinegrasp_env.ENV_IDS] + [("KineGraspSelect-v0", {"action_bins": 6})]
for env_id, extra in variants:
    env = gym.make(env_id, n_draws=8, **extra)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)  # with its render check: every declared render mode
    env.close()
    kinds = sorted({w.category.__name__ for w in caught})
    print("checked", env_id, extra, kinds)
human = gym.make("KineGraspSelect-v0", n_draws=4, render_mode="human")
human.reset(seed=0)
print("human render:", human.render())
human.close()
"""


@pytest.mark.parametrize("display", [None, ":97"])
def test_gymnasium_check_env_with_its_render_check(display):
    """Gymnasium's ``check_env`` as users run it, render check included, for every
    registered env, on a machine without a display (none set, or one that does not answer):
    it makes the env with render_mode="human", whose GUI connect used to end the process
    with exit status 1. Now: the GUI is refused with a clear error, and the env's human mode
    warns (NoDisplayWarning) and renders nothing. In a subprocess, so that a dead process
    cannot take pytest with it."""
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    if display is not None:
        env["DISPLAY"] = display
    proc = subprocess.run([sys.executable, "-c", RENDER_CHECK], capture_output=True, text=True,
                          env=env, check=False, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    reason = "$DISPLAY is not set" if display is None else f"the X server {display!r}"
    for kind in ("BulletWorld", "SceneViewer"):
        assert any(line.startswith(f"{kind} refused: pybullet's GUI needs a display")
                   and reason in line for line in lines), proc.stdout
    checked = [line for line in lines if line.startswith("checked ")]
    assert len(checked) == len(VARIANTS)
    for line in checked:  # the one warning is ours, about the human mode
        assert line.endswith("['NoDisplayWarning']"), line
    assert "human render: None" in lines


@pytest.mark.parametrize(("env_id", "extra"), VARIANTS)
def test_same_seed_same_rollout(env_id, extra):
    from gymnasium.utils.env_checker import data_equivalence

    envs = [gym.make(env_id, **SMALL, **extra) for _ in range(2)]
    outs = []
    for env in envs:
        env.action_space.seed(3)
        obs, _ = env.reset(seed=11)
        trace = [obs]
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            trace += [obs, reward, info["p_fc"], info["draw_seed"]]
            if terminated or truncated:
                obs, _ = env.reset()
                trace.append(obs)
        outs.append(trace)
        env.close()
    assert data_equivalence(outs[0], outs[1])
    other = gym.make(env_id, **SMALL, **extra)
    other.reset(seed=12)
    *_, info = other.step(other.action_space.sample())
    assert info["draw_seed"] != outs[0][4]  # another seed, other internal draws
    other.close()


def test_make_by_module_string():
    env = gym.make("kinegrasp_env:KineGrasp-v0", **SMALL)
    env.close()
    assert kinegrasp_env.ENV_IDS == ("KineGrasp-v0", "KineGraspSelect-v0")


def test_action_keeps_the_palm_and_moves_the_elbow():
    env = gym.make("KineGrasp-v0", **SMALL).unwrapped
    env.reset(seed=0, options={"object": "drill", "grasp": 0, "sigma": 0.01})
    kin = env._engine("drill").kin
    palm0 = kin.pose(env.q, PALM_LINK)
    elbow0 = kin.pose(env.q, ELBOW_LINK)[0, :3, 3]
    env.step(np.array([0.8, -1.0], dtype=np.float32))
    assert np.abs(pose_error(kin.pose(env.q, PALM_LINK), palm0)).max() < 1e-6
    assert np.linalg.norm(kin.pose(env.q, ELBOW_LINK)[0, :3, 3] - elbow0) > 0.01
    env.close()


def test_reward_equals_the_evaluation_engine():
    """Plumbing, not the estimate: the reward is the evaluation of the env's current
    configuration with the draw seed it reports (a wrong configuration, seed or draw count in
    the env fails it); the estimate itself is checked by the engines' tests."""
    env = gym.make("KineGrasp-v0", n_draws=32).unwrapped
    env.reset(seed=5, options={"object": "spray_flask", "grasp": 1, "sigma": 0.02})
    _, reward, _, _, info = env.step(np.array([0.5, -1.0], dtype=np.float32))
    g = env.grasp
    here = Grasp(g.object, env.q.copy(), g.palm_pose, g.points, g.normals, g.fingers, g.links,
                 g.q_nominal)
    stats = evaluate_grasp(here, env.noise, 32, seed=info["draw_seed"], chunk=32)
    assert reward == pytest.approx(stats.p_fc) == pytest.approx(info["p_fc"])
    assert info["reward_limit_penalty"] == 0.0
    env.close()


def test_rgb_array_render():
    env = gym.make("KineGraspSelect-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    image = env.render()
    assert image.shape == (240, 320, 3) and image.dtype == np.uint8
    assert image.std() > 5  # not a blank frame
    env.close()


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_vector_envs(mode):
    vec = gym.make_vec("KineGraspSelect-v0", num_envs=2, vectorization_mode=mode, **SMALL)
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (2, 44)
    obs, reward, *_ = vec.step(vec.action_space.sample())
    assert reward.shape == (2,)
    vec.close()


@pytest.mark.parametrize(("options", "needle"), [
    ({"object": "teapot"}, "unknown object 'teapot'"),
    ({"sigma": -0.1}, "sigma must be finite and >= 0"),
    ({"grasp": 99, "object": "cube"}, "grasp index 99 out of range"),
    ({"colour": "red"}, r"unknown reset options \['colour'\]"),
    ({"sigma": 4.0}, r"sigma must be finite and >= 0 and at most pi \(3.1416\) radians"),
    ({"sigma": 1e308}, "at most pi"),
    ({"sigma": float("nan")}, "sigma must be finite"),
    ({"sigma": float("inf")}, "sigma must be finite"),
    ({"sigma": "wide"}, "sigma must be a number of radians, got 'wide'"),
    ({"psi": float("nan")}, "psi must be a finite elbow angle in radians, got nan"),
    ({"psi": "up"}, "psi must be a finite elbow angle"),
])
def test_bad_reset_options(options, needle):
    env = gym.make("KineGrasp-v0", **SMALL)
    with pytest.raises(ValueError, match=needle):
        env.reset(seed=0, options=options)
    env.close()


@pytest.mark.parametrize("sigma_range", [(0.0, 4.0), (0.0, float("inf")), (0.0, float("nan"))])
def test_sigma_range_beyond_pi_is_refused(sigma_range):
    with pytest.raises(ValueError, match="sigma_range must be 0 <= low <= high <= pi"):
        gym.make("KineGrasp-v0", sigma_range=sigma_range)


def test_discrete_select_bins_are_elbow_angles():
    env = gym.make("KineGraspSelect-v0", n_draws=4, action_bins=4).unwrapped
    assert [env.action_angle(k) for k in range(4)] == pytest.approx(
        [-np.pi, -np.pi / 2, 0.0, np.pi / 2])
    env.reset(seed=0, options={"object": "cube", "grasp": 0})
    *_, info = env.step(np.int64(2))  # psi = 0, reachable for this grasp
    assert info["within_limits"] and info["elbow_angle"] == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(ValueError, match="action 4 outside Discrete"):
        env.action_angle(4)
    for bad in (1, 2.5, True):
        with pytest.raises(ValueError, match="action_bins must be an integer >= 2"):
            gym.make("KineGraspSelect-v0", action_bins=bad)
    env.close()
