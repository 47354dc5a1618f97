"""Every command for every robot: the paper's KUKA + SDH, the Panda, and a robot a user adds
(the xArm 6 of pybullet_data, its description written here at run time), each planning its
own cube grasps and running the same command lines on them.

What it proves: a command that runs for one robot runs for each, from a grasp file alone
(the file names its robot; no ``--robot`` given), and says which robot it ran where its
output has the field. The numbers themselves are checked against independent references in
each command's own tests; here the draws are few.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from cli_helpers import run_in_process

from kinegrasp_env.cli.main import main
from tests.test_user_robot import DESCRIPTION

ROBOTS = ("kuka_sdh", "panda", "xarm6")
#: A noise model of every source a robot's engines take (joints, palm, object, friction).
SPEC = {"joints": {"sigma": 0.01}, "palm": {"translation_sigma": 0.001},
        "object": {"translation_sigma": 0.001}, "friction": {"sigma": 0.05}}
#: A hand source every robot's hand takes (one closing sigma: radians or metres).
HAND = {"hand": {"closing_sigma": 0.01}}
#: The command lines ({g}: the robot's grasp file, {o}: an output path of its own, {r}: the
#: robot, for a command that reads no grasp file); the last item names a file the command
#: must write (or None).
COMMANDS = {
    "evaluate": (["evaluate", "--grasps", "{g}", "--grasp", "0", "--sigma", "0.01",
                  "--samples", "6", "--json"], None),
    "evaluate --noise-spec": (["evaluate", "--grasps", "{g}", "--grasp", "0", "--noise-spec",
                               "spec.yaml", "--samples", "6", "--json"], None),
    "evaluate --static-hold --hold-test": (["evaluate", "--grasps", "{g}", "--grasp", "0",
                                            "--sigma", "0.01", "--samples", "3",
                                            "--static-hold", "--hold-test", "--json"], None),
    "rank": (["rank", "{g}", "--sigma", "0.01", "--samples", "6", "--json", "--out",
              "{o}.csv"], "{o}.csv"),
    "rank --criterion hold_static": (["rank", "{g}", "--sigma", "0.01", "--samples", "6",
                                      "--criterion", "hold_static", "--out", "{o}.csv"],
                                     "{o}.csv"),
    "rank --criterion hold": (["rank", "{g}", "--sigma", "0.01", "--samples", "2",
                               "--criterion", "hold", "--out", "{o}.csv"], "{o}.csv"),
    "rank --criterion hold --noise-spec": (["rank", "{g}", "--noise-spec", "hand.yaml",
                                            "--samples", "2", "--criterion", "hold", "--out",
                                            "{o}.csv"], "{o}.csv"),
    "rank --adaptive": (["rank", "{g}", "--samples", "30", "--adaptive", "--top-k", "1",
                         "--out", "{o}.csv"], "{o}.csv"),
    "rank --adaptive --criterion hold_static": (["rank", "{g}", "--samples", "30",
                                                 "--adaptive", "--top-k", "1", "--criterion",
                                                 "hold_static", "--out", "{o}.csv"],
                                                "{o}.csv"),
    "evaluate --noise-spec hand": (["evaluate", "--grasps", "{g}", "--grasp", "0",
                                    "--noise-spec", "hand.yaml", "--samples", "6", "--json"],
                                   None),
    "elbow --method reweight": (["elbow", "--grasps", "{g}", "--grasp", "0", "--samples", "6",
                                 "--batch", "100", "--method", "reweight", "--engine", "fast",
                                 "--json"], None),
    "elbow": (["elbow", "--grasps", "{g}", "--grasp", "0", "--samples", "6", "--json"], None),
    "report": (["report", "--grasps", "{g}", "--grasp", "0", "--samples", "6", "--out",
                "{o}.html"], "{o}.html"),
    "reproduce fig9": (["reproduce", "fig9", "--grasps", "{g}", "--samples", "4", "--out",
                        "{o}"], "{o}/fig9.csv"),
    "reproduce table1": (["reproduce", "table1", "--grasps", "{g}", "--samples", "4", "--out",
                          "{o}"], "{o}/table1.csv"),
    "reproduce fig7": (["reproduce", "fig7", "--grasps", "{g}", "--samples", "4", "--out",
                        "{o}"], "{o}/fig7.csv"),
    "reproduce fig10": (["reproduce", "fig10", "--grasps", "{g}", "--samples", "4", "--out",
                         "{o}"], "{o}/fig10.csv"),
    "reproduce fig10 --method reweight": (["reproduce", "fig10", "--grasps", "{g}",
                                           "--samples", "8", "--method", "reweight", "--out",
                                           "{o}"], "{o}/fig10.csv"),
    "ee": (["ee", "--robot", "{r}", "--samples", "50", "--json"], None),
    "validate": (["validate", "--grasps", "{g}", "--grasp", "0", "--samples", "1",
                  "--sigma", "0", "--json", "--out", "{o}"], "{o}/summary.json"),
    "validate --simulator mujoco": (["validate", "--grasps", "{g}", "--grasp", "0",
                                     "--samples", "1", "--sigma", "0", "--simulator",
                                     "mujoco", "--json", "--out", "{o}"], "{o}/summary.json"),
    "sensitivity": (["sensitivity", "--grasps", "{g}", "--grasp", "0", "--noise-spec",
                     "spec.yaml", "--samples", "6"], None),
}


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """A data folder of this module's own with the xArm 6 added, and three cube grasps
    planned for each robot (``plan --robot R --seed 0``): the folder."""
    root = tmp_path_factory.mktemp("every_robot")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("KINEGRASP_HOME", str(root / "home"))
        patch.chdir(root)
        (root / "xarm6.yaml").write_text(yaml.safe_dump(DESCRIPTION))
        (root / "spec.yaml").write_text(yaml.safe_dump(SPEC))
        (root / "hand.yaml").write_text(yaml.safe_dump(HAND))
        assert main(["robots", "add", str(root / "xarm6.yaml")]) == 0
        for robot in ROBOTS:
            assert main(["plan", "--robot", robot, "--object", "cube", "--count", "3",
                         "--seed", "0", "--out", f"{robot}.json"]) == 0
        yield root


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("robot", ROBOTS)
def test_the_command_runs_for_the_robot(workspace, monkeypatch, capsys, robot, command):
    if "mujoco" in command:
        pytest.importorskip("mujoco")
    monkeypatch.setenv("KINEGRASP_HOME", str(workspace / "home"))
    monkeypatch.chdir(workspace)
    grasps = f"{robot}.json"
    assert json.loads(Path(grasps).read_text()).get("robot", "kuka_sdh") == robot
    words, written = COMMANDS[command]
    out = f"out_{robot}_{command.replace(' ', '_').replace('-', '')}"
    argv = [w.format(g=grasps, o=out, r=robot) for w in words]
    text = run_in_process(capsys, *argv)
    if written is not None:
        assert Path(written.format(o=out)).is_file(), (argv, text)
    if "--json" in argv and command.split()[0] == "evaluate":
        assert json.loads(text)["robot"] == robot
    if command == "ee":
        assert json.loads(text)["robot"] == robot
    if command.startswith("reproduce"):
        rows = Path(written.format(o=out)).read_text().splitlines()
        assert len(rows) >= 2 and all(row.split(",")[0] == robot for row in rows[1:]
                                      if rows[0].startswith("robot,"))
    if "--json" in argv and command.split()[0] == "elbow":
        assert json.loads(text).get("robot", "kuka_sdh") == robot
    if "--static-hold" in argv:
        assert 0.0 <= json.loads(text)["p_hold_static"] <= 1.0
        assert 0.0 <= json.loads(text)["p_hold"] <= 1.0
    if "--criterion" in argv:
        column = "p_hold" if "hold" in argv else "p_hold_static"
        assert column in Path(written.format(o=out)).read_text().splitlines()[0].split(",")
    if command.startswith("validate"):
        summary = json.loads(Path(written.format(o=out)).read_text())
        assert summary["settings"].get("robot", "kuka_sdh") == robot
        assert summary["settings"]["simulator"] == command.split()[-1].replace(
            "validate", "pybullet")


def test_evaluate_prints_one_record_for_every_robot(workspace, monkeypatch, capsys):
    """``evaluate --json`` prints the same keys whichever robot ran (the robot, object and
    grasp, the engine, Q's moments and the nominal-minus-mean error among them), and a hand
    whose one motor moves both jaws (the Panda's) the jaws' push besides: a script that
    reads one robot's record reads another's."""
    monkeypatch.setenv("KINEGRASP_HOME", str(workspace / "home"))
    monkeypatch.chdir(workspace)
    for noise in (["--sigma", "0.01"], ["--noise-spec", "spec.yaml"]):
        keys = {}
        for robot in ROBOTS:
            text = run_in_process(capsys, "evaluate", "--grasps", f"{robot}.json", "--grasp",
                                  "0", *noise, "--samples", "4", "--json")
            keys[robot] = set(json.loads(text))
        assert {"robot", "object", "grasp", "engine", "q_var", "error"} <= keys["kuka_sdh"]
        assert "jaw_push_mm" in keys["panda"]
        assert keys["panda"] - {"jaw_push_mm"} == keys["kuka_sdh"] == keys["xarm6"], keys
        # a spec's friction source draws mu per draw: no one friction then
        assert ("friction" in keys["kuka_sdh"]) == (noise[0] == "--sigma")
        assert ("noise_model" in keys["kuka_sdh"]) == (noise[0] == "--noise-spec")


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_env_takes_the_robots_grasp_file(workspace, monkeypatch, robot):
    """``KineGraspSelect-v0`` on the robot's planned grasps: a step's reward is a P(FC) in
    [0, 1] (a 6-joint arm chooses among its IK branches)."""
    import gymnasium as gym
    import numpy as np

    import kinegrasp_env  # noqa: F401  (registers the envs)

    monkeypatch.setenv("KINEGRASP_HOME", str(workspace / "home"))
    monkeypatch.chdir(workspace)
    kwargs = {"robot": robot, "grasp_file": f"{robot}.json", "n_draws": 4}
    env = gym.make("KineGraspSelect-v0", **kwargs)
    env.reset(seed=0)
    _, reward, terminated, _, _ = env.step(np.array([0.2], dtype=np.float32))
    assert terminated and 0.0 <= reward <= 1.0
    env.close()
