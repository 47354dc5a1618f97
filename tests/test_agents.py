"""SB3 agents: training pipeline end to end, reload, evaluation, bad input."""

from __future__ import annotations

import dataclasses
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
    assert row["elbow_policy"] == pytest.approx(env.elbow_angle(q),
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


@pytest.mark.parametrize(("argv", "needle"), [
    (["--total-timesteps", "0"], "--total-timesteps must be >= 1, got 0"),  # not the default
    (["--total-timesteps", "-5"], "--total-timesteps must be >= 1, got -5"),
    (["--seed", "-1"], "--seed must be an integer >= 0, got -1"),
])
def test_train_refuses_bad_counts_before_writing(tmp_path, capsys, argv, needle):
    """A bad count or seed is one line, and an earlier model in --out stays as it was (an
    untrained model was written over it)."""
    model = tmp_path / "KineGraspSelect-v0_ppo.zip"
    model.write_bytes(b"trained")
    assert train.main([*argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and needle in err
    assert model.read_bytes() == b"trained" and sorted(tmp_path.iterdir()) == [model]


def test_hyperparams_missing_file(tmp_path):
    with pytest.raises(train.UsageError, match="no hyperparameter file"):
        train.load_hyperparams("KineGraspSelect-v0", "ppo", folder=tmp_path)


@pytest.mark.parametrize(("pair", "needle"), [
    ("reward", "--env-kwarg takes KEY=VALUE"), ("=batch", "--env-kwarg takes KEY=VALUE"),
    ("re-ward=batch", "--env-kwarg takes KEY=VALUE"),
    ("split=test", "--env-kwarg split: set by the script"),
    ("reward=bogus", "reward must be 'draws' or 'batch', got 'bogus'"),
    ("rewards=batch", "unexpected keyword argument 'rewards'")])
def test_train_env_kwarg_errors_are_one_line(capsys, pair, needle):
    assert train.main(["--env-kwarg", pair, "--total-timesteps", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and needle in err, err


def test_train_env_kwarg_values_are_yaml():
    assert train.env_overrides(["reward=batch", "n_draws=8", "sigma_range=[0.01, 0.02]"]) == {
        "reward": "batch", "n_draws": 8, "sigma_range": [0.01, 0.02]}


def test_train_cli_one_line_error(capsys):
    assert train.main(["--env", "KineGraspSelect-v0", "--algo", "a2c"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown algorithm 'a2c'" in err


def test_make_env_from_a_grasp_file(tmp_path):
    """--grasp-file: every grasp of the file is a task (no split), whatever its objects; a
    missing file is a UsageError naming it."""
    from kinegrasp_env.world.grasps import save_grasps, shipped_grasps

    path = save_grasps(shipped_grasps("cube")[:3] + shipped_grasps("mug")[5:6],
                       tmp_path / "g.json")
    env = train.make_env("KineGraspSelect-v0", {"action_bins": 12}, "train", 0, str(path))
    assert {k: len(v) for k, v in env.unwrapped.tasks.items()} == {"cube": 3, "mug": 1}
    env.close()
    with pytest.raises(train.UsageError, match="--grasp-file: no file"):
        train.make_env("KineGraspSelect-v0", {}, "train", 0, str(tmp_path / "none.json"))


def test_unregistered_env_id():
    with pytest.raises(train.UsageError, match="unknown environment 'Nope-v0'"):
        train.make_env("Nope-v0", {}, "train", 0)


# ------------------------------------------------------------- evaluation statistics
evaluate_module = _load("evaluate")
COMMITTED = ROOT / "agents" / "models" / "evaluation.json"
#: the open-world evaluation: held-out imported objects (agents/heldout.yaml), with the
#: optimizer as the reference
OPENWORLD = ROOT / "agents" / "models" / "evaluation_openworld.json"
#: the built-in-only policy scored on the open-world held-out grasps, same draws as OPENWORLD
OPENWORLD_BUILTIN = ROOT / "agents" / "models" / "evaluation_openworld_builtin_policy.json"
#: the policy trained on the batch reward (scored on COMMITTED's draws)
BATCH = ROOT / "agents" / "models" / "evaluation_batch.json"


def _holm_by_hand(p: list[float]) -> list[float]:
    """Holm's step-down adjusted p-values: sorted ascending, (m - k) p_(k) made monotone."""
    m = len(p)
    order = sorted(range(m), key=lambda i: p[i])
    adjusted, running = [0.0] * m, 0.0
    for k, i in enumerate(order):
        running = max(running, (m - k) * p[i])
        adjusted[i] = min(1.0, running)
    return adjusted


@pytest.mark.parametrize(("path", "grasps"), [(COMMITTED, 12), (OPENWORLD, 16),
                                             (OPENWORLD_BUILTIN, 16), (BATCH, 12)],
                         ids=["in-distribution", "open-world", "open-world-builtin-policy",
                              "batch-reward-policy"])
def test_committed_evaluation_summary_recomputed_from_rows(path, grasps):
    """The committed summary equals an independent recomputation from its per-grasp rows:
    scipy's t.interval for the means, ttest_rel and its confidence_interval for the paired
    differences, a hand-written Holm step-down, Bonferroni intervals at 1 - 0.05/m; the
    fraction of the optimizer's gain and the mean decision times from the rows' means."""
    from scipy import stats

    result = json.loads(path.read_text())
    rows = result["rows"]
    n = len(rows)
    assert n == result["grasps"] == grasps
    for method, stored in result["mean_p_fc"].items():
        values = np.array([r[method] for r in rows])
        lo, hi = stats.t.interval(0.95, n - 1, loc=values.mean(), scale=stats.sem(values))
        assert stored == pytest.approx([values.mean(), lo, hi], rel=1e-12, abs=1e-15)
    baselines = [m for m in result["mean_p_fc"] if m != "policy"]
    assert list(result["paired_tests"]) == [f"policy-{b}" for b in baselines]
    policy = np.array([r["policy"] for r in rows])
    tests = {b: stats.ttest_rel(policy, np.array([r[b] for r in rows])) for b in baselines}
    holm = _holm_by_hand([tests[b].pvalue for b in baselines])
    m = len(baselines)
    for b, p_holm in zip(baselines, holm, strict=True):
        stored, test = result["paired_tests"][f"policy-{b}"], tests[b]
        d = policy - np.array([r[b] for r in rows])
        ci = test.confidence_interval(0.95)
        simultaneous = test.confidence_interval(1 - 0.05 / m)
        assert stored["p"] == pytest.approx(test.pvalue, rel=1e-9)
        assert stored["t"] == pytest.approx(test.statistic, rel=1e-12)
        assert stored["p_holm"] == pytest.approx(p_holm, rel=1e-9)
        assert stored["ci"] == pytest.approx([ci.low, ci.high], rel=1e-9)
        assert stored["ci_simultaneous"] == pytest.approx([simultaneous.low, simultaneous.high],
                                                          rel=1e-9)
        assert result["paired_differences"][f"policy-{b}"] == pytest.approx(
            [d.mean(), ci.low, ci.high], rel=1e-9)
        assert (stored["wins"], stored["losses"], stored["ties"]) == (
            int((d > 0).sum()), int((d < 0).sum()), int((d == 0).sum()))
    if "optimizer" in result["mean_p_fc"]:
        mean = {m: np.mean([r[m] for r in rows]) for m in result["mean_p_fc"]}
        for method, fraction in result["optimizer_gain_fraction"].items():
            assert fraction == pytest.approx((mean[method] - mean["nominal"])
                                             / (mean["optimizer"] - mean["nominal"]), rel=1e-9)
        for method, seconds in result["decision_seconds"].items():
            assert seconds == pytest.approx(np.mean([r[f"seconds_{method}"] for r in rows]))
    # and the file is what summarize() makes of its own rows
    fresh = evaluate_module.summarize(rows)
    assert {k: result[k] for k in fresh} == fresh


@pytest.mark.parametrize("seed", range(5))
def test_holm_rejects_exactly_what_the_step_down_procedure_rejects(seed):
    """Independent definition: Holm rejects H_(1..k) while p_(k) <= alpha / (m - k + 1);
    adjusted p <= alpha must mark exactly those, for every alpha."""
    rng = np.random.default_rng(seed)
    p = (rng.uniform(0, 0.1, 6) ** rng.uniform(0.5, 2)).tolist()
    p[1] = p[0]  # a tie
    adjusted = evaluate_module.holm(p)
    assert adjusted == pytest.approx(_holm_by_hand(p), rel=1e-12)
    order = np.argsort(p, kind="stable")
    for alpha in np.linspace(0.001, 0.3, 60):
        rejected = set()
        for k, i in enumerate(order):
            if p[i] > alpha / (len(p) - k):
                break
            rejected.add(int(i))
        assert {i for i, a in enumerate(adjusted) if a <= alpha} == rejected


def test_holm_leaves_nan_out():
    assert evaluate_module.holm([0.01, float("nan"), 0.04]) == pytest.approx(
        [0.02, float("nan"), 0.04], nan_ok=True)


def test_summarize_mode_rewrites_only_the_summary(tmp_path, capsys):
    """--summarize recomputes a stale summary from the rows; rows and settings untouched."""
    committed = json.loads(COMMITTED.read_text())
    stale = {k: v for k, v in committed.items() if k not in ("paired_tests", "statistics")}
    stale["mean_p_fc"] = {m: [0.0, 0.0, 0.0] for m in stale["mean_p_fc"]}
    path = tmp_path / "evaluation.json"
    path.write_text(json.dumps(stale))
    assert evaluate_module.main(["--summarize", str(path)]) == 0
    assert "| policy-spread |" in capsys.readouterr().out
    assert json.loads(path.read_text()) == committed
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


@pytest.mark.parametrize(("content", "needle"), [
    (None, "no file"),
    ("{not json", "not a readable JSON file"),
    (json.dumps({"rows": []}), "no per-grasp rows"),
    (json.dumps({"rows": [{"nominal": 0.5}]}), "no 'policy' P(FC)"),
    (json.dumps([1, 2]), "no per-grasp 'rows' list"),
])
def test_summarize_bad_file_one_line_error(tmp_path, capsys, content, needle):
    path = tmp_path / "evaluation.json"
    if content is not None:
        path.write_text(content)
    assert evaluate_module.main(["--summarize", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and needle in err
    assert (path.read_text() if content is not None else None) == content  # untouched


@pytest.mark.parametrize(("argv", "needle"), [
    (["--draws", "0"], "--draws must be >= 1, got 0"),
    (["--oracle-draws", "-1"], "--oracle-draws must be >= 0, got -1"),
    (["--grasp-file", "nowhere.json"], "--grasp-file: no file nowhere.json"),
    # the tests' empty catalog: the held-out blobs are not imported (agents/prepare.py is not
    # run), and the file is refused in one line naming the object
    (["--grasp-file", str(ROOT / "agents" / "grasps" / "test.json")], "'blob200'"),
    (["--robot", "pandaa"], "--robot: unknown robot 'pandaa'"),
    (["--robot", "panda"], "--robot panda: agents/models/KineGraspSelect-v0_ppo.zip was "
                           "trained on robot 'kuka_sdh'"),
])
def test_evaluate_bad_arguments_one_line_error(capsys, argv, needle):
    assert evaluate_module.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and needle in err


def test_evaluate_refuses_seeds_and_files_that_are_no_model(tmp_path, capsys):
    not_a_model = tmp_path / "result.json"
    not_a_model.write_text("{}")
    for argv, needle in [
            (["--seed", "-1", "--quick"], "--seed must be an integer >= 0, got -1"),
            (["--optimizer-seed", "-2", "--quick"], "--optimizer-seed must be an integer >= 0"),
            (["--model", str(not_a_model), "--quick"],
             f"--model: {not_a_model} is not a stable-baselines3 model")]:
        assert evaluate_module.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and needle in err, err


@pytest.mark.expensive
def test_evaluate_refuses_a_policy_of_the_other_env(tmp_path, capsys):
    """A policy trained on KineGrasp-v0 (two actions) is not scored as a KineGraspSelect-v0
    one (the env refused its action from inside the run)."""
    train.train("KineGrasp-v0", "sac", seed=0, out=tmp_path, total_timesteps=8,
                checkpoint_every=1000, progress=False)
    model = tmp_path / "KineGrasp-v0_sac.zip"
    assert evaluate_module.main(["--model", str(model), "--quick"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "scores KineGraspSelect-v0 policies" in err, err


def test_oracle_selection_draws_are_not_scoring_draws():
    """Scoring uses chunks 0..K-1 of the seed, the oracle's selection chunks K..: no noise
    draw is shared."""
    from kinegrasp_env.montecarlo.chunks import CHUNK, chunk_configurations

    def chunk_noise(index: int, size: int) -> np.ndarray:
        """Arm noise (size, 7) of chunk ``index`` of seed 0: its rows ``index * CHUNK ..``."""
        return chunk_configurations(np.zeros(14), 7, 0.0283, "gaussian", 0, index * CHUNK,
                                    size)[:, :7]

    draws = 2000
    first = evaluate_module.scoring_chunks(draws)
    assert first * CHUNK >= draws > (first - 1) * CHUNK
    scoring = np.vstack([chunk_noise(c, CHUNK) for c in range(first)])
    selection = chunk_noise(first, 200)
    assert not (selection[:, None, :] == scoring[None, :, :]).all(-1).any()


@pytest.mark.parametrize(("first", "second", "grasps"),
                         [(OPENWORLD, OPENWORLD_BUILTIN, 16), (BATCH, COMMITTED, 12)],
                         ids=["open-world-vs-builtin", "batch-vs-draws-reward"])
def test_paired_policy_comparison(tmp_path, capsys, first, second, grasps):
    """Two results of different policies share grasps and draws (every column that does not
    depend on the model is identical, row by row), and --compare's paired comparison of their
    policy columns equals scipy's ttest_rel and its confidence interval on those rows."""
    from scipy import stats

    a, b = (json.loads(p.read_text()) for p in (first, second))
    assert [(r["object"], r["grasp"]) for r in a["rows"]] == [
        (r["object"], r["grasp"]) for r in b["rows"]]
    for column in ("nominal", "random", "spread", "elbow_nominal", "elbow_spread"):
        assert [r[column] for r in a["rows"]] == [r[column] for r in b["rows"]], column
    policy_a, policy_b = (np.array([r["policy"] for r in x["rows"]]) for x in (a, b))
    test = stats.ttest_rel(policy_a, policy_b)
    ci = test.confidence_interval(0.95)
    d = policy_a - policy_b
    out = tmp_path / "compare.json"
    assert evaluate_module.main(["--compare", str(first), str(second),
                                 "--out", str(out)]) == 0
    assert "| policy: A - B |" in capsys.readouterr().out
    result = json.loads(out.read_text())
    assert result["grasps"] == len(d) == grasps and result["df"] == grasps - 1
    assert result["mean"] == pytest.approx(d.mean(), rel=1e-12)
    assert result["ci"] == pytest.approx([ci.low, ci.high], rel=1e-9)
    assert result["t"] == pytest.approx(test.statistic, rel=1e-12)
    assert result["p"] == pytest.approx(test.pvalue, rel=1e-9)
    assert (result["mean_a"], result["mean_b"]) == pytest.approx(
        (policy_a.mean(), policy_b.mean()), rel=1e-12)
    assert (result["wins"], result["losses"], result["ties"]) == (
        int((d > 0).sum()), int((d < 0).sum()), int((d == 0).sum()))


def _tampered(result: dict, change) -> dict:
    out = json.loads(json.dumps(result))
    change(out)
    return out


@pytest.mark.parametrize(("change", "needle"), [
    (lambda r: r["rows"].pop(), "not the same grasps (16 vs 15 rows, first difference at row 15)"),
    (lambda r: r.update(seed=1), "different scoring settings: seed = 0 vs 1"),
    (lambda r: r["rows"][2].update(nominal=0.5), "not the same draws: nominal P(FC) of"),
    (lambda r: r["rows"][3].pop("policy"), "no 'policy' P(FC) for"),
], ids=["grasps", "seed", "nominal", "no-policy"])
def test_compare_refuses_unpaired_results_one_line_error(tmp_path, capsys, change, needle):
    base = json.loads(OPENWORLD.read_text())
    path_a, path_b, out = tmp_path / "a.json", tmp_path / "b.json", tmp_path / "out.json"
    path_a.write_text(json.dumps(base))
    path_b.write_text(json.dumps(_tampered(base, change)))
    assert evaluate_module.main(["--compare", str(path_a), str(path_b), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and needle in err and err.startswith("evaluate: error: --compare")
    assert not out.exists()


@pytest.mark.expensive
def test_evaluate_cli_end_to_end_with_optimizer(tmp_path, capsys):
    """--limit 1 with few draws through the CLI: the oracle's grid estimates are chunk K of
    the seed (engine draws recomputed here), the optimizer's choice is scored on chunk 0."""
    import gymnasium as gym

    from kinegrasp_env.montecarlo.chunks import CHUNK, chunk_configurations
    from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.toolkit.elbow_search import optimize_robot_elbow

    out = tmp_path / "evaluation.json"
    argv = ["--limit", "1", "--draws", "10", "--oracle-draws", "5", "--grid", "3",
            "--random-angles", "2", "--optimizer-samples", "20", "--processes", "1",
            "--out", str(out)]
    assert evaluate_module.main(argv) == 0
    result = json.loads(out.read_text())
    row = result["rows"][0]
    assert set(result["mean_p_fc"]) == {*evaluate_module.METHODS, "oracle", "optimizer"}
    assert result["optimizer_seed"] == 1 and result["grasps"] == 1
    assert set(result["decision_seconds"]) == {"policy", "spread", "oracle", "optimizer"}
    env = gym.make("KineGraspSelect-v0", split="test", n_draws=1).unwrapped
    env.reset(seed=0, options={"object": row["object"], "grasp": 0, "sigma": 0.0283})
    engine, noise = make_engine("pybullet", DEFAULT_ROBOT, row["object"]), JointNoise(0.0283)

    def draw_chunk(q0: np.ndarray, index: int, size: int):
        """The first ``size`` draws of chunk ``index`` of seed 0 at q0, closed by ``engine``."""
        return engine.run(chunk_configurations(q0, 7, 0.0283, "gaussian", 0, index * CHUNK,
                                               size))

    grid = [env.configuration_at(p)[0] for p in np.linspace(-np.pi, np.pi, 3, endpoint=False)]
    selection = [float((draw_chunk(q, 1, 5).outcome == FORCE_CLOSURE).mean()) for q in grid]
    assert row["oracle_grid_p_fc"] == selection
    best = grid[int(np.argmax(selection))]
    assert row["elbow_oracle"] == pytest.approx(env.elbow_angle(best))
    found = optimize_robot_elbow(env.grasp, noise, 20, 1, evaluate_with="fast")
    assert row["elbow_optimizer"] == pytest.approx(
        env.elbow_angle(found.best_q), abs=1e-12)
    scored = draw_chunk(found.best_q, 0, 10).outcome == FORCE_CLOSURE
    assert row["optimizer"] == float(scored.mean())
    engine.close()
    env.close()
    for method, (mean, _, _) in evaluate_module.summarize(result["rows"])["mean_p_fc"].items():
        assert result["mean_p_fc"][method][0] == mean == row[method]


@pytest.mark.expensive
def test_a_policy_of_another_robot_trains_and_is_evaluated(tmp_path):
    """A policy trained on the Panda's env (``train.py --env-kwarg robot=panda``) is evaluated
    on the Panda's held-out grasps: each method's P(FC) is ``evaluate --robot panda``'s draws
    at its configuration (``evaluate_grasp``, recomputed here for the nominal and the
    optimizer's), the optimizer's elbow angle that of its configuration along the Panda's own
    self-motion, and the configurations keep the grasp's palm pose (the Panda's forward
    kinematics)."""
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.kinematics import Kinematics
    from kinegrasp_env.robot.null_motion import ArmSelfMotion
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.toolkit.elbow_search import optimize_robot_elbow
    from kinegrasp_env.world.grasps import shipped_grasps

    train.train("KineGraspSelect-v0", "ppo", seed=0, out=tmp_path, total_timesteps=64,
                progress=False, overrides={"robot": "panda"})
    model = tmp_path / "KineGraspSelect-v0_ppo.zip"
    assert evaluate_module.model_robot(str(model), None) == "panda"  # its training summary
    result = evaluate_module.evaluate(str(model), 0.0233, draws=20, oracle_draws=5, grid=3,
                                      seed=0, limit=1, optimizer_samples=20)
    assert result["robot"] == "panda"
    row = result["rows"][0]
    grasp = next(g for g in shipped_grasps(row["object"], "panda") if g.id == row["grasp"])
    nominal = evaluate_grasp(grasp, sigma=0.0233, n=20, seed=0, engine="pybullet")
    assert row["nominal"] == nominal.p_fc
    found = optimize_robot_elbow(grasp, JointNoise(0.0233), 20, 1, evaluate_with="fast")
    moved = dataclasses.replace(grasp, q0=found.best_q)
    assert row["optimizer"] == evaluate_grasp(moved, sigma=0.0233, n=20, seed=0,
                                              engine="pybullet").p_fc
    description = load_robot("panda")
    assert row["elbow_optimizer"] == pytest.approx(float(
        ArmSelfMotion(description).elbow_angle(found.best_q[None])[0]), abs=1e-12)
    kinematics = Kinematics(description.model)
    np.testing.assert_allclose(kinematics.pose(found.best_q[None], description.palm_link),
                               kinematics.pose(np.asarray(grasp.q0)[None],
                                               description.palm_link), atol=1e-8)


# ------------------------------------------------------------- open-world data
prepare_module = _load("prepare")


def test_heldout_objects_never_in_the_training_file():
    """The committed grasp sets follow agents/heldout.yaml: test.json holds exactly the spec's
    held-out objects with test_grasps grasps each, train.json the built-in training grasps
    (i % 4 != 3 of the shipped sets, compared by q0) plus the spec's training objects, and no
    held-out object is trained on."""
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import OBJECT_NAMES

    spec = prepare_module.read_spec()
    used = {i: spec["replaced"].get(i, i) for i in spec["train"] + spec["test"]}
    test = json.loads((ROOT / "agents" / "grasps" / "test.json").read_text())
    train_set = json.loads((ROOT / "agents" / "grasps" / "train.json").read_text())
    held_out = [f"blob{used[i]:03d}" for i in spec["test"]]
    counts: dict[str, int] = {}
    for g in test["grasps"]:
        counts[g["object"]] = counts.get(g["object"], 0) + 1
    assert counts == {name: spec["test_grasps"] for name in held_out}
    trained = {g["object"] for g in train_set["grasps"]}
    assert trained == set(OBJECT_NAMES) | {f"blob{used[i]:03d}" for i in spec["train"]}
    assert not trained & set(held_out)
    for name in OBJECT_NAMES:
        expected = [g.q0.tolist() for i, g in enumerate(shipped_grasps(name)) if i % 4 != 3]
        assert [g["q0"] for g in train_set["grasps"] if g["object"] == name] == expected


@pytest.mark.parametrize(("text", "needle"), [
    ("train: [1]\ntest: [1]\ntrain_grasps: 2\ntest_grasps: 2\n", "share indices [1]"),
    ("train: [1]\ntest: [1000]\ntrain_grasps: 2\ntest_grasps: 2\n", "'test' must be a list"),
    ("train: [1]\ntest: [2]\ntrain_grasps: 0\ntest_grasps: 2\n", "'train_grasps' must be"),
])
def test_prepare_bad_spec_one_line_error(tmp_path, capsys, text, needle):
    path = tmp_path / "spec.yaml"
    path.write_text(text)
    assert prepare_module.main(["--spec", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and needle in err


def test_multistep_reach_loss_by_hand():
    """Two hand-made curves: the first's best angle (P 0.9 at psi 2.0) is 2.5 rad from the
    nominal -0.5, beyond a 1.5 rad reach (best within: 0.6 at psi 0.5); the second's best
    (0.7 at psi 3.0) is 0.4 rad from the nominal -2.883 across the +-pi seam, so within."""
    multistep = _load("multistep")
    rows = [{"elbow_nominal": -0.5, "optimizer_curve": [[-1.0, 0.5], [0.5, 0.6], [2.0, 0.9]]},
            {"elbow_nominal": -2.883, "optimizer_curve": [[-1.0, 0.65], [3.0, 0.7]]}]
    out = multistep.reach_loss(rows, 1.5)
    assert out["best_within_reach"] == pytest.approx((0.6 + 0.7) / 2)
    assert out["best_anywhere"] == pytest.approx((0.9 + 0.7) / 2)
    assert out["loss_mean"] == pytest.approx(0.15) and out["loss_max"] == pytest.approx(0.3)
    assert out["grasps_best_beyond_reach"] == 1
    with pytest.raises(ValueError, match="no optimizer_curve"):
        multistep.reach_loss([{"object": "cube", "grasp": "0", "elbow_nominal": 0.0}], 1.5)


def test_a_training_summary_records_the_models_path_the_same_on_every_machine(tmp_path):
    """Inside the repository the model's path is recorded relative to its root (so a
    committed summary names no machine's folders); outside it, as given."""
    inside = ROOT / "agents" / "models" / "KineGraspSelect-v0_ppo.zip"
    assert train.recorded_path(inside) == "agents/models/KineGraspSelect-v0_ppo.zip"
    assert train.recorded_path(tmp_path / "m.zip") == str(tmp_path / "m.zip")
    for summary in (ROOT / "agents" / "models").glob("*_ppo*.json"):
        assert json.loads(summary.read_text())["model"].startswith("agents/models/"), summary
