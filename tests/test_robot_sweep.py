"""``kinegrasp sweep`` and ``kinegrasp sensitivity`` of a description robot (``--robot
panda``): a sweep cell against ``kinegrasp evaluate`` of the same grasp, sigma, draws and
seed; the Sobol indices per arm joint against the estimators computed here from an
independent evaluation of the same stream; bad input refused in one line before any work.
"""

from __future__ import annotations

import csv
import json
import math
import re
import sqlite3

import numpy as np
import pytest
from cli_helpers import run_in_process as run

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli import main
from kinegrasp_env.montecarlo.chunks import close_engines
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.sweep import SUMMARY_COLUMNS, SpecError, SweepSpec
from kinegrasp_env.world.grasps import shipped_grasps

PANDA_CUBE = asset_path("grasps", "panda", "cube.json")
KUKA_CUBE = asset_path("grasps", "kuka_sdh", "cube.json")
#: cube grasp 1 of the Panda at 0.02 rad: P(FC) 0.375 over 24 draws (seed 3), so a wrong
#: draw changes the counts
GRASP, SIGMA, SEED = 1, 0.02, 3


@pytest.fixture(autouse=True, scope="module")
def _engines():
    yield
    close_engines()


def fails(capsys, *argv: str, lines: int = 1) -> str:
    """``kinegrasp ARGV`` in-process, which must fail with status 2 and write ``lines``
    lines on stderr (a sweep's first line says what it starts), the last the error; that
    line."""
    capsys.readouterr()
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == lines, err
    assert err[-1].startswith("kinegrasp ") and ": error: " in err[-1], err
    return err[-1]


def test_panda_sweep_cell_equals_evaluate(tmp_path, capsys):
    """The spec names no robot; ``--robot panda`` makes it the Panda's (its shipped cube
    set). Chunks of 7 split the 24 draws unevenly; the cell must still be ``evaluate``'s
    run of the same grasp, sigma, draws and seed (every outcome count; Q's moments to
    rounding: merged per chunk in the sweep, over all draws at once by evaluate; measured
    7e-18 apart, relative 2e-16: tolerance relative 1e-12)."""
    spec = tmp_path / "spec.yaml"
    spec.write_text(f"objects: [cube]\ngrasps: [{GRASP}]\nsigmas: [{SIGMA}]\n"
                    f"engines: [pybullet]\nsamples: 24\nchunk: 7\nseed: {SEED}\n")
    out = tmp_path / "out"
    run(capsys, "sweep", str(spec), "--out", str(out), "--robot", "panda")
    with open(out / "summary.csv") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
    assert tuple(reader.fieldnames) == ("robot", *SUMMARY_COLUMNS)
    (row,) = rows
    expected = json.loads(run(capsys, "evaluate", "--grasps", str(PANDA_CUBE), "--grasp",
                              str(GRASP), "--sigma", str(SIGMA), "--samples", "24",
                              "--seed", str(SEED), "--json"))
    assert expected["robot"] == row["robot"] == "panda"
    assert 0 < expected["p_fc"] < 1  # both outcomes occur: the comparison can fail
    assert float(row["p_fc"]) == expected["p_fc"]
    for name, count in expected["outcomes"].items():
        assert int(row[name]) == count, name
    assert math.isclose(float(row["q_mean"]), expected["q_mean"], rel_tol=1e-12)
    assert math.isclose(float(row["q_std"]), expected["q_std"], rel_tol=1e-12)
    assert float(row["q_nominal"]) == expected["q_nominal"]
    # the store is the Panda's: the same folder is not extended by the default robot
    assert "holds a sweep of robot 'panda', this one's is 'kuka_sdh' (the spec's robot, or " \
           "--robot)" in fails(
        capsys, "sweep", str(spec), "--out", str(out), lines=2)
    # nor a store of the Panda that records no layout of its draws (made before its rows
    # came in chunks)
    with sqlite3.connect(out / "results.sqlite") as db:
        db.execute("DELETE FROM meta WHERE key = 'draw_layout'")
    assert "random draws are laid out otherwise (not recorded, now 'rows of chunks of 250, " \
        in fails(capsys, "sweep", str(spec), "--out", str(out), "--robot", "panda", lines=2)
    # nor a default robot's store that records no robot (an older kinegrasp's: its draws
    # came in the spec's chunks); its store now records its robot and is extended
    kuka = tmp_path / "kuka"
    run(capsys, "sweep", str(spec), "--out", str(kuka))
    run(capsys, "sweep", str(spec), "--out", str(kuka))
    with sqlite3.connect(kuka / "results.sqlite") as db:
        db.execute("DELETE FROM meta WHERE key = 'robot'")
    assert "holds a sweep of the default robot whose random draws came in the spec's chunks" \
        in fails(capsys, "sweep", str(spec), "--out", str(kuka), lines=2)


def single_joint_spec(tmp_path, joint: int, sigma: float) -> str:
    sigmas = [0.0] * 7
    sigmas[joint] = sigma
    path = tmp_path / "joint.yaml"
    path.write_text(f"joints: {{sigma: {sigmas}, distribution: gaussian}}\n")
    return str(path)


def test_sensitivity_one_noisy_joint_against_independent_estimators(tmp_path, capsys):
    """Noise on panda_joint4 alone. A is evaluate's draws of the seed, B the next N rows of
    the same stream: here both come from one independent evaluation of 2N draws, and the
    Saltelli first-order and Jansen total estimators are computed from them directly (with
    a single noisy joint, A with that joint from B is B). The noisy joint's indices must
    equal them (to rounding, 1e-12); every frozen joint's are exactly 0; P(FC) with every
    source equals the evaluation of N draws of the seed."""
    n, joint, sigma = 48, 3, 0.03
    spec = single_joint_spec(tmp_path, joint, sigma)
    result = json.loads(run(capsys, "sensitivity", "--robot", "panda", "--object", "cube",
                            "--grasp", str(GRASP), "--noise-spec", spec, "--samples", str(n),
                            "--bootstrap", "0", "--seed", str(SEED), "--engine", "pybullet",
                            "--factors", "joints", "--json"))
    grasp = shipped_grasps("cube", "panda")[GRASP]
    sigmas = [0.0] * 7
    sigmas[joint] = sigma
    both = evaluate_grasp(grasp, sigma=tuple(sigmas), n=2 * n, seed=SEED)
    y = (both.draws.outcome == FORCE_CLOSURE).astype(float)
    y_a, y_b = y[:n], y[n:]
    variance = np.var(y, ddof=1)
    assert variance > 0  # both outcomes occur
    first = float(np.mean(y_b * (y_b - y_a)) / variance)
    total = float(0.5 * np.mean((y_a - y_b) ** 2) / variance)
    sources = {s["source"]: s for s in result["sources"]}
    assert list(sources) == [f"panda_joint{i}" for i in range(1, 8)]
    noisy = sources[f"panda_joint{joint + 1}"]
    assert math.isclose(noisy["first"], first, rel_tol=1e-12)
    assert math.isclose(noisy["total"], total, rel_tol=1e-12)
    assert noisy["p_alone"] == float(y_a.mean())
    for name, s in sources.items():
        if s is not noisy:
            assert s["first"] == 0.0 and s["total"] == 0.0, name
    assert result["dominant"] == noisy["source"]
    alone = evaluate_grasp(grasp, sigma=tuple(sigmas), n=n, seed=SEED)
    assert result["p_all"] == alone.p_fc == float(y_a.mean())
    assert result["robot"] == "panda"


@pytest.mark.parametrize(("source", "text"), [
    ("palm", "palm: {translation_sigma: 0.004, rotation_sigma: 0.03}\n"),
    ("hand", "hand: {closing_sigma: 0.015}\n")])  # a narrower start meets the cube at times
def test_sensitivity_of_one_noisy_source_against_independent_estimators(tmp_path, capsys,
                                                                         source, text):
    """A palm error or a hand offset alone (the joints exact): as for one noisy joint, the
    source's indices equal the Saltelli and Jansen estimators computed directly from one
    evaluation of 2N draws of the same spec (A its first N rows, B the next); a spec without
    a joints section has no joint factor, even with ``--factors joints``."""
    n = 40
    spec = tmp_path / f"{source}.yaml"
    spec.write_text(text)
    result = json.loads(run(capsys, "sensitivity", "--robot", "panda", "--object", "cube",
                            "--grasp", str(GRASP), "--noise-spec", str(spec), "--samples",
                            str(n), "--bootstrap", "0", "--seed", str(SEED), "--engine",
                            "fast", "--factors", "joints", "--json"))
    from kinegrasp_env.sampling.noise_spec import load_noise_model

    grasp = shipped_grasps("cube", "panda")[GRASP]
    both = evaluate_grasp(grasp, n=2 * n, seed=SEED, engine="fast",
                          noise_model=load_noise_model(spec))
    y = (both.draws.outcome == FORCE_CLOSURE).astype(float)
    y_a, y_b = y[:n], y[n:]
    variance = np.var(y, ddof=1)
    assert variance > 0
    sources = {s["source"]: s for s in result["sources"]}
    assert list(sources) == [source]  # no joints section: no joint factor
    mine = sources[source]
    assert math.isclose(mine["first"], float(np.mean(y_b * (y_b - y_a)) / variance),
                        rel_tol=1e-12)
    assert math.isclose(mine["total"], float(0.5 * np.mean((y_a - y_b) ** 2) / variance),
                        rel_tol=1e-12)
    assert result["p_all"] == float(y_a.mean())


@pytest.mark.parametrize(("change", "message"), [
    ({"robot": "pandaa"}, "unknown robot 'pandaa' (did you mean 'panda'?)"),
    ({"robot": "panda", "noise": ["gaussian", {"hand": {"spread_sigma": 0.01}}]},
     "drop hand.spread_sigma"),
    ({"robot": "panda", "engines": ["physics"],
      "noise": [{"palm": {"translation_sigma": 0.001}}]}, "not palm errors"),
    ({"robot": "panda", "objects": ["mug"]}, "robot 'panda' has no shipped grasps of 'mug'"),
    ({"robot": "panda", "grasps": [0, 4]},
     "grasp 4 does not exist for cube (its shipped set has grasps 0..3)"),
    ({"robot": "panda", "grasp_files": {"cube": str(KUKA_CUBE)}},
     "grasp_files: cube: grasp '0' is a grasp of robot 'kuka_sdh', not of 'panda'"),
    ({"robot": "kuka_sdh", "grasp_files": {"cube": str(PANDA_CUBE)}},
     "grasp_files: cube: grasp '0' is a grasp of robot 'panda', not of 'kuka_sdh'"),
])
def test_bad_robot_specs_are_named(change, message):
    spec = {"objects": ["cube"], "grasps": [0], "sigmas": [0.01], **change}
    with pytest.raises(SpecError, match=re.escape(message)):
        SweepSpec.from_dict(spec)


def test_robot_spec_key_and_override():
    """``robot:`` in the spec, and the override that replaces it; the Panda's grasps."""
    spec = SweepSpec.from_dict({"objects": ["cube"], "grasps": [1], "sigmas": [0.01],
                                "robot": "panda"})
    assert spec.robot == "panda"
    assert spec.grasp("cube", 1).robot == "panda"
    assert all(t.key.startswith("panda/cube/1/") for t in spec.tasks())
    back = SweepSpec.from_dict({"objects": ["cube"], "sigmas": [0.01], "robot": "panda"},
                               robot="kuka_sdh")
    assert back.robot == "kuka_sdh" and back.grasp("cube", 0).robot == "kuka_sdh"
    assert all(t.key.startswith("cube/") for t in back.tasks())
    with pytest.raises(SpecError, match=r"^--robot: unknown robot 'nope'"):
        SweepSpec.from_dict({"objects": ["cube"], "sigmas": [0.01]}, robot="nope")


def test_bad_robot_sensitivity_input(tmp_path, capsys):
    joint = single_joint_spec(tmp_path, 0, 0.01)
    hand = tmp_path / "hand.yaml"
    hand.write_text("joints: {sigma: 0.01}\nhand: {spread_sigma: 0.01}\n")
    base = ("sensitivity", "--robot", "panda", "--object", "cube", "--samples", "8")
    assert "drop hand.spread_sigma" in fails(
        capsys, *base, "--noise-spec", str(hand))
    assert "grasp index 9 out of range: cube has 4 grasps of robot panda" in fails(
        capsys, *base, "--noise-spec", joint, "--grasp", "9")
    assert "unknown robot 'pand'" in fails(
        capsys, "sensitivity", "--robot", "pand", "--object", "cube", "--noise-spec", joint)
    assert "no shipped grasps of 'mug'" in fails(
        capsys, "sensitivity", "--robot", "panda", "--object", "mug", "--noise-spec", joint)


def test_sensitivity_grasp_file_names_its_robot(tmp_path, capsys):
    """``--grasps`` of the Panda's file without ``--robot``: the file's robot, the same
    analysis as its shipped grasp; a grasp of one robot given to the other is refused with
    the line ``evaluate`` gives."""
    joint = single_joint_spec(tmp_path, 1, 0.02)
    args = ("--grasp", str(GRASP), "--noise-spec", joint, "--samples", "8", "--bootstrap",
            "20", "--engine", "pybullet", "--json")
    from_file = run(capsys, "sensitivity", "--grasps", str(PANDA_CUBE), *args)
    shipped = run(capsys, "sensitivity", "--robot", "panda", "--object", "cube", *args)
    assert json.loads(from_file)["robot"] == "panda"
    assert from_file == shipped
    assert "grasp '1' is a grasp of robot 'panda', not of 'kuka_sdh'" in fails(
        capsys, "sensitivity", "--grasps", str(PANDA_CUBE), "--robot", "kuka_sdh", *args)
    assert "grasp '1' is a grasp of robot 'kuka_sdh', not of 'panda'" in fails(
        capsys, "sensitivity", "--grasps", str(KUKA_CUBE), "--robot", "panda", *args)


def test_evaluate_takes_the_robots_own_shipped_grasp(capsys):
    """``evaluate --robot panda --object cube --grasp 1`` is entry 1 of the Panda's shipped
    cube set (the same JSON as naming that file), not the default robot's grasp 1 (which
    would be refused as a grasp of another robot)."""
    common = ["--grasp", "1", "--sigma", "0.0133", "--samples", "20", "--seed", "4", "--json",
              "--engine", "pybullet"]
    by_set = json.loads(run(capsys, "evaluate", "--robot", "panda", "--object", "cube", *common))
    by_file = json.loads(run(capsys, "evaluate", "--robot", "panda", "--grasps",
                             str(asset_path("grasps", "panda", "cube.json")), *common))
    assert by_set == by_file
    assert by_set["grasp"] == shipped_grasps("cube", "panda")[1].id
