"""The IK branches of a 6-joint arm's palm pose, and `kinegrasp elbow` across them.

The arm is the xArm 6 of ``tests/test_user_robot.py`` (its description written at run time in
a data folder of this test's own; the library knows none of its names), the palm pose that of
its first planned cube grasp. Independent references: pybullet's own forward kinematics of
the URDF (``getLinkState``) for the pose each branch reaches, pybullet's joint limits for the
limits, joint differences computed here (angles wrapped where pybullet's range exceeds
2 pi) for distinctness, and ``kinegrasp evaluate`` of the grasp (same seed: the same draws)
for the nominal branch's P(FC) on the selection draws.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pybullet
import pytest
import yaml
from pybullet_utils.bullet_client import BulletClient

from kinegrasp_env.cli.main import main
from tests.test_user_robot import (
    ARM,
    DESCRIPTION,
    XARM_URDF,
    bullet_link_pose,
    bullet_palm_pose,
    run,
)

#: Draws per branch of the CLI runs (small: the protocol, not the numbers, is checked).
SAMPLES = 12
#: Arm joints (radians) of an xArm 6 configuration whose own IK branch the 200 seeded starts
#: do not find (drawn uniformly within the limits, seed 1: the first of 40 draws).
MISSED_BRANCH = [0.07427745862364432, 1.8886559163201393, -2.6610261108755267,
                 2.8189476143269747, -0.1854013078954293, -0.4817541292647971]


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The xArm 6 added to a data folder of this module's own, and two cube grasps planned
    (``plan --robot xarm6 --seed 0``): (grasp file path, its grasps as JSON)."""
    root = tmp_path_factory.mktemp("ik_branches")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("KINEGRASP_HOME", str(root / "home"))
        patch.chdir(root)
        (root / "xarm6.yaml").write_text(yaml.safe_dump(DESCRIPTION))
        assert main(["robots", "add", str(root / "xarm6.yaml")]) == 0
        assert main(["plan", "--robot", "xarm6", "--object", "cube", "--count", "1",
                     "--seed", "0", "--out", "g.json"]) == 0
        yield root / "g.json", json.loads((root / "g.json").read_text())["grasps"]


@pytest.fixture()
def home(planned, monkeypatch):
    """The module's data folder for one test."""
    monkeypatch.setenv("KINEGRASP_HOME", str(planned[0].parent / "home"))
    monkeypatch.chdir(planned[0].parent)
    return planned


def bullet_limits() -> tuple[np.ndarray, np.ndarray]:
    """(lower (6,), upper (6,)) of the arm joints as pybullet reads the URDF."""
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(str(XARM_URDF), useFixedBase=True)
        info = {client.getJointInfo(body, j)[1].decode(): client.getJointInfo(body, j)
                for j in range(client.getNumJoints(body))}
    finally:
        client.disconnect()
    return (np.array([info[n][8] for n in ARM]), np.array([info[n][9] for n in ARM]))


def rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (radians) of the rotation between two (3, 3) rotations (atan2 of its sine and
    cosine: exact near 0, where an arccos of the trace loses half the digits)."""
    r = a.T @ b
    sine = 0.5 * np.linalg.norm([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return float(np.arctan2(sine, 0.5 * (np.trace(r) - 1.0)))


def test_every_branch_reaches_the_palm_pose_and_they_differ(home):
    """Each branch puts pybullet's palm at the grasp's palm pose (position < 1e-4 m, angle
    < 1e-3 rad; measured at most 1e-7 m and 3e-8 rad on both planned cube grasps, starts seeds
    0-2: the IK stops at 1e-7 and pybullet's link states are single precision), within
    pybullet's joint limits; at least 2 branches (measured 3), pairwise more than 0.1 rad
    apart on some joint (measured: 1.99 rad at the least; the solutions merged into one
    branch agree to ~1e-6); the planner's own configuration is one of them (within 1e-3)."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.ik_branches import ik_branches

    grasp = home[1][0]
    target = np.array(grasp["palm_pose"])
    branches = ik_branches(load_robot("xarm6"), target, starts=200, seed=0)
    assert len(branches) >= 2
    lower, upper = bullet_limits()
    for b in branches:
        pose = bullet_palm_pose(b.q)
        assert np.linalg.norm(pose[:3, 3] - target[:3, 3]) < 1e-4
        assert rotation_angle(pose[:3, :3], target[:3, :3]) < 1e-3
        assert np.all(b.q >= lower - 1e-9) and np.all(b.q <= upper + 1e-9)
        assert b.hits >= 1 and b.label
    wrap = (upper - lower) > 2 * np.pi
    for i, a in enumerate(branches):
        for b in branches[i + 1:]:
            d = a.q - b.q
            d = np.where(wrap, (d + np.pi) % (2 * np.pi) - np.pi, d)
            assert np.abs(d).max() > 0.1
    assert len({b.label for b in branches}) == len(branches)
    q0 = np.array(grasp["q0"][:6])
    gaps = [np.abs(np.where(wrap, (b.q - q0 + np.pi) % (2 * np.pi) - np.pi, b.q - q0)).max()
            for b in branches]
    assert min(gaps) < 1e-3
    again = ik_branches(load_robot("xarm6"), target, starts=200, seed=0)
    assert [b.q.tolist() for b in again] == [b.q.tolist() for b in branches]  # seeded


def test_bad_input_to_ik_branches(home):
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.ik_branches import ik_branches

    robot = load_robot("xarm6")
    for pose, starts, message in [(np.eye(3), 10, "palm_pose must be a finite (4, 4)"),
                                  (np.full((4, 4), np.nan), 10, "palm_pose must be a finite"),
                                  (np.diag([2.0, 2.0, 2.0, 1.0]), 10, "not a rigid transform"),
                                  (np.diag([1.0, 1.0, -1.0, 1.0]), 10, "not a rigid transform"),
                                  (2 * np.eye(4), 10, "not a rigid transform"),
                                  (np.eye(4), 0, "starts must be an integer >= 1"),
                                  (np.eye(4), True, "starts must be an integer >= 1")]:
        with pytest.raises(ValueError, match=re.escape(message)):
            ik_branches(robot, pose, starts=starts)


def test_elbow_cli_across_the_ik_branches(home, capsys):
    """``kinegrasp elbow`` of the 6-joint arm's grasp: one line on the IK branches, every
    branch evaluated, the best chosen on the selection draws and scored on fresh ones; the
    nominal branch's selection P(FC) is ``evaluate``'s of the grasp on the same seed."""
    path, grasps = home
    args = ["elbow", "--grasps", str(path), "--grasp", "0", "--samples", str(SAMPLES),
            "--seed", "3", "--engine", "pybullet"]
    text = run(capsys, *args)
    assert "a 6-joint arm has no self-motion; the variants of cube grasp 0 are its" in text
    assert "IK branches (200 IK starts)" in text
    out = json.loads(run(capsys, *args, "--json"))
    assert out["variants"] == "ik_branches" and out["robot"] == "xarm6"
    assert out["engine"] == "pybullet" and out["samples"] == SAMPLES
    n = len(out["branches"])
    assert n >= 2 and len(out["curve"]) == n and f"its {n} IK branches" in text
    selection = [p["p_fc"] for p in out["curve"]]
    assert out["best_branch"] == int(np.argmax(selection))
    assert out["best_p_fc"] == out["curve"][out["best_branch"]]["fresh_p_fc"]
    cert = out["certificate"]
    assert cert["chosen_branch"] == out["best_branch"] and len(cert["rivals"]) == n - 1
    assert "IK branch" in cert["statement"]
    nominal = out["nominal_branch"]
    assert out["branches"][nominal]["q"] == grasps[0]["q0"][:6]
    alone = json.loads(run(capsys, "evaluate", "--grasps", str(path), "--grasp", "0",
                           "--samples", str(SAMPLES), "--seed", "3", "--json"))
    assert out["curve"][nominal]["p_fc"] == alone["p_fc"]
    best_q = np.array(out["best_q"])
    pose = bullet_palm_pose(best_q[:6])
    assert np.linalg.norm(pose[:3, 3] - np.array(grasps[0]["palm_pose"])[:3, 3]) < 1e-4


def test_elbow_plot_draws_each_branch(home, capsys, monkeypatch, tmp_path):
    """``elbow --plot`` of the 6-joint arm: the PNG written, its bars the printed curve's
    selection and fresh P(FC) per branch (the figure read back before it is saved)."""
    from kinegrasp_env.toolkit import elbow_plots as plots

    drawn = {}
    save = plots.save_figure

    def keep(fig, path, dpi=120):
        drawn["bars"] = [[b.get_height() for b in c] for c in fig.axes[0].containers
                         if hasattr(c, "patches")]
        return save(fig, path, dpi)

    monkeypatch.setattr(plots, "save_figure", keep)
    png = tmp_path / "branches.png"
    out = json.loads(run(capsys, "elbow", "--grasps", str(home[0]), "--grasp", "0",
                         "--samples", str(SAMPLES), "--seed", "3", "--plot", str(png),
                         "--json"))
    assert out["plot"] == str(png) and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert drawn["bars"] == [[p["p_fc"] for p in out["curve"]],
                             [p["fresh_p_fc"] for p in out["curve"]]]


def test_elbow_cli_bad_input_is_one_line(home, capsys):
    path = str(home[0])
    for args, message in [
            (["--grasps", path, "--ik-starts", "0"], "--ik-starts must be"),
            (["--grasps", path, "--method", "reweight", "--noise", "uniform"], "Gaussian"),
            (["--grasps", path, "--method", "reweight", "--batch", "1"], "--batch >= --samples"),
            (["--grasps", path, "--robot", "panda"], "xarm6"),
            (["--grasps", path, "--object", "mug"], "--object mug"),
            (["--object", "cube", "--ik-starts", "50"], "--ik-starts is for a 6-joint arm"),
            (["--robot", "panda", "--object", "cube", "--ik-starts", "50"],
             "--ik-starts is for a 6-joint arm")]:
        capsys.readouterr()
        assert main(["elbow", "--samples", "2", *args]) == 2, args
        err = capsys.readouterr().err.strip()
        assert message in err and "\n" not in err, (args, err)


def test_fig7_and_fig10_of_a_six_joint_arm_compare_its_ik_branches(home, capsys, tmp_path):
    """``reproduce fig10|fig7 --robot xarm6``: the variants are the palm pose's IK branches
    (labelled, no elbow angle), each putting the palm where the grasp has it by pybullet's
    own kinematics; fig10 has one row per branch in force closure at its nominal closing,
    fig7 the robust and the fragile one of them."""
    import csv

    from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
    from kinegrasp_env.toolkit.arm_variants import variants_of
    from kinegrasp_env.world.grasps import load_grasps

    path, grasps = home
    out = tmp_path / "f10"
    run(capsys, "reproduce", "fig10", "--robot", "xarm6", "--grasps", str(path), "--samples",
        str(SAMPLES), "--out", str(out))
    rows = list(csv.DictReader((out / "fig10.csv").open()))
    labels = [r["ik_branch"] for r in rows]
    assert len(rows) >= 2 and all(labels) and len(set(labels)) == len(labels)
    assert {r["elbow_angle"] for r in rows} == {""}
    assert sorted(r["config"] for r in rows if r["config"]) == ["fragile", "robust"]
    grasp = load_grasps(str(path))[0]
    with RobotReferenceEngine("xarm6", "cube") as engine:
        variants = variants_of(grasp, engine, 10)
    assert [v.meta["ik_branch"] for v in variants] == labels
    palm = np.asarray(grasps[0]["palm_pose"])
    for v in variants:
        pose = bullet_palm_pose(v.q0[:6])
        assert np.linalg.norm(pose[:3, 3] - palm[:3, 3]) < 1e-4
        assert rotation_angle(pose[:3, :3], palm[:3, :3]) < 1e-4
    text = run(capsys, "reproduce", "fig7", "--robot", "xarm6", "--grasps", str(path),
               "--samples", str(SAMPLES), "--out", str(tmp_path / "f7"))
    assert "robust   id 0v" in text and "IK branch det(J)" in text
    rows = list(csv.DictReader((tmp_path / "f7" / "fig7.csv").open()))
    assert [r["config"] for r in rows] == ["robust", "fragile"]
    assert all(r["ik_branch"] in labels for r in rows)


def test_elbow_report_of_the_ik_branches(home, capsys, tmp_path):
    """``elbow --report`` of the 6-joint arm: the page's bars are the printed curve's
    selection and fresh P(FC) per branch, and each view draws the arm's ``link3`` where
    pybullet's own kinematics puts it at that view's branch (the nominal and the chosen
    one: the same palm, another arm)."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.picture import robot_geometry
    from tests.test_robot_report import figure

    page = tmp_path / "branches.html"
    out = json.loads(run(capsys, "elbow", "--grasps", str(home[0]), "--grasp", "0",
                         "--samples", str(SAMPLES), "--seed", "0", "--report", str(page),
                         "--json"))
    assert out["best_branch"] != out["nominal_branch"]  # two arms: a swap would show
    html = page.read_text()
    bars = figure(html, "fig-branches")["data"]
    assert bars[0]["y"] == [p["p_fc"] for p in out["curve"]]
    assert bars[1]["y"] == [p["fresh_p_fc"] for p in out["curve"]]
    shapes = robot_geometry(load_robot("xarm6"), []).shapes
    keys = {f"robot:xarm6:{k}" for k, s in enumerate(shapes) if s.link == "link3"}
    for view, branch in (("nominal", out["nominal_branch"]), ("chosen", out["best_branch"])):
        q = np.array(out["branches"][branch]["q"])
        expected = bullet_link_pose(q, "link3")
        poses = [np.asarray(pose).reshape(3, 4)
                 for trace in figure(html, f"fig-arm-{view}")["data"]
                 if trace.get("name") == "robot (closed, nominal)"
                 for key, pose in trace["kgInstances"] if key in keys]
        assert poses
        for pose in poses:  # the link's pieces sit in its frame (visual origin: identity)
            np.testing.assert_allclose(pose[:, 3], expected[:3, 3], atol=1e-5)


def test_the_branches_as_an_elbow_coordinate(home):
    """:class:`~kinegrasp_env.robot.branch_motion.BranchMotion` on the grasp's palm pose: B
    branches, each bin's coordinate puts the arm on branch k of
    :func:`~kinegrasp_env.robot.ik_branches.ik_branches` (same starts and seed), with the
    palm where pybullet's forward kinematics says the grasp has it (1e-4 m); psi and psi + 2 pi
    are one branch; the coordinate of a branch's configuration is its bin's centre."""
    from kinegrasp_env.robot.branch_motion import BranchMotion
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.ik_branches import ik_branches

    grasp = home[1][0]
    q0 = np.asarray(grasp["q0"], dtype=float)
    description = load_robot("xarm6")
    motion = BranchMotion(description)
    palm = bullet_palm_pose(q0[:6])
    found = ik_branches(description, palm, seed=0)
    count = len(found)
    assert count >= 2 and motion.branches(q0).shape == (count, 6)
    for k in range(count):
        centre = -np.pi + 2.0 * np.pi * (k + 0.5) / count
        for psi in (centre, centre + 2.0 * np.pi, centre - 0.49 * 2.0 * np.pi / count):
            q, reached = motion.set_elbow_angle(q0, psi)
            assert reached
            # the same branch (branches lie > 0.1 rad apart; the IK converges to 1e-7, and
            # pybullet's palm pose is single precision: measured 1.7e-7)
            np.testing.assert_allclose(q[:6], found[k].q, atol=1e-5)
            np.testing.assert_allclose(q[6:], q0[6:])
        assert motion.elbow_angle(q[None])[0] == pytest.approx(centre, abs=1e-12)
        reached = bullet_palm_pose(q[:6])
        assert np.abs(reached[:3, 3] - palm[:3, 3]).max() < 1e-4


def test_the_elbow_search_and_the_env_see_the_same_branches(home, capsys):
    """``kinegrasp elbow`` at two run seeds and the envs' branch coordinate
    (:class:`~kinegrasp_env.robot.branch_motion.BranchMotion`) list the same IK branches in
    the same order: the branch search's starts do not follow the run's noise seed, so the
    branch an optimizer chooses is the env's bin of the same index. The nominal branch is the
    grasp's own joints in the search and the IK's solution in the env (within the branches'
    merge tolerance, 1e-3 rad); every other branch is the same solution to the bit. A
    configuration whose own branch the starts miss is added last by both."""
    from kinegrasp_env.robot.branch_motion import BranchMotion
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.ik_branches import MERGE_TOL

    path, grasps = home
    runs = [json.loads(run(capsys, "elbow", "--grasps", str(path), "--grasp", "0",
                           "--samples", str(SAMPLES), "--seed", seed, "--json"))
            for seed in ("3", "11")]
    found = [[b["q"] for b in out["branches"]] for out in runs]
    assert found[0] == found[1]
    env = BranchMotion(load_robot("xarm6")).branches(np.asarray(grasps[0]["q0"], float))
    assert env.shape == (len(found[0]), 6)
    nominal = runs[0]["nominal_branch"]
    for k, q in enumerate(found[0]):
        if k == nominal:
            assert np.abs(env[k] - q).max() < MERGE_TOL
        else:
            np.testing.assert_array_equal(env[k], q)
    # an arm configuration whose own branch the seeded starts miss (one of 40 uniform draws
    # within the limits): both add it last, as a branch of its own
    import dataclasses

    from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
    from kinegrasp_env.robot.kinematics import Kinematics
    from kinegrasp_env.toolkit.elbow_search import branch_variants
    from kinegrasp_env.world.grasps import load_grasps

    description = load_robot("xarm6")
    q = np.asarray(grasps[0]["q0"], dtype=float)
    q[:6] = MISSED_BRANCH
    pose = Kinematics(description.model).pose(q[None], description.palm_link)[0]
    grasp = dataclasses.replace(load_grasps(path)[0], q0=q, palm_pose=pose)
    with RobotReferenceEngine(description, "cube") as engine:
        search, own = branch_variants(grasp, engine, 200)
    assert search[own].label == "nominal" and own == len(search) - 1
    np.testing.assert_array_equal(np.array([b.q for b in search]),
                                  BranchMotion(description).branches(q))


def test_the_env_moves_a_six_joint_arm_across_its_branches(home, monkeypatch):
    """``KineGrasp-v0`` of the xArm 6: the elbow coordinate the agent moves crosses a bin's
    edge and the arm changes branch (the palm pose kept); the observation shows the
    coordinate moved to; Gymnasium's ``check_env`` passes both envs with their renderings."""
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import kinegrasp_env  # noqa: F401  (registers the envs)
    from kinegrasp_env.envs import render

    kwargs = {"robot": "xarm6", "grasp_file": str(home[0]), "n_draws": 4}
    env = gym.make("KineGrasp-v0", step_size=0.3, max_steps=30, **kwargs).unwrapped
    info = env.reset(seed=0, options={"grasp": 0, "psi": 3.5})[1]
    assert info["elbow_angle"] == pytest.approx(3.5 - 2.0 * np.pi)  # the coordinate asked
    env.reset(seed=0, options={"grasp": 0})
    motion = env.self_motion
    start, count = motion.branch_of(env.q)
    palm = bullet_palm_pose(env.q[:6])
    sine = 6 + (env.q.size - 6) + 13  # q0's arm and hand, sigma, one-hot, palm pose
    seen, psi = {start}, env._psi
    for _ in range(int(np.ceil(2.0 * np.pi / 0.3)) + 1):
        obs = env.step(np.array([1.0, -1.0], dtype=np.float32))[0]
        psi = (psi + 0.3 + np.pi) % (2.0 * np.pi) - np.pi
        assert env._psi == pytest.approx(psi, abs=1e-9)
        assert np.arctan2(*obs[sine:sine + 2]) == pytest.approx(psi, abs=1e-6)
        seen.add(motion.branch_of(env.q)[0])
        assert np.abs(bullet_palm_pose(env.q[:6])[:3, 3] - palm[:3, 3]).max() < 1e-4
    assert seen == set(range(count))
    env.close()
    monkeypatch.setattr(render, "display_available", lambda: False)  # headless anywhere
    for name in ("KineGrasp-v0", "KineGraspSelect-v0"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(gym.make(name, render_mode="rgb_array", **kwargs).unwrapped)
        others = [str(w.message) for w in caught if w.category is not render.NoDisplayWarning]
        assert not others, others  # only the human mode's note that there is no display


def test_the_env_of_a_six_joint_arm_takes_a_per_joint_noise(home):
    """A noise model with one sigma per arm joint (6 for the xArm 6): the env's info shows the
    largest, as the observation does."""
    import gymnasium as gym

    import kinegrasp_env  # noqa: F401  (registers the envs)

    sigmas = [0.004, 0.006, 0.002, 0.009, 0.001, 0.003]
    env = gym.make("KineGrasp-v0", robot="xarm6", grasp_file=str(home[0]), n_draws=4,
                   noise_model={"joints": {"sigma": sigmas}}).unwrapped
    obs, info = env.reset(seed=0, options={"grasp": 0})
    assert info["sigma"] == max(sigmas)
    sigma_entry = 6 + (env.q.size - 6)  # after q0's arm and hand joints, scaled by 0.05 rad
    assert obs[sigma_entry] == pytest.approx(max(sigmas) / 0.05)
    assert env.step(np.zeros(2, dtype=np.float32))[-1]["sigma"] == max(sigmas)
    env.close()


def test_plan_variants_of_a_six_joint_arm_are_its_branches(home, capsys):
    """``plan --robot xarm6 --variants 3``: each grasp's variants put pybullet's palm at the
    grasp's palm pose (1e-4 m), differ pairwise by > 0.1 rad on some joint, name their branch,
    and one of them is the grasp's own configuration."""
    assert main(["plan", "--robot", "xarm6", "--object", "cube", "--count", "1", "--seed",
                 "0", "--variants", "3", "--out", "variants.json"]) == 0
    assert "IK-branch variants" in capsys.readouterr().out
    grasps = json.loads(open("variants.json").read())["grasps"]
    nominal, variants = grasps[0], [g for g in grasps if g["id"].startswith("0v")]
    assert len(variants) >= 2 and all(g["meta"]["ik_branch"] for g in variants)
    palm = bullet_palm_pose(np.asarray(nominal["q0"])[:6])
    arms = np.array([g["q0"][:6] for g in variants])
    for arm in arms:
        assert np.abs(bullet_palm_pose(arm)[:3, 3] - palm[:3, 3]).max() < 1e-4
    gaps = [np.abs(np.angle(np.exp(1j * (a - b)))).max()
            for i, a in enumerate(arms) for b in arms[i + 1:]]
    assert min(gaps) > 0.1
    assert np.abs(np.angle(np.exp(1j * (arms - np.asarray(nominal["q0"])[:6])))).max(
        axis=1).min() < 1e-3


@pytest.mark.parametrize("count", range(1, 17))
def test_every_bins_lower_edge_is_its_own_branch(count):
    """With B branches, the coordinate -pi + 2 pi k / B (what ``KineGraspSelect-v0`` with
    ``action_bins=B`` asks for bin k) is on branch k for every k, as is the bin's centre;
    B = 6, k = 1 rounded down to branch 0 when the edge was not its bin's own."""
    from kinegrasp_env.robot.branch_motion import BranchMotion

    class Stub(BranchMotion):
        def __init__(self):
            self.arm = 1

        def branches(self, q):
            return np.arange(count, dtype=float)[:, None]

    motion = Stub()
    for k in range(count):
        for psi in (-np.pi + 2.0 * np.pi * k / count, -np.pi + 2.0 * np.pi * (k + 0.5) / count):
            q, reached = motion.set_elbow_angle(np.array([99.0, 5.0]), psi)
            assert reached and q[0] == k and q[1] == 5.0


def test_evaluate_elbow_of_a_six_joint_arm_takes_the_branch_of_its_bin(home, capsys):
    """``evaluate --elbow PSI`` of the xArm 6 evaluates the grasp on the IK branch whose bin
    holds PSI: the same P(FC), on the same draws, as the grasp written with that branch's arm
    joints (branch k of :func:`~kinegrasp_env.robot.ik_branches.ik_branches`, found here)."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.ik_branches import ik_branches

    grasp = home[1][0]
    q0 = np.asarray(grasp["q0"], dtype=float)
    found = ik_branches(load_robot("xarm6"), bullet_palm_pose(q0[:6]), seed=0)
    k = len(found) - 1
    psi = -np.pi + 2.0 * np.pi * (k + 0.5) / len(found)
    common = ["--grasp", "0", "--samples", str(SAMPLES), "--engine", "fast", "--json"]
    assert main(["evaluate", "--grasps", str(home[0]), "--elbow", f"{psi:.6f}", *common]) == 0
    moved = json.loads(capsys.readouterr().out)
    data = json.loads(home[0].read_text())
    data["grasps"] = [{**grasp, "q0": [*found[k].q.tolist(), *grasp["q0"][6:]]}]
    Path("branch.json").write_text(json.dumps(data))
    assert main(["evaluate", "--grasps", "branch.json", *common]) == 0
    direct = json.loads(capsys.readouterr().out)
    assert moved["grasp"] == f"0@{psi:.3f}"
    assert moved["p_fc"] == direct["p_fc"] and moved["outcomes"] == direct["outcomes"]


def test_the_six_joint_flange_jacobian_is_its_kinematics_derivative(home):
    """The re-weighting's body Jacobian of the xArm 6's flange (6 x 6) is the derivative of
    the flange pose: central differences of the forward kinematics (h = 1e-6 rad), each
    column to 1e-6."""
    from kinegrasp_env.closing.hand_errors import flange_link
    from kinegrasp_env.montecarlo.palm_batch import PalmJacobian
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.kinematics import Kinematics, rotation_log

    description = load_robot("xarm6")
    kin, flange = Kinematics(description.model), flange_link(description)
    q = np.asarray(home[1][0]["q0"], dtype=float)
    jac = PalmJacobian(description)(q)[0]
    assert jac.shape == (6, 6)
    base, h = kin.pose(q[None], flange)[0], 1e-6
    for j in range(6):
        step = np.zeros_like(q)
        step[j] = h
        rel = [np.linalg.inv(base) @ kin.pose((q + sign * step)[None], flange)[0]
               for sign in (1, -1)]
        twist = np.concatenate([(rel[0][:3, 3] - rel[1][:3, 3]) / (2 * h),
                                (rotation_log(rel[0][:3, :3]) - rotation_log(rel[1][:3, :3]))
                                / (2 * h)])
        np.testing.assert_allclose(jac[:, j], twist, atol=1e-6)


def test_reweighted_branches_agree_with_direct_draws(home, capsys):
    """``elbow --method reweight`` of the 6-joint arm: every IK branch's P(FC) from one batch
    agrees with 2,000 direct draws at that branch within 3 combined standard errors (the
    weights' delta-method error and the binomial one; an independent estimate: the branch's
    own joint noise closed by the engine); the best branch is the batch's best; the command
    prints the batch's evidence per branch and the chosen and nominal ones' fresh draws."""
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.toolkit.elbow_reweight_search import optimize_robot_branches_reweighted
    from kinegrasp_env.toolkit.elbow_search import optimize_robot_branches
    from kinegrasp_env.world.grasps import load_grasps

    grasp = load_grasps(str(home[0]))[0]
    noise, direct_draws = JointNoise(0.0133), 2000
    branches, evidence = optimize_robot_branches_reweighted(grasp, noise, 300, 0,
                                                            engine="fast", batch=3000)
    direct = optimize_robot_branches(grasp, noise, direct_draws, 0, evaluate_with="fast")
    assert [b.label for b in branches.branches] == [b.label for b in direct.branches]
    for c, p in zip(evidence.curve, direct.result.curve, strict=True):
        assert not c.fallback
        se = np.hypot(c.se, np.sqrt(p.p_fc * (1 - p.p_fc) / direct_draws))
        assert abs(c.point.p_fc - p.p_fc) <= 3 * se, (c.point.psi, c.point.p_fc, p.p_fc)
    assert branches.best == int(np.argmax([c.point.p_fc for c in evidence.curve]))
    args = ["elbow", "--grasps", str(home[0]), "--grasp", "0", "--samples", "100",
            "--method", "reweight", "--engine", "fast"]
    text = run(capsys, *args)
    assert "IK branches from one batch of 200 closings" in text
    assert "re-weighted to every branch" in text and "at the best branch" in text
    out = json.loads(run(capsys, *args, "--json"))
    assert out["variants"] == "ik_branches" and out["reweight"]["batch"] == 200
    fresh = {p["branch"] for p in out["curve"] if "fresh_p_fc" in p}
    assert fresh == {out["best_branch"], out["nominal_branch"]}
    assert "re-weighted advantage" in out["certificate"]["method"]


def test_a_branch_whose_arm_collides_is_left_out_of_the_batch(home, capsys, monkeypatch,
                                                               tmp_path):
    """The batch is closed with the arm of the grasp's own branch and cannot see another
    branch's arm in the object: a branch whose clearance is not positive is left out of the
    re-weighted search (its curve, JSON and plot), and the summary names it. The branch is
    made to collide by the clearance query the search asks (this grasp's branches all
    clear the cube); the query itself is tested with the planner."""
    from kinegrasp_env.toolkit import elbow_reweight_search
    from kinegrasp_env.world.grasps import load_grasps

    real, own = elbow_reweight_search.clearance, load_grasps(str(home[0]))[0].q0

    def blocked(engine, q):
        return real(engine, q) if np.allclose(q, own) else -0.01

    monkeypatch.setattr(elbow_reweight_search, "clearance", blocked)
    args = ["elbow", "--grasps", str(home[0]), "--grasp", "0", "--samples", "60",
            "--method", "reweight", "--engine", "fast", "--plot", str(tmp_path / "b.png")]
    out = json.loads(run(capsys, *args, "--json"))
    assert [p["branch"] for p in out["curve"]] == [out["nominal_branch"]]
    assert len(out["branches"]) == 3 and (tmp_path / "b.png").stat().st_size > 0
    text = run(capsys, *args[:-2])
    left = [b for b in range(3) if b != out["nominal_branch"]]
    for b in left:
        assert f"branch {b} (" in text and "left out, its arm meets the object" in text


def test_the_reweighted_branch_plot_shows_why(home, capsys, monkeypatch, tmp_path):
    """``elbow --method reweight --plot`` of the 6-joint arm: beside the bars, the batch's
    deviations in the fragile directions (whitened by the nominal branch's covariance, so
    the nominal branch's 2-s.d. ellipse is the circle of radius 2, to 1e-9) and the chosen
    branch's ellipse."""
    from kinegrasp_env.toolkit import elbow_plots as plots

    drawn = {}
    save = plots.save_figure

    def keep(fig, path, dpi=120):
        right = fig.axes[1]
        drawn["lines"] = {line.get_label(): line.get_xydata() for line in right.get_lines()}
        return save(fig, path, dpi)

    monkeypatch.setattr(plots, "save_figure", keep)
    png = tmp_path / "why.png"
    run(capsys, "elbow", "--grasps", str(home[0]), "--grasp", "0", "--samples", "300",
        "--method", "reweight", "--engine", "fast", "--plot", str(png))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    nominal = drawn["lines"]["nominal branch, 2 s.d."]
    np.testing.assert_allclose(np.linalg.norm(nominal, axis=1), 2.0, atol=1e-9)
    assert "best branch, 2 s.d." in drawn["lines"]
    # the page draws the same: its chart of why, the nominal ellipse the radius-2 circle
    # (to the 4 digits the page stores)
    from tests.test_robot_report import figure

    page = tmp_path / "why.html"
    run(capsys, "elbow", "--grasps", str(home[0]), "--grasp", "0", "--samples", "300",
        "--method", "reweight", "--engine", "fast", "--report", str(page))
    traces = {t["name"]: t for t in figure(page.read_text(), "fig-fragility")["data"]}
    ring = np.column_stack([traces["nominal branch, 2 s.d."]["x"],
                            traces["nominal branch, 2 s.d."]["y"]])
    np.testing.assert_allclose(np.linalg.norm(ring, axis=1), 2.0, atol=2e-4)
    assert "best branch, 2 s.d." in traces and "Why this branch" in page.read_text()


def test_the_batch_reward_of_a_six_joint_arm_agrees_with_direct_draws(home):
    """``reward="batch"`` of the xArm 6: one batch over every IK branch; at the states of a
    rollout that crosses branches, the reward is within four combined standard errors plus
    0.015 (the Gaussian model's bias allowed, as for the Panda) of 2,000 direct draws of the
    same configuration and noise."""
    import dataclasses

    import gymnasium as gym

    import kinegrasp_env  # noqa: F401  (registers the envs)
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp

    env = gym.make("KineGrasp-v0", robot="xarm6", grasp_file=str(home[0]), reward="batch",
                   batch_size=2000, step_size=0.5).unwrapped
    env.reset(seed=0, options={"grasp": 0, "sigma": 0.0133})
    motion = env.self_motion
    q0 = np.asarray(env.grasp.q0, dtype=float)
    own, count = motion.branch_of(q0)
    covered = env._covered_configurations(q0)  # the batch's mixture: every other branch
    assert sorted(motion.branch_of(q)[0] for q in covered) == sorted(set(range(count)) - {own})
    palm = bullet_palm_pose(q0[:6])
    for q in covered:
        assert np.abs(bullet_palm_pose(q[:6])[:3, 3] - palm[:3, 3]).max() < 1e-4
    seen = set()
    for _ in range(6):
        _, _, _, _, info = env.step(np.array([1.0, -1.0], dtype=np.float32))
        branch = motion.branch_of(env.q)[0]
        if info["reward_method"] != "batch" or branch in seen:
            continue
        seen.add(branch)
        here = dataclasses.replace(env.grasp, q0=env.q.copy())
        direct = evaluate_grasp(here, sigma=0.0133, n=2000, seed=9, engine="fast").p_fc
        lo, hi = info["p_fc_ci"]
        se = np.hypot((hi - lo) / (2 * 1.96), np.sqrt(direct * (1 - direct) / 2000))
        assert abs(info["p_fc"] - direct) <= 4 * se + 0.015, (info, direct)
    assert len(seen) >= 2
    env.close()


def test_a_six_joint_arms_batch_size_is_checked_against_its_branches(home):
    """A 6-joint arm's batch covers the grasp's IK branches, known at its first batch: a
    batch_size enough for them (one per target beside the defensive share) is taken at
    construction and reset, one closing fewer is refused at the reset, naming both."""
    from kinegrasp_env.envs.batch_reward import sigma_levels
    from kinegrasp_env.envs.kinegrasp import KineGraspEnv
    from kinegrasp_env.sampling.reweight import least_batch

    probe = KineGraspEnv(robot="xarm6", grasp_file=str(home[0]), reward="batch",
                         batch_size=4096)
    probe.reset(seed=0, options={"grasp": 0, "sigma": 0.0133})
    q0 = np.asarray(probe.grasp.q0, dtype=float)
    targets = (1 + len(probe._covered_configurations(q0))) * len(sigma_levels(
        *probe.sigma_range))
    need = least_batch(targets)
    env = KineGraspEnv(robot="xarm6", grasp_file=str(home[0]), reward="batch",
                       batch_size=need)
    env.reset(seed=0, options={"grasp": 0, "sigma": 0.0133})
    assert len(env._batch.batch) == need
    small = KineGraspEnv(robot="xarm6", grasp_file=str(home[0]), reward="batch",
                         batch_size=need - 1)
    with pytest.raises(ValueError, match=f"^batch_size {need - 1} is too small for cube grasp "
                                         f"0: a batch of {need - 1} closings cannot cover "
                                         f"{targets} targets"):
        small.reset(seed=0, options={"grasp": 0, "sigma": 0.0133})


def test_fig10_of_a_six_joint_arm_from_one_batch(home, capsys, tmp_path):
    """fig10 of the xArm 6 with ``method="reweight"`` (at sigma 0.0233 rad, where the cube
    grasp's branches fail often enough for the weights to matter): one row per IK branch
    (the direct run's branches), each branch's P(FC) re-weighted from one batch within 3
    combined standard errors of that branch's 1,500 direct draws (independent closings of
    its own joint noise); the command line takes the method too."""
    from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine, evaluate_grasp
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit.arm_variants import variants_of
    from kinegrasp_env.toolkit.experiments import fig10
    from kinegrasp_env.world.grasps import load_grasps

    grasp = load_grasps(str(home[0]))[0]
    rows = fig10(load_robot("xarm6"), tmp_path / "f10", grasp_sets={"cube": [grasp]},
                 samples=400, sigma=0.0233, engine="fast", method="reweight")
    with RobotReferenceEngine("xarm6", "cube") as engine:
        variants = {v.id: v for v in variants_of(grasp, engine, 10)}
    assert sorted(r["id"] for r in rows) == sorted(variants)
    for row in rows:
        p, ess = row["p_fc"], row["samples"]
        assert ess >= 400 and p < 0.95  # re-weighted (not the fall-back), and informative
        direct = evaluate_grasp(variants[row["id"]], sigma=0.0233, n=1500, seed=11,
                                engine="fast").p_fc
        se = np.hypot(np.sqrt(p * (1 - p) / ess), np.sqrt(direct * (1 - direct) / 1500))
        assert abs(p - direct) <= 3 * se, (row, direct)
    text = run(capsys, "reproduce", "fig10", "--robot", "xarm6", "--grasps", str(home[0]),
               "--samples", "100", "--engine", "fast", "--method", "reweight", "--out",
               str(tmp_path / "cli"))
    assert ("chosen on one batch of 200 closings re-weighted to every candidate (seed 0), "
            "reported on 100 fresh draws (chunk 1)") in text
