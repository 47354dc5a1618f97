"""Compare elbow-angle choices on held-out grasps: nominal IK, random, palm-spread rule, trained
policy, oracle and the elbow optimizer.

Example (the committed table):
    python agents/evaluate.py --model agents/models/KineGraspSelect-v0_ppo.zip --seed 0 \
        --out agents/models/evaluation.json
The open-world table (objects never used for any decision; ``agents/prepare.py`` first):
    python agents/evaluate.py --model agents/models/KineGraspSelect-v0_ppo_openworld.zip \
        --grasp-file agents/grasps/test.json --out agents/models/evaluation_openworld.json
Recompute the statistics of an existing result from its per-grasp rows (no evaluation run):
    python agents/evaluate.py --summarize agents/models/evaluation.json
Compare the policies of two results on the same grasps and draws, A - B per grasp (paired
t-test, one comparison; :func:`compare_results`):
    python agents/evaluate.py --compare agents/models/evaluation_openworld.json \
        agents/models/evaluation_openworld_builtin_policy.json

**Scoring.** For every grasp of the held-out ``test`` split of the robot's shipped sets
(``--robot``, default the one the model was trained on) (grasp index i % 4 == 3 of each
object's set), or with ``--grasp-file`` every grasp of that file, at noise ``--sigma``, the arm
configuration chosen by each method is evaluated with ``--draws`` Monte Carlo draws of
``--engine`` (default the reference, pybullet) on chunks ``0..K-1`` of ``--seed`` (K =
ceil(draws / 250)), the same draws for every method (common random numbers).

**Methods.** ``nominal`` (the grasp's IK configuration); ``random`` (the mean over
``--random-angles`` uniformly drawn elbow angles, ``--draws`` in all: the expected P(FC) of
picking the elbow at random); ``spread`` (no learning: of the oracle's grid, the angle with the
smallest palm-position spread per unit joint noise, sqrt(trace(J_p J_p^T))); ``policy`` (the
trained model, deterministic); ``oracle`` (the best of a grid of ``--grid`` elbow angles by
``--oracle-draws`` draws each, drawn on chunks ``K, K+1, ...`` of the seed: selection draws
independent of the scoring draws; ``--oracle-draws 0`` leaves it out); ``optimizer`` (the
reference, :func:`kinegrasp_env.toolkit.elbow_search.optimize_robot_elbow` (a 6-joint arm:
``optimize_robot_branches``) with ``--optimizer-samples`` fast-engine draws per angle and seed
``--optimizer-seed``, default seed + 1: its selection draws are independent of the scoring
draws too; ``--optimizer-samples 0`` leaves it out). Each row also records the decision time of
the methods that decide (``seconds_<method>``, wall clock).

**Statistics** (:func:`summarize`, from the per-grasp rows alone; n = number of grasps):

- ``mean_p_fc[m] = [mean, lo, hi]``: the mean P(FC) over the grasps with a 95% Student-t
  interval, mean +- t(0.975, n-1) s / sqrt(n).
- ``paired_differences["policy-m"] = [mean, lo, hi]``: the paired difference policy - m per
  grasp, with an unadjusted 95% Student-t interval (same layout as before).
- ``paired_tests["policy-m"]``: the paired t-test (two-sided, df = n - 1) of each comparison
  made (policy vs each baseline present, m of them): ``p``; Holm's step-down adjustment over
  the m p-values, ``p_holm`` (sort ascending, p_(j) -> max over i <= j of
  min(1, (m - i + 1) p_(i))); ``ci`` (the unadjusted 95% t-interval) and ``ci_simultaneous``,
  Bonferroni t-intervals at level 1 - 0.05 / m each, which cover all m differences at once
  with probability >= 95%. Holm is uniformly more powerful than Bonferroni, so a comparison
  can be Holm-significant (p_holm < 0.05) while its Bonferroni interval still touches zero;
  an interval that excludes zero always means p_holm < 0.05. Also the wins/losses/ties of the
  policy (per-grasp differences > 0, < 0, == 0).
- ``optimizer_gain_fraction[m]`` (when the optimizer ran): (mean_m - mean_nominal) /
  (mean_optimizer - mean_nominal), the fraction of the optimizer's gain over nominal that m
  reaches; ``decision_seconds[m]``: the mean decision time.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import tempfile
import time
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy import stats as sps

#: Methods of every evaluation, in table order.
METHODS = ("nominal", "random", "spread", "policy")
#: Methods a run may leave out (``--oracle-draws 0``, ``--optimizer-samples 0``); a result
#: without them is still summarized.
OPTIONAL_METHODS = ("oracle", "optimizer")
#: Keys :func:`summarize` writes (the rest of a result is its settings and rows).
SUMMARY_KEYS = ("grasps", "statistics", "mean_p_fc", "paired_differences", "paired_tests",
                "optimizer_gain_fraction", "decision_seconds")
STATISTICS = ("Student-t 95% intervals (df = n - 1); paired t-tests of policy vs each "
              "baseline, Holm step-down adjusted p-values over those comparisons; "
              "simultaneous 95% intervals by Bonferroni (each at 1 - 0.05/m)")


class UsageError(ValueError):
    """Bad command-line input (reported in one line, exit status 2)."""


# ---------------------------------------------------------------------------- statistics
def t_interval(values: np.ndarray, confidence: float = 0.95) -> tuple[float, float, float]:
    """(mean, lo, hi) of values (n,) with a Student-t interval, df = n - 1 (nan for n < 2;
    a zero-width interval when every value is equal)."""
    values = np.asarray(values, dtype=float)
    mean = float(values.mean())
    if values.size < 2:
        return mean, math.nan, math.nan
    half = float(sps.t.ppf(0.5 + confidence / 2, values.size - 1)
                 * values.std(ddof=1) / math.sqrt(values.size))
    return mean, mean - half, mean + half


def paired_t_test(d: np.ndarray) -> tuple[float, float]:
    """(t, two-sided p) of the paired differences d (n,) against a zero mean. Every d equal:
    p = 1 if they are 0, else 0 (t = +-inf); n < 2: nan."""
    d = np.asarray(d, dtype=float)
    if d.size < 2:
        return math.nan, math.nan
    sd = float(d.std(ddof=1))
    mean = float(d.mean())
    if sd == 0.0:
        return (0.0, 1.0) if mean == 0.0 else (math.copysign(math.inf, mean), 0.0)
    t = mean / (sd / math.sqrt(d.size))
    return t, float(2.0 * sps.t.sf(abs(t), d.size - 1))


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values, in the input order; nan entries stay nan and do not
    count as comparisons."""
    p = np.asarray(p_values, dtype=float)
    finite = np.flatnonzero(np.isfinite(p))
    out = np.full(p.shape, math.nan)
    order = finite[np.argsort(p[finite], kind="stable")]
    m = order.size
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[index]))
        out[index] = running
    return out.tolist()


def methods_in(rows: list[dict]) -> list[str]:
    """The methods every row has a P(FC) for, in table order."""
    return [m for m in METHODS + OPTIONAL_METHODS
            if all(isinstance(r.get(m), (int, float)) for r in rows)]


def paired_tests(rows: list[dict], baselines: list[str]) -> dict:
    """Paired t-tests of policy - b for every baseline b, with Holm and Bonferroni (see the
    module docstring)."""
    diffs = {b: np.array([r["policy"] - r[b] for r in rows], dtype=float) for b in baselines}
    tests = {b: paired_t_test(d) for b, d in diffs.items()}
    adjusted = holm([tests[b][1] for b in baselines])
    simultaneous = 1.0 - 0.05 / max(len(baselines), 1)
    out = {}
    for b, p_holm in zip(baselines, adjusted, strict=True):
        d = diffs[b]
        mean, lo, hi = t_interval(d)
        _, slo, shi = t_interval(d, simultaneous)
        out[f"policy-{b}"] = {
            "mean": mean, "sd": float(d.std(ddof=1)) if d.size > 1 else math.nan,
            "n": int(d.size), "df": int(d.size - 1), "t": tests[b][0], "p": tests[b][1],
            "p_holm": p_holm, "ci": [lo, hi], "ci_simultaneous": [slo, shi],
            "simultaneous_level": simultaneous, "wins": int((d > 0).sum()),
            "losses": int((d < 0).sum()), "ties": int((d == 0).sum())}
    return out


def summarize(rows: list[dict]) -> dict:
    """Every summary field of a result (:data:`SUMMARY_KEYS`), from its per-grasp rows alone.

    Raises:
        ValueError: no rows, or no policy column.
    """
    if not rows:
        raise ValueError("no per-grasp rows to summarize")
    methods = methods_in(rows)
    if "policy" not in methods:
        raise ValueError("the rows have no 'policy' P(FC) for every grasp")
    baselines = [m for m in methods if m != "policy"]
    means = {m: list(t_interval(np.array([r[m] for r in rows], dtype=float)))
             for m in methods}
    tests = paired_tests(rows, baselines)
    summary = {"grasps": len(rows), "statistics": STATISTICS, "mean_p_fc": means,
               "paired_differences": {k: [v["mean"], *v["ci"]] for k, v in tests.items()},
               "paired_tests": tests}
    if "optimizer" in methods:
        gain = means["optimizer"][0] - means["nominal"][0]
        summary["optimizer_gain_fraction"] = {
            m: (means[m][0] - means["nominal"][0]) / gain if gain else math.nan
            for m in methods}
    timed = [m for m in methods if all(f"seconds_{m}" in r for r in rows)]
    if timed:
        summary["decision_seconds"] = {m: float(np.mean([r[f"seconds_{m}"] for r in rows]))
                                       for m in timed}
    return summary


def resummarize(result: dict) -> dict:
    """The result with its summary recomputed from its rows (every other key kept)."""
    out = {k: v for k, v in result.items() if k not in SUMMARY_KEYS}
    rows = out.pop("rows")
    summary = summarize(rows)
    ordered = {**out, "grasps": summary.pop("grasps"), "rows": rows}
    ordered.update(summary)
    return ordered


#: Settings that fix the scoring draws: two results that agree on them (and on the grasps)
#: scored every configuration on the same draws, so their rows can be paired.
SCORING_SETTINGS = ("sigma", "draws", "seed", "engine", "robot")
#: A result's setting where it has none (results from before it was recorded).
SETTING_DEFAULTS = {"engine": "pybullet", "robot": "kuka_sdh"}


def compare_results(a: dict, b: dict, method: str = "policy") -> dict:
    """Paired comparison of ``method``'s P(FC) in result ``a`` minus result ``b`` (two
    evaluations of different models on the same grasps and draws), per grasp: the mean
    difference with its 95% Student-t interval (df = n - 1), the two-sided paired t-test and
    the wins/losses/ties of ``a`` (differences > 0, < 0, == 0). One comparison: no
    multiplicity adjustment.

    Raises:
        ValueError: different grasps (object, id, in order), different
            :data:`SCORING_SETTINGS`, a nominal P(FC) that differs on some grasp (not the same
            draws), or a row without ``method``.
    """
    keys_a = [(r.get("object"), r.get("grasp")) for r in a["rows"]]
    keys_b = [(r.get("object"), r.get("grasp")) for r in b["rows"]]
    if keys_a != keys_b:
        raise ValueError(f"not the same grasps ({len(keys_a)} vs {len(keys_b)} rows, first "
                         f"difference at row {_first_difference(keys_a, keys_b)})")
    for key in SCORING_SETTINGS:
        if _setting(a, key) != _setting(b, key):
            raise ValueError(f"different scoring settings: {key} = {_setting(a, key)!r} vs "
                             f"{_setting(b, key)!r}")
    for (obj, grasp), ra, rb in zip(keys_a, a["rows"], b["rows"], strict=True):
        if ra.get("nominal") != rb.get("nominal"):
            raise ValueError(f"not the same draws: nominal P(FC) of {obj} grasp {grasp} is "
                             f"{ra.get('nominal')!r} vs {rb.get('nominal')!r}")
        if not all(isinstance(r.get(method), (int, float)) for r in (ra, rb)):
            raise ValueError(f"no {method!r} P(FC) for {obj} grasp {grasp}")
    d = np.array([ra[method] - rb[method] for ra, rb in zip(a["rows"], b["rows"],
                                                           strict=True)], dtype=float)
    mean, lo, hi = t_interval(d)
    t, p = paired_t_test(d)
    return {"method": method, "grasps": int(d.size), "df": int(d.size - 1),
            "mean_a": float(np.mean([r[method] for r in a["rows"]])),
            "mean_b": float(np.mean([r[method] for r in b["rows"]])),
            "mean": mean, "sd": float(d.std(ddof=1)) if d.size > 1 else math.nan,
            "ci": [lo, hi], "t": t, "p": p, "wins": int((d > 0).sum()),
            "losses": int((d < 0).sum()), "ties": int((d == 0).sum()),
            "statistics": "paired Student-t (df = n - 1), 95% interval, two-sided p; one "
                          "comparison, no multiplicity adjustment; nominal P(FC) identical "
                          "on every grasp (common draws)"}


def _first_difference(a: list, b: list) -> int:
    """Index of the first differing entry of two lists (the shorter length if none)."""
    return next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y),
                min(len(a), len(b)))


def _setting(result: dict, key: str):
    """A scoring setting of a result (results from before it was recorded:
    :data:`SETTING_DEFAULTS`)."""
    return result.get(key, SETTING_DEFAULTS.get(key))


def write_json_atomic(path: Path, payload: dict) -> None:
    """Write payload to path via a temporary file in the same folder and a rename: a reader
    sees the old file or the new one, never half of one."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(json.dumps(payload, indent=1))
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def read_result(path: str, option: str = "--summarize") -> dict:
    """An evaluation JSON with per-grasp rows (``option`` names the command-line option in
    the error messages).

    Raises:
        UsageError: missing or unreadable file, not JSON, or no rows.
    """
    file = Path(path)
    if not file.is_file():
        raise UsageError(f"{option}: no file {path}")
    try:
        result = json.loads(file.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise UsageError(f"{option}: {path} is not a readable JSON file ({error})") from None
    if not isinstance(result, dict) or not isinstance(result.get("rows"), list):
        raise UsageError(f"{option}: {path} has no per-grasp 'rows' list")
    return result


# ---------------------------------------------------------------------------- evaluation
def palm_spread(env, q: np.ndarray) -> float:
    """Palm-position spread per unit joint noise at configuration q (dof,) of the env's
    robot: the root of the trace of J_p J_p^T over its arm joints (metres per radian)."""
    from kinegrasp_env.robot.catalog import load_robot

    description = load_robot(env.robot)
    jac = env.kinematics.jacobian(q, description.palm_link)[0][:3, :description.arm_dof]
    return float(np.sqrt(np.trace(jac @ jac.T)))


def scoring_chunks(draws: int) -> int:
    """Number of chunks (0..K-1 of the seed) the scoring of ``draws`` draws uses; selection
    draws start at chunk K."""
    from kinegrasp_env.montecarlo.grasp_stats import DEFAULT_CHUNK, chunk_sizes

    return len(chunk_sizes(draws, DEFAULT_CHUNK))


class Scorer:
    """P(FC) of a grasp (of any robot) moved to configuration q, by ``engine`` (default the
    reference, pybullet) on chunks ``first_chunk, first_chunk + 1, ...`` of ``seed`` (common
    random numbers): ``kinegrasp evaluate``'s draws of that seed from row ``first_chunk``
    x 250 on (:func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`)."""

    def __init__(self, noise, seed: int, executor, engine: str = "pybullet") -> None:
        self.noise, self.seed, self.executor = noise, int(seed), executor
        self.engine = engine

    def __call__(self, grasp, q: np.ndarray, n: int, first_chunk: int = 0) -> float:
        from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
        from kinegrasp_env.montecarlo.grasp_stats import DEFAULT_CHUNK

        moved = dataclasses.replace(grasp, q0=np.asarray(q, dtype=float))
        return evaluate_grasp(moved, sigma=self.noise.sigma, n=n, seed=self.seed,
                              noise=self.noise.kind, engine=self.engine,
                              executor=self.executor,
                              offset=first_chunk * DEFAULT_CHUNK).p_fc


def choose(env, model, obs, grasp, q0: np.ndarray, score: Scorer, settings: dict,
           executor) -> tuple[dict, dict]:
    """Each deciding method's configuration (dof,) for the current task, and a dict of
    extra row entries (decision times in seconds, the oracle's selection estimates)."""
    def reach(psi: float) -> np.ndarray:
        return env.configuration_at(psi, q0)[0]

    extra: dict = {}
    start = time.perf_counter()
    action, _ = model.predict(obs, deterministic=True)
    configs = {"nominal": q0, "policy": reach(env.action_angle(action))}
    extra["seconds_policy"] = time.perf_counter() - start
    start = time.perf_counter()
    grid_psi = np.linspace(-math.pi, math.pi, settings["grid"], endpoint=False)
    candidates = [reach(p) for p in grid_psi]
    configs["spread"] = candidates[int(np.argmin([palm_spread(env, q) for q in candidates]))]
    extra["seconds_spread"] = time.perf_counter() - start
    if settings["oracle_draws"] > 0:
        start = time.perf_counter()
        first = scoring_chunks(settings["draws"])  # selection draws never scored
        quick = [score(grasp, q, settings["oracle_draws"], first_chunk=first)
                 for q in candidates]
        configs["oracle"] = candidates[int(np.argmax(quick))]
        extra["seconds_oracle"] = time.perf_counter() - start
        extra["oracle_grid_p_fc"] = quick
    if settings["optimizer_samples"] > 0:
        from kinegrasp_env.toolkit.elbow_search import optimize_variants

        start = time.perf_counter()
        found, branches = optimize_variants(grasp, score.noise, settings["optimizer_samples"],
                                            settings["optimizer_seed"], evaluate_with="fast",
                                            executor=executor)
        configs["optimizer"] = np.asarray(found.best_q, dtype=float)
        extra["seconds_optimizer"] = time.perf_counter() - start
        extra["optimizer_own_p_fc"] = found.best_p_fc
        # its selection curve, [psi (rad), P(FC)] per evaluated angle (fast engine)
        # a 6-joint arm's curve is over its IK branches: each at the env's coordinate
        extra["optimizer_curve"] = [[round(env.elbow_angle(p.q) if branches else p.psi, 4),
                                     p.p_fc] for p in found.curve]
    return configs, extra


def evaluate_task(env, model, obs, score: Scorer, settings: dict, rng: np.random.Generator,
                  executor) -> dict:
    """The row of the env's current task: P(FC) and elbow angle (radians) of every method."""
    grasp, q0 = env.grasp, env.q.copy()
    configs, extra = choose(env, model, obs, grasp, q0, score, settings, executor)
    row = {"object": grasp.object, "grasp": grasp.id,
           "elbow_nominal": env.elbow_angle(q0)}
    for method in [*METHODS, *(m for m in OPTIONAL_METHODS if m in configs)]:
        if method == "random":
            angles = rng.uniform(-math.pi, math.pi, settings["random_angles"])
            share = max(settings["draws"] // settings["random_angles"], 1)
            row[method] = float(np.mean([score(grasp, env.configuration_at(p, q0)[0], share)
                                         for p in angles]))
        else:
            row[method] = score(grasp, configs[method], settings["draws"])
        row[f"elbow_{method}"] = (env.elbow_angle(configs[method]) if method in configs
                                  else None)
    row.update(extra)
    return row


def load_model(model_path: str):
    """The SB3 model (SAC when the file name says ``_sac``, else PPO), on the CPU."""
    from stable_baselines3 import PPO, SAC

    path = Path(model_path)
    if not path.exists():
        raise UsageError(f"no model at {path}")
    try:
        return (SAC if "_sac" in path.stem else PPO).load(path, device="cpu")
    except (ValueError, KeyError, OSError, zipfile.BadZipFile) as error:
        raise UsageError(f"--model: {path} is not a stable-baselines3 model saved by "
                         f"train.py ({str(error).splitlines()[0]})") from None


def model_robot(model_path: str, robot: str | None) -> str:
    """The robot a model is evaluated on: ``robot``, else the one its training summary
    (``<model>.json`` beside it, ``train.py``'s) names, else the default robot; a ``robot``
    other than the summary's is a UsageError."""
    summary = Path(model_path).with_suffix(".json")
    trained = None
    if summary.is_file():
        try:
            kwargs = json.loads(summary.read_text()).get("env_kwargs") or {}
        except (json.JSONDecodeError, AttributeError):
            kwargs = {}
        trained = kwargs.get("robot", SETTING_DEFAULTS["robot"])
    if robot is not None and trained is not None and robot != trained:
        raise UsageError(f"--robot {robot}: {model_path} was trained on robot {trained!r} "
                         f"({summary})")
    return robot or trained or SETTING_DEFAULTS["robot"]


def evaluate(model_path: str, sigma: float, draws: int, oracle_draws: int, grid: int,
             seed: int, processes: int = 1, limit: int | None = None,
             random_angles: int = 4, optimizer_samples: int = 0,
             optimizer_seed: int | None = None, grasp_file: str | None = None,
             engine: str = "pybullet", robot: str | None = None) -> dict:
    """Evaluate every method on the held-out grasps, or on every grasp of ``grasp_file``
    (see the module docstring); the result holds the settings, one row per grasp and
    :func:`summarize`'s fields.

    ``optimizer_samples`` defaults to 0 here (no optimizer, as before it existed); the
    command line's default is 1000. ``optimizer_seed`` defaults to ``seed + 1``.
    """
    import gymnasium as gym
    from tqdm import tqdm

    import kinegrasp_env  # noqa: F401
    from kinegrasp_env.montecarlo.execution import LocalExecutor
    from kinegrasp_env.sampling.noise import JointNoise

    model = load_model(model_path)
    robot = model_robot(model_path, robot)
    bins = getattr(model.action_space, "n", None)  # a policy over Discrete(bins) elbow angles
    tasks_from = ({"grasp_file": grasp_file} if grasp_file is not None
                  else {"split": "test"})
    try:
        env = gym.make("KineGraspSelect-v0", n_draws=1, robot=robot, **tasks_from,
                       action_bins=None if bins is None else int(bins)).unwrapped
    except ValueError as error:  # a grasp file naming an object not in the catalog, ...
        if grasp_file is None:
            raise UsageError(f"--robot {robot}: {error}") from None
        raise UsageError(f"--grasp-file: {error}; for agents/grasps/*.json, run "
                         "agents/prepare.py first") from None
    if model.observation_space.shape != env.observation_space.shape:
        env.close()
        raise UsageError(f"{model_path} observes {model.observation_space.shape[0]} values; "
                         f"the env of robot {robot!r} gives {env.observation_space.shape[0]} (a "
                         "model of another robot? --robot names the one it was trained on)")
    if model.action_space != env.action_space:
        env.close()
        raise UsageError(f"{model_path} acts in {model.action_space}; this script scores "
                         f"KineGraspSelect-v0 policies, whose actions are {env.action_space} "
                         "(a model trained on another env?)")
    settings = {"draws": draws, "oracle_draws": oracle_draws, "grid": grid,
                "random_angles": random_angles, "optimizer_samples": optimizer_samples,
                "optimizer_seed": seed + 1 if optimizer_seed is None else optimizer_seed}
    rng = np.random.default_rng(seed)
    tasks = [(name, i) for name in env.object_names for i in range(len(env.tasks[name]))]
    tasks = tasks[:limit] if limit else tasks
    rows = []
    # one pool for the whole run: its workers keep their engines between evaluations
    with LocalExecutor(processes) as executor:
        score = Scorer(JointNoise(sigma), seed, executor, engine)
        for name, index in tqdm(tasks, desc="held-out grasps", file=sys.stderr, disable=None):
            obs, _ = env.reset(seed=seed, options={"object": name, "grasp": index, "sigma": sigma})
            rows.append(evaluate_task(env, model, obs, score, settings, rng, executor))
    env.close()
    result = {"model": str(model_path), "robot": robot, "grasp_file": grasp_file,
              "engine": engine,
              "sigma": sigma, "draws": draws,
              "oracle_draws": oracle_draws, "grid": grid, "seed": seed,
              "random_angles": random_angles,
              "oracle_selection": f"chunks {scoring_chunks(draws)}.. of the seed (scoring: "
                                  f"chunks 0..{scoring_chunks(draws) - 1})",
              "optimizer_samples": optimizer_samples,
              "optimizer_seed": settings["optimizer_seed"], "rows": rows}
    return resummarize(result)


# ---------------------------------------------------------------------------- output
def _fmt_p(p: float) -> str:
    return "nan" if not math.isfinite(p) else f"{p:.1e}" if p < 0.0001 else f"{p:.4f}"


def table(result: dict) -> str:
    """Markdown tables of a result: mean P(FC) per method with 95% t-intervals, then the
    paired differences with their unadjusted and simultaneous intervals and p-values."""
    lines = [f"held-out grasps: {result['grasps']}"
             + (f" of {result['grasp_file']}" if result.get("grasp_file") else "")
             + f", sigma = {result['sigma']}, {result['draws']} draws per configuration "
               f"({result.get('engine', 'pybullet')} engine)",
             "", "| method | mean P(FC) | 95% t-CI |", "|---|---|---|"]
    for m, (mean, lo, hi) in result["mean_p_fc"].items():
        lines.append(f"| {m} | {mean:.3f} | {lo:.3f} .. {hi:.3f} |")
    tests = result.get("paired_tests", {})
    level = next(iter(tests.values()), {}).get("simultaneous_level", math.nan)
    lines += ["", f"| paired difference | mean | 95% t-CI | simultaneous 95% CI (Bonferroni, "
                  f"each {100 * level:.2f}%) | p | p (Holm) | wins/losses/ties |",
              "|---|---|---|---|---|---|---|"]
    for name, v in tests.items():
        lines.append(f"| {name} | {v['mean']:+.3f} | {v['ci'][0]:+.3f} .. {v['ci'][1]:+.3f} | "
                     f"{v['ci_simultaneous'][0]:+.3f} .. {v['ci_simultaneous'][1]:+.3f} | "
                     f"{_fmt_p(v['p'])} | {_fmt_p(v['p_holm'])} | "
                     f"{v['wins']}/{v['losses']}/{v['ties']} |")
    if "optimizer_gain_fraction" in result:
        lines += ["", "fraction of the optimizer's gain over nominal: " + ", ".join(
            f"{m} {f:+.2f}" for m, f in result["optimizer_gain_fraction"].items())]
    if "decision_seconds" in result:
        lines += ["", "mean decision time (s): " + ", ".join(
            f"{m} {s:.3g}" for m, s in result["decision_seconds"].items())]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default="agents/models/KineGraspSelect-v0_ppo.zip")
    parser.add_argument("--sigma", type=float, default=0.0283)
    parser.add_argument("--draws", type=int, default=2000)
    parser.add_argument("--oracle-draws", type=int, default=200,
                        help="draws per grid angle of the oracle's selection (0: leave the "
                             "oracle out)")
    parser.add_argument("--grid", type=int, default=12)
    parser.add_argument("--random-angles", type=int, default=4,
                        help="random elbow angles averaged per grasp (--draws shared)")
    parser.add_argument("--optimizer-samples", type=int, default=1000,
                        help="fast-engine draws per angle of the elbow optimizer (0: leave "
                             "the optimizer out)")
    parser.add_argument("--optimizer-seed", type=int, default=None,
                        help="seed of the optimizer's selection draws (default: --seed + 1)")
    parser.add_argument("--grasp-file", help="evaluate every grasp of this file (e.g. "
                        "agents/grasps/test.json, objects never trained on) instead of the "
                        "shipped sets' held-out split")
    parser.add_argument("--engine", default="pybullet", choices=("pybullet", "fast"),
                        help="engine of the scoring draws")
    parser.add_argument("--robot",
                        help="catalog robot the model was trained on (train.py --env-kwarg "
                             "robot=NAME; default: the one its training summary names, else "
                             "kuka_sdh): its held-out grasps, its env, its engines")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--limit", type=int, default=None,
                        help="evaluate only the first N held-out grasps")
    parser.add_argument("--quick", action="store_true", help="tiny run for tests")
    parser.add_argument("--out", help="write the result as JSON")
    parser.add_argument("--summarize", metavar="FILE",
                        help="recompute the summary of an existing result JSON from its "
                             "per-grasp rows and write it back (no evaluation run)")
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"),
                        help="paired comparison of the policy column of two result JSONs on "
                             "the same grasps and draws, A - B per grasp (no evaluation run; "
                             "--out writes it as JSON)")
    return parser


def check_args(args) -> None:
    """Raises UsageError naming the first bad value."""
    if args.oracle_draws < 0:
        raise UsageError(f"--oracle-draws must be >= 0, got {args.oracle_draws}")
    if args.grasp_file is not None and not Path(args.grasp_file).is_file():
        raise UsageError(f"--grasp-file: no file {args.grasp_file} (run agents/prepare.py)")
    for name in ("draws", "grid", "random_angles", "processes"):
        if getattr(args, name) < 1:
            raise UsageError(f"--{name.replace('_', '-')} must be >= 1, got "
                             f"{getattr(args, name)}")
    if not 0 <= args.sigma <= math.pi:
        raise UsageError(f"--sigma must be in [0, pi] radians, got {args.sigma}")
    if args.optimizer_samples < 0:
        raise UsageError(f"--optimizer-samples must be >= 0, got {args.optimizer_samples}")
    if args.limit is not None and args.limit < 1:
        raise UsageError(f"--limit must be >= 1, got {args.limit}")
    from kinegrasp_env.sampling.noise import is_integer_seed

    for name in ("seed", "optimizer_seed"):
        value = getattr(args, name)
        if value is not None and not is_integer_seed(value):
            raise UsageError(f"--{name.replace('_', '-')} must be an integer >= 0, got {value}")
    from kinegrasp_env.robot.catalog import check_robot_name
    from kinegrasp_env.robot.description import RobotDescriptionError

    try:
        if args.robot is not None:
            check_robot_name(args.robot)
    except RobotDescriptionError as error:
        raise UsageError(f"--robot: {error}") from None


def run_summarize(path: str) -> int:
    """``--summarize FILE``: recompute the summary from the rows and write the file back."""
    result = read_result(path)
    try:
        updated = resummarize(result)
    except (ValueError, KeyError, TypeError) as error:
        raise UsageError(f"--summarize: {path}: {error}") from None
    write_json_atomic(Path(path), updated)
    print(table(updated))
    return 0


def run_compare(path_a: str, path_b: str, out: str | None) -> int:
    """``--compare A B``: the paired comparison of the policy column, A - B; printed, and
    written as JSON to ``out`` when given."""
    a, b = read_result(path_a, "--compare"), read_result(path_b, "--compare")
    try:
        result = {"a": path_a, "b": path_b, **compare_results(a, b)}
    except (ValueError, KeyError, TypeError) as error:
        raise UsageError(f"--compare: {path_a} vs {path_b}: {error}") from None
    if out and not Path(out).resolve().parent.is_dir():
        raise UsageError(f"--out: no folder {Path(out).parent}")
    print(f"| {result['method']}: A - B | mean A | mean B | mean difference | 95% t-CI | p "
          f"| wins/losses/ties of A |\n|---|---|---|---|---|---|---|\n"
          f"| {path_a} - {path_b} (n = {result['grasps']}) | {result['mean_a']:.3f} | "
          f"{result['mean_b']:.3f} | {result['mean']:+.4f} | {result['ci'][0]:+.4f} .. "
          f"{result['ci'][1]:+.4f} | {_fmt_p(result['p'])} | "
          f"{result['wins']}/{result['losses']}/{result['ties']} |")
    if out:
        write_json_atomic(Path(out), result)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.summarize:
            return run_summarize(args.summarize)
        if args.compare:
            return run_compare(*args.compare, args.out)
        check_args(args)
        if args.quick:
            args.draws, args.oracle_draws, args.grid, args.processes = 20, 8, 3, 1
            args.random_angles, args.optimizer_samples = 2, 20
            args.limit = args.limit or 2
        if args.out and not Path(args.out).resolve().parent.is_dir():
            raise UsageError(f"--out: no folder {Path(args.out).parent}")
        result = evaluate(args.model, args.sigma, args.draws, args.oracle_draws, args.grid,
                          args.seed, args.processes, limit=args.limit,
                          random_angles=args.random_angles,
                          optimizer_samples=args.optimizer_samples,
                          optimizer_seed=args.optimizer_seed, grasp_file=args.grasp_file,
                          engine=args.engine, robot=args.robot)
    except UsageError as error:
        print(f"evaluate: error: {error}", file=sys.stderr)
        return 2
    print(table(result))
    if args.out:
        write_json_atomic(Path(args.out), result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
