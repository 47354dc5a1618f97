"""Gymnasium environments: API checks, determinism, the self-motion action, the reward."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from env_helpers import check_reward_is_the_evaluation

import kinegrasp_env
from kinegrasp_env import ENV_IDS
from kinegrasp_env.robot.default_robot import ELBOW_LINK, PALM_LINK
from kinegrasp_env.robot.kinematics import pose_error

# the reference engine: these tests hold the env to it exactly (the default is "fast")
SMALL = {"n_draws": 8, "engine": "pybullet"}
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
    kin = env.kinematics
    palm0 = kin.pose(env.q, PALM_LINK)
    elbow0 = kin.pose(env.q, ELBOW_LINK)[0, :3, 3]
    env.step(np.array([0.8, -1.0], dtype=np.float32))
    assert np.abs(pose_error(kin.pose(env.q, PALM_LINK), palm0)).max() < 1e-6
    assert np.linalg.norm(kin.pose(env.q, ELBOW_LINK)[0, :3, 3] - elbow0) > 0.01
    env.close()


@pytest.mark.parametrize("n_draws", [32, 300])
def test_reward_equals_the_evaluation_engine(n_draws):
    """Plumbing, not the estimate: the reward is the evaluation of the env's current
    configuration with the draw seed it reports (a wrong configuration, seed or draw count in
    the env fails it; 300 draws span two of the evaluation's chunks); the estimate itself is
    checked by the engines' tests."""
    env = gym.make("KineGrasp-v0", n_draws=n_draws).unwrapped
    env.reset(seed=5, options={"object": "spray_flask", "grasp": 1, "sigma": 0.02})
    _, reward, _, _, info = env.step(np.array([0.5, -1.0], dtype=np.float32))
    assert 0 < info["outcomes"]["force_closure"] < n_draws  # not a trivial 0 or 1
    check_reward_is_the_evaluation(env, reward, info)
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


@pytest.mark.parametrize("env_id", ["KineGrasp-v0", "KineGraspSelect-v0"])
def test_an_ended_episode_needs_a_reset(env_id):
    """After terminated or truncated, step() refuses until reset() (KineGrasp-v0 went on
    moving the elbow with fresh rewards and terminated=False); a vector env resets by
    itself and steps on."""
    env = gym.make(env_id, **SMALL, max_steps=2) if env_id == "KineGrasp-v0" else gym.make(
        env_id, **SMALL)
    env.reset(seed=0)
    stop = np.array([0.0, 1.0]) if env_id == "KineGrasp-v0" else env.action_space.sample()
    _, _, terminated, truncated, _ = env.step(stop)
    assert terminated or truncated
    with pytest.raises(RuntimeError, match="the episode has ended"):
        env.step(stop)
    env.reset(seed=0)
    env.step(stop)  # a new episode steps
    if env_id == "KineGrasp-v0":  # truncated after max_steps steps, not terminated
        env.reset(seed=0)
        go_on = np.array([0.1, -1.0])
        env.step(go_on)
        assert env.step(go_on)[3]
        with pytest.raises(RuntimeError, match="the episode has ended"):
            env.step(go_on)
    env.close()
    vec = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", **SMALL)
    vec.reset(seed=0)
    for _ in range(3):
        vec.step(vec.action_space.sample())
    vec.close()


@pytest.mark.parametrize(("options", "needle"), [
    ({"object": "teapot"}, "unknown object 'teapot'"),
    ({"sigma": -0.1}, "sigma must be finite and >= 0"),
    ({"grasp": 99, "object": "cube"}, "grasp index 99 out of range"),
    ({"colour": "red"}, r"unknown reset options \['colour'\]; the env takes object, grasp"),
    ({"sigma": 4.0}, r"^sigma must be <= pi \(3\.14159 rad\), got 4$"),
    ({"sigma": 1e308}, "must be <= pi"),
    ({"sigma": float("nan")}, "sigma must be finite"),
    ({"sigma": float("inf")}, "sigma must be finite"),
    ({"sigma": "wide"}, "sigma must be one number of radians for all arm joints .*, got 'wide'"),
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


# ----------------------------------------------------------------------------- given tasks
#: Contacts of a palm-pose task against the shipped grasp's: measured <= 5.6e-11 m over all
#: 48 shipped grasps (the IK reaches the palm pose to 1e-7 m / 1e-7 rad at worst, typically
#: ~1e-10); a 1e-8 m bound (and 1e-8 on Q).
PALM_TOL = 1e-8


@pytest.mark.parametrize(("name", "index"), [("drill", 0), ("drill", 5), ("mug", 3),
                                             ("spray_flask", 7), ("cube", 11)])
def test_q0_of_a_shipped_grasp_is_that_grasp(name, index):
    """Invariant: resetting with a shipped grasp's q0 gives the task of its grasp index: the
    hand closed at q0 by the env's engine lands on the stored nominal contacts and Q (which
    the planner recorded with the same reference engine), the same observation, and (same
    seed) the same reward."""
    from kinegrasp_env.world.grasps import shipped_grasps

    env = gym.make("KineGrasp-v0", **SMALL).unwrapped
    shipped = shipped_grasps(name)[index]
    runs = []
    for option in ({"grasp": index}, {"q0": shipped.q0.tolist()}):
        obs, info = env.reset(seed=3, options={"object": name, "sigma": 0.02, **option})
        grasp = env.grasp
        _, reward, *_ = env.step(np.array([0.4, -1.0], dtype=np.float32))
        runs.append((obs, reward, info, grasp))
    (obs0, reward0, info0, _), (obs1, reward1, info1, given) = runs
    assert given is not shipped and info1["grasp"] == "q0" and given.meta["source"] == "q0"
    np.testing.assert_array_equal(given.q0, shipped.q0)
    assert given.fingers.tolist() == shipped.fingers.tolist()
    assert given.links.tolist() == shipped.links.tolist()
    np.testing.assert_allclose(given.points, shipped.points, rtol=0, atol=1e-12)
    np.testing.assert_allclose(given.normals, shipped.normals, rtol=0, atol=1e-12)
    assert given.q_nominal == pytest.approx(shipped.q_nominal, rel=1e-9)
    np.testing.assert_allclose(given.palm_pose, shipped.palm_pose, rtol=0, atol=1e-12)
    np.testing.assert_allclose(obs1, obs0, rtol=0, atol=1e-6)
    assert reward1 == reward0
    assert {k: v for k, v in info1.items() if k != "grasp"} == {
        k: v for k, v in info0.items() if k != "grasp"}
    env.close()


@pytest.mark.parametrize(("name", "index", "form"), [("drill", 0, "quaternion"),
                                                     ("drill", 6, "pose"),
                                                     ("mug", 2, "quaternion"),
                                                     ("cube", 9, "pose")])
def test_palm_pose_of_a_shipped_grasp_gives_its_contacts(name, index, form):
    """A palm pose equal to a shipped grasp's (forward kinematics at its q0, in the object
    frame; the quaternion from scipy) gives a task with the grasp's nominal contacts and Q
    within PALM_TOL, whatever elbow the IK picks; with ``elbow`` the arm is at that angle."""
    from scipy.spatial.transform import Rotation

    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import load_object

    env = gym.make("KineGraspSelect-v0", **SMALL).unwrapped
    shipped = shipped_grasps(name)[index]
    palm_world = env.kinematics.pose(shipped.q0, PALM_LINK)[0]
    np.testing.assert_allclose(palm_world, shipped.palm_pose, atol=1e-12)  # FK = stored
    palm = np.linalg.inv(load_object(name).pose) @ palm_world
    entry = {"pose": palm.tolist()} if form == "pose" else {
        "position": palm[:3, 3].tolist(),
        "quaternion": Rotation.from_matrix(palm[:3, :3]).as_quat().tolist()}
    entry["hand"] = shipped.hand.tolist()
    psi0 = env.elbow_angle(shipped.q0)
    for elbow in (None, psi0 + 0.1):
        obs, info = env.reset(seed=0, options={"object": name, "palm_pose": {
            **entry, "elbow": elbow}, "sigma": 0.01})
        given = env.grasp
        assert info["grasp"] == "palm_pose" and obs.shape == (44,)
        assert given.fingers.tolist() == shipped.fingers.tolist()
        np.testing.assert_allclose(given.points, shipped.points, rtol=0, atol=PALM_TOL)
        np.testing.assert_allclose(given.normals, shipped.normals, rtol=0, atol=PALM_TOL)
        assert given.q_nominal == pytest.approx(shipped.q_nominal, abs=PALM_TOL)
        assert np.abs(pose_error(env.kinematics.pose(env.q, PALM_LINK), palm_world)
                      ).max() < 1e-6
        if elbow is not None:
            assert info["elbow_angle"] == pytest.approx(elbow, abs=1e-6)
    env.close()


def given_task_errors() -> list[tuple[dict, str]]:
    """(reset options, the error's words) of each bad given task (drill, shipped grasp 0)."""
    from kinegrasp_env.world.grasps import shipped_grasps

    q0 = shipped_grasps("drill")[0].q0
    swung = q0.copy()
    swung[0] += 0.8  # the arm turned away: the hand closes on air
    beyond = q0.copy()
    beyond[1] = 2.5  # joint 2's limit is 2.0944 rad
    nan = q0.copy()
    nan[9] = np.nan
    inside = {"pose": [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 0.05], [0, 0, 0, 1]],
              "spread": 0.0}  # the palm at the drill's axis, 5 cm up: the hand in the drill
    far = {"position": [1.5, 0.0, 0.8], "quaternion": [1, 0, 0, 0], "spread": 0.0}
    return [
        ({"object": "drill", "q0": q0[:13].tolist()}, "q0 must have 14 entries .*got 13"),
        ({"object": "drill", "q0": nan.tolist()}, "q0 has non-finite entries"),
        ({"object": "drill", "q0": beyond.tolist()},
         r"q0\[1\] \(lbr_iiwa_joint_2\) = 2.5000 is outside its limits"),
        ({"object": "drill", "q0": "up"}, "q0 must be 14 numbers"),
        ({"object": "drill", "q0": swung.tolist()},
         r"q0: the hand does not close on drill \(missed: "),
        ({"object": "drill", "palm_pose": inside},
         r"palm_pose: the hand does not close on drill \(start_collision: "),
        ({"object": "drill", "palm_pose": far}, "palm_pose is unreachable on drill: no IK"),
        ({"object": "drill", "palm_pose": {**far, "quaternion": [0, 0, 0, 2]}},
         "quaternion must be unit"),
        ({"object": "drill", "palm_pose": np.eye(4)}, "palm_pose must be a dict"),
        ({"object": "teapot", "q0": q0.tolist()}, "unknown object 'teapot'; known objects"),
        ({"q0": q0.tolist()}, "q0 needs the option object"),
        ({"object": "drill", "q0": q0.tolist(), "grasp": 0}, "not grasp and q0"),
        ({"object": "drill", "q0": q0.tolist(), "palm_pose": far}, "not q0 and palm_pose"),
    ]


def test_bad_given_tasks_are_value_errors():
    env = gym.make("KineGrasp-v0", **SMALL).unwrapped
    for options, needle in given_task_errors():
        with pytest.raises(ValueError, match=needle):
            env.reset(seed=0, options=options)
    env.close()


def test_imported_object_with_a_planned_q0(tmp_path, monkeypatch):
    """An imported 6 cm cube (the built-in cube's shape and frame: centre of the base at the
    object's pose) with the q0 of a planned grasp of the built-in cube (its shipped set, the
    planner's output): the task's nominal contacts are the planned ones (to the STL file's
    float32 rounding, measured 1.4e-9 m; bound 1e-8 m) and one step's reward is the
    evaluation of the imported object at the step's configuration and draw seed."""
    import trimesh

    from kinegrasp_env.world import importer
    from kinegrasp_env.world.grasps import shipped_grasps

    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    importer.forget()
    path = tmp_path / "box6.stl"
    trimesh.creation.box(extents=(0.06, 0.06, 0.06)).export(path)
    importer.import_object(path)
    planned = shipped_grasps("cube")[4]
    env = gym.make("KineGrasp-v0", **SMALL).unwrapped  # its objects: the built-in ones
    obs, info = env.reset(seed=0, options={"object": "box6", "q0": planned.q0.tolist(),
                                           "sigma": 0.01})
    assert info["object"] == "box6" and obs.shape == (44,) and np.all(np.isfinite(obs))
    np.testing.assert_allclose(env.grasp.points, planned.points, rtol=0, atol=1e-8)
    assert env.grasp.q_nominal == pytest.approx(planned.q_nominal, abs=1e-7)
    obs, reward, _, _, info = env.step(np.array([0.3, 1.0], dtype=np.float32))
    assert info["object"] == "box6" and sum(info["outcomes"].values()) == SMALL["n_draws"]
    assert obs.shape == (44,)
    check_reward_is_the_evaluation(env, reward, info)
    env.close()
    importer.forget()


def test_max_steps_is_where_an_episode_ends():
    """``max_steps`` truncates the episode, past the default 10 too (no registered
    TimeLimit overrides it)."""
    env = gym.make("KineGrasp-v0", n_draws=2, max_steps=12)
    env.reset(seed=0)
    ends = [env.step(np.zeros(2, np.float32))[3] for _ in range(12)]
    assert ends == [False] * 11 + [True]
    env.close()


def test_a_pybullet_env_refuses_to_be_copied_or_pickled():
    """An env whose engine holds a pybullet client cannot be deep-copied or pickled (a copy
    would share, then close, the original's client): a TypeError saying so, at the copy."""
    import copy
    import pickle

    env = gym.make("KineGrasp-v0", n_draws=2, engine="pybullet")
    env.reset(seed=0)
    env.step(np.zeros(2, np.float32))
    for make_copy in (copy.deepcopy, pickle.dumps):
        with pytest.raises(TypeError, match="holds a pybullet client, which cannot be copied"):
            make_copy(env)
    env.step(np.zeros(2, np.float32))  # the original still runs
    env.close()
