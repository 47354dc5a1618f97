"""KineGrasp-v0 with a robot of the catalog other than the default: the Panda."""

from __future__ import annotations

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest

import kinegrasp_env  # noqa: F401  (registers the envs)
from kinegrasp_env.montecarlo.robot_evaluate import RobotReferenceEngine, evaluate_robot_grasp
from kinegrasp_env.robot.kinematics import pose_error

#: few draws: these tests check the plumbing, not the estimate
SMALL = {"robot": "panda", "n_draws": 4}
TASK = {"object": "drill", "grasp": 1, "sigma": 0.01}


def test_unknown_robot_is_a_one_line_error_naming_the_known_ones():
    with pytest.raises(ValueError, match="unknown robot 'pandaa'") as err:
        gym.make("KineGrasp-v0", robot="pandaa")
    message = str(err.value)
    assert "\n" not in message and "kuka_sdh" in message and "panda" in message


def test_spaces_come_from_the_description():
    env = gym.make("KineGrasp-v0", **SMALL)
    # 7 arm joints twice (q0 and the current arm), 1 hand joint, 23 others
    assert env.observation_space.shape == (2 * 7 + 1 + 23,)
    assert env.action_space.shape == (2,)
    obs, info = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape and info["robot"] == "panda"
    assert info["object"] in ("cube", "drill", "spray_flask")
    env.close()


def test_default_draws_and_engine_for_the_panda():
    env = gym.make("KineGrasp-v0", robot="panda").unwrapped
    assert (env.n_draws, env.engine) == (16, "pybullet")
    env.close()


@pytest.mark.parametrize("extra", [{"engine": "fast"}, {"render_mode": "rgb_array"},
                                   {"noise_model": {"joints": {"sigma": 0.01}}}])
def test_what_the_panda_does_not_take_is_refused(extra):
    with pytest.raises(ValueError, match="robot 'panda' takes"):
        gym.make("KineGrasp-v0", robot="panda", **extra)


def test_default_robot_grasp_options_are_refused():
    env = gym.make("KineGrasp-v0", **SMALL)
    with pytest.raises(ValueError, match="reset option q0 is for the default robot"):
        env.reset(seed=0, options={"object": "drill", "q0": [0.0] * 8})
    env.close()


@pytest.mark.expensive
def test_gymnasium_and_sb3_checkers():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("KineGrasp-v0", robot="panda")  # the defaults: 16 draws a step
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
    env.close()
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make("KineGrasp-v0", **SMALL)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env.unwrapped, warn=True)
    env.close()


def rollout(seed: int, steps: int = 3) -> list[np.ndarray]:
    env = gym.make("KineGrasp-v0", **SMALL)
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        action = env.action_space.sample()
        action[1] = -1.0  # keep going
        obs, reward, _, _, info = env.step(action)
        out += [obs, np.array([reward, info["draw_seed"]])]
    env.close()
    return out


def test_same_seed_same_trajectory():
    first, again, other = rollout(3), rollout(3), rollout(4)
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert not all(np.array_equal(a, b) for a, b in zip(first, other, strict=True))


def test_action_keeps_the_palm_and_moves_the_elbow():
    """Palm and elbow from pybullet's forward kinematics (not the env's own)."""
    env = gym.make("KineGrasp-v0", **SMALL).unwrapped
    env.reset(seed=0, options=TASK)
    world = RobotReferenceEngine("panda", "drill").world
    elbow_link = env._robot.motion.angle_links[1]

    def poses(q):
        world.set_configuration(q)
        return world.link_pose("panda_hand"), world.link_pose(elbow_link)[:3, 3]

    palm0, elbow0 = poses(env.q)
    psi0 = env._psi
    _, _, _, _, info = env.step(np.array([0.8, -1.0], dtype=np.float32))
    palm1, elbow1 = poses(env.q)
    assert info["within_limits"]
    # the action is float32; Newton's residual is below 1e-9 rad
    assert abs(info["elbow_angle"] - psi0 - float(np.float32(0.8)) * env.step_size) < 1e-9
    # pybullet's poses are float32-based: 1e-6 m / rad is their rounding with a margin
    assert np.abs(pose_error(palm1, palm0)).max() < 1e-6
    assert np.linalg.norm(elbow1 - elbow0) > 0.01
    world.close()
    env.close()


def test_reward_equals_the_robot_evaluation():
    """Plumbing: the reward is evaluate_robot_grasp at the env's configuration with the
    draw seed it reports (a wrong configuration, seed, noise or draw count fails it)."""
    env = gym.make("KineGrasp-v0", robot="panda", n_draws=12).unwrapped
    env.reset(seed=1, options={"object": "spray_flask", "grasp": 1, "sigma": 0.02})
    _, reward, _, _, info = env.step(np.array([0.5, -1.0], dtype=np.float32))
    here = dataclasses.replace(env.grasp, q0=env.q.copy())
    evaluation = evaluate_robot_grasp(here, sigma=info["sigma"], n=12, seed=info["draw_seed"],
                                      noise=info["noise"])
    assert 0 < evaluation.counts["force_closure"] < 12  # not a trivial 0 or 1
    assert reward == evaluation.p_fc == info["p_fc"]
    assert info["outcomes"] == evaluation.counts
    env.close()


def test_select_env_takes_the_robot_too():
    env = gym.make("KineGraspSelect-v0", **SMALL)
    env.reset(seed=0, options=TASK)
    _, reward, terminated, _, info = env.step(np.array([0.1], dtype=np.float32))
    assert terminated and 0.0 <= reward <= 1.0 and info["draws"] == 4
    env.close()


def test_a_grasp_file_of_another_robot_is_refused(tmp_path):
    from kinegrasp_env.assets import asset_path
    from kinegrasp_env.world.grasps import load_grasps, save_grasps

    kuka = tmp_path / "kuka.json"
    save_grasps(load_grasps(asset_path("grasps", "drill.json"))[:1], kuka)
    with pytest.raises(ValueError, match="holds grasps of robot 'kuka_sdh'; make the env"):
        gym.make("KineGrasp-v0", robot="panda", grasp_file=str(kuka))
    panda = tmp_path / "panda.json"
    save_grasps(load_grasps(asset_path("grasps", "panda", "cube.json"))[:1], panda)
    with pytest.raises(ValueError, match="holds grasps of robot 'panda'; make the env"):
        gym.make("KineGrasp-v0", grasp_file=str(panda))


def test_generic_self_motion_matches_the_default_robots_compiled_one():
    """The description-driven self-motion on the KUKA against the compiled kernel of the
    default robot's chain (another implementation): 24 moves of 12 shipped grasps agree to
    1.0e-9 rad measured (tolerance 1e-8: a 10x margin) and reach the same moves."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.ik import ArmIK
    from kinegrasp_env.robot.kinematics import Kinematics
    from kinegrasp_env.robot.model import kuka_sdh
    from kinegrasp_env.robot.null_motion import ArmSelfMotion
    from kinegrasp_env.world.grasps import shipped_grasps

    generic, compiled = ArmSelfMotion(load_robot("kuka_sdh")), ArmIK(Kinematics(kuka_sdh()))
    reached = 0
    for obj in ("drill", "mug"):
        for grasp in shipped_grasps(obj)[:6]:
            psi0 = compiled.elbow_angle(grasp.q0[None])[0]
            for change in (0.3, -0.6):
                q, ok = generic.set_elbow_angle(grasp.q0, psi0 + change)
                q_ref, ok_ref = compiled.set_elbow_angle(grasp.q0, psi0 + change)
                assert ok == ok_ref[0]
                if ok:
                    reached += 1
                    assert np.abs(q - q_ref[0]).max() < 1e-8
    assert reached >= 20
