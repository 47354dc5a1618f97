"""Noise models on the command line: ``evaluate``/``rank --noise-spec`` and sweep ``noise``
entries give the numbers of the library with the same model and seed."""

from __future__ import annotations

import json
import math

import pytest

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli.main import main
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.montecarlo.sweep import SpecError, SweepSpec, run_sweep
from kinegrasp_env.montecarlo.sweep_noise import cell_noise
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_spec import load_noise_model, noise_model_from_spec, spec_of
from kinegrasp_env.world.grasps import grasp_by_index, save_grasps, shipped_grasps

SPEC = "joints: {sigma: 0.02, distribution: triangular}\nobject: {translation_sigma: 0.003}\n" \
       "friction: {distribution: uniform, low: 0.3, high: 0.7}\n"


def _evaluate(grasp, noise, n, seed):
    """The library's evaluation of a JointNoise or a NoiseModel."""
    if isinstance(noise, JointNoise):
        return evaluate_grasp(grasp, sigma=noise.sigma, noise=noise.kind, n=n, seed=seed,
                              engine="fast")
    return evaluate_grasp(grasp, noise_model=noise, n=n, seed=seed, engine="fast")


@pytest.fixture()
def spec_file(tmp_path):
    path = tmp_path / "noise.yaml"
    path.write_text(SPEC)
    return path


def test_evaluate_with_a_noise_spec_is_the_library_evaluation(spec_file, capsys):
    assert main(["evaluate", "--object", "cube", "--grasp", "1", "--noise-spec",
                 str(spec_file), "--samples", "120", "--seed", "3", "--engine", "fast",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    model = load_noise_model(spec_file)
    stats = _evaluate(shipped_grasps("cube")[1], model, 120, 3)
    # the library's numbers, and what every robot's record names (no "friction": mu is per
    # draw); Q's variance and the error (q_nominal - q_mean) to a few ulps
    expected = {"robot": "kuka_sdh", "object": "cube", "grasp": "1",
                "noise_spec": str(spec_file), "sigma": 0.02, "noise": "triangular",
                "noise_model": json.loads(json.dumps(spec_of(model))), "samples": 120,
                "seed": 3, "engine": "fast", "p_fc": stats.p_fc, "p_fc_ci": list(stats.ci),
                "q_nominal": stats.q_nominal, "q_mean": stats.q_mean,
                "q_var": stats.q_std ** 2, "q_std": stats.q_std, "q_skew": stats.q_skew,
                "error": stats.q_nominal - stats.q_mean, "outcomes": stats.counts}
    assert set(out) == set(expected)
    assert 0 < stats.p_fc < 1
    for key, value in expected.items():
        if isinstance(value, float):
            assert out[key] == pytest.approx(value, rel=1e-12), key
        else:
            assert out[key] == value, key
    assert out["noise_model"]["friction"] == {"distribution": "uniform", "low": 0.3,
                                              "high": 0.7}


@pytest.mark.parametrize("extra, needle", [
    (["--sigma", "0.02"], "--sigma and --noise-spec both given"),
    (["--noise", "uniform"], "--noise and --noise-spec both given"),
])
def test_noise_spec_conflicts_are_one_line_errors(spec_file, capsys, extra, needle):
    assert main(["evaluate", "--noise-spec", str(spec_file), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


def test_rank_with_a_noise_spec_and_its_resume_settings(spec_file, tmp_path, capsys):
    candidates = tmp_path / "cands.json"
    save_grasps(shipped_grasps("cube")[:2], candidates)
    out = tmp_path / "ranked.csv"
    args = ["rank", str(candidates), "--noise-spec", str(spec_file), "--samples", "60",
            "--engine", "fast", "--out", str(out)]
    assert main(args) == 0
    rows = out.read_text().splitlines()[1:]
    model = load_noise_model(spec_file)
    p_fc = {g.id: _evaluate(g, model, 60, 0).p_fc for g in shipped_grasps("cube")[:2]}
    assert {r.split(",")[0]: float(r.split(",")[1]) for r in rows} == pytest.approx(p_fc,
                                                                                   abs=1e-6)
    # an interrupted run's log holds the model: another model does not resume from it
    partial = out.with_name(out.name + ".partial.jsonl")
    partial.write_text(json.dumps({"settings": {"noise_model": {"joints": {}}}}) + "\n")
    assert main(args) == 2
    assert "settings" in capsys.readouterr().err


def test_sweep_noise_entries_are_models_whose_joint_sigma_is_the_cells(spec_file, tmp_path):
    data = {"objects": ["cube"], "grasps": [0], "sigmas": [0.0, 0.03],
            "noise": ["gaussian", "noise.yaml", {"preset": "dexnet"}], "engines": ["fast"],
            "samples": 80, "chunk": 40, "seed": 2}
    spec = SweepSpec.from_dict(data, base=spec_file.parent)
    labels = spec.noise
    assert labels[0] == "gaussian" and labels[1].startswith("noise-")
    assert labels[2].startswith("model-")
    with LocalExecutor(1) as ex:
        rows, _, _ = run_sweep(spec, tmp_path / "out", ex, progress=False)
    models = dict(spec.models)
    for row in rows:
        noise = cell_noise(row["sigma"], row["noise"], models.get(row["noise"]))
        if row["noise"] != "gaussian":
            assert noise.joints.sigma == row["sigma"]  # the cell's sigma, the model's rest
        # the rows evaluate draws (its own chunks): the sweep's chunks of 40 are rows of them
        stats = _evaluate(grasp_by_index("cube", 0), noise, 80, 2)
        assert row["p_fc"] == stats.p_fc
        assert row["q_mean"] == pytest.approx(stats.q_mean, rel=1e-12) or \
            math.isnan(row["q_mean"])
    dexnet = cell_noise(0.03, labels[2], models[labels[2]])
    assert dexnet == noise_model_from_spec({"preset": "dexnet", "joints": {"sigma": 0.03}})


def test_a_sweep_says_which_models_joint_sigma_its_cells_replace(spec_file, tmp_path, capsys):
    """``sweep`` names each noise model whose joints.sigma the cells' sigmas replace (it was
    dropped without a word), and the table's columns stay aligned under a model's label."""
    sweep = tmp_path / "sweep.json"
    sweep.write_text(json.dumps({
        "objects": ["cube"], "grasps": [0], "sigmas": [0.01], "engines": ["fast"],
        "samples": 20, "chunk": 20, "noise": ["gaussian", {"joints": {"sigma": 0.02},
                                                          "palm": {"translation_sigma": 0.001}},
                                              {"palm": {"translation_sigma": 0.001}}]}))
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    notes = [line for line in captured.err.splitlines() if "is replaced" in line]
    assert len(notes) == 1 and "its joints.sigma 0.02 is replaced by each cell's sigma " \
        "(sigmas: 0.01)" in notes[0], captured.err
    table = [line for line in captured.out.splitlines() if line.startswith(("object", "cube"))]
    assert len(table) == 4 and len({line.index(" fast ") for line in table[1:]}) == 1
    assert len({len(line) for line in table}) == 1, table


@pytest.mark.parametrize("noise, needle", [
    (["gausian"], "unknown noise 'gausian': give a distribution"),
    (["missing.yaml"], "missing.yaml: no such file"),
    ([{"joints": {"sigma": -1}}], "joints.sigma must be >= 0"),
    ([{"joints": {"covariance": [[0.0] * 7] * 7}}], "cannot give a covariance"),
    ([3], "neither a distribution nor a noise model"),
])
def test_bad_sweep_noise_entries(noise, needle):
    with pytest.raises(SpecError) as info:
        SweepSpec.from_dict({"objects": ["cube"], "sigmas": [0.01], "noise": noise})
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_an_engine_that_cannot_take_the_model_is_refused_before_any_work(spec_file, capsys):
    model = load_noise_model(spec_file)
    with pytest.raises(ValueError, match=r"^the physics engine takes joint and hand "
                                         r"noise only"):
        evaluate_grasp(shipped_grasps("cube")[0], noise_model=model, n=10,
                       engine="physics")
    assert main(["evaluate", "--noise-spec", str(spec_file), "--engine", "physics"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "object, friction errors" in err[0]
    # the same words from every command that refuses it
    assert main(["sensitivity", "--noise-spec", str(spec_file), "--engine", "physics",
                 "--samples", "8"]) == 2
    again = capsys.readouterr().err.strip().splitlines()
    assert [line.split(": error: ")[1] for line in again + err] == [
        err[0].split(": error: ")[1]] * 2


def test_a_spec_for_another_arm_is_refused_naming_its_file(tmp_path, capsys):
    """Per-joint sigmas for 6 joints given to the 7-joint default robot: every command
    that runs the spec says so in one line that names the spec's file, before any work."""
    spec = tmp_path / "six.yaml"
    spec.write_text("joints: {sigma: [0.01, 0.01, 0.01, 0.01, 0.01, 0.01]}\n")
    candidates = asset_path("grasps", "kuka_sdh", "cube.json")
    out = tmp_path / "r.html"
    for command in (["evaluate", "--object", "cube"], ["rank", str(candidates)],
                    ["report", "--object", "cube", "--out", str(out)],
                    ["sensitivity", "--object", "cube"]):
        assert main([*command, "--noise-spec", str(spec), "--samples", "8"]) == 2, command
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].endswith(
            f"error: --noise-spec {spec}: robot 'kuka_sdh' has 7 arm joints; the spec's "
            "joints describe 6 (give sigma and bias as one value or one per arm joint, a "
            "covariance as one row and column per arm joint)"), (command, err)
    assert not out.exists()


def test_a_sweep_takes_a_noise_spec_file_of_any_name(tmp_path):
    """``--noise-spec n.txt`` is read whatever its suffix; a sweep's ``noise`` entry of the
    same file was refused as an unknown noise. An existing file is a spec file."""
    (tmp_path / "n.txt").write_text("joints: {sigma: 0.0133}\n")
    spec = SweepSpec.from_dict({"objects": ["cube"], "sigmas": [0.01], "noise": ["n.txt"]},
                               base=tmp_path)
    (label,) = spec.noise
    assert label.startswith("n-") and json.loads(dict(spec.models)[label])["joints"]
