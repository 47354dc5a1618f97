"""Calibration of the elbow certificate: how often the statement ``kinegrasp elbow`` prints is
false, on curves whose truth is known, against its error level delta.

The statement (``toolkit/elbow_certificate.py``): "with confidence 1 - delta no evaluated elbow
angle beats the chosen one by more than B in P(FC)". It is false in a run when the true
max_j (p_j - p_chosen) over the run's evaluated angles exceeds B (B as computed, before it is
rounded up for printing, so the count is of a claim at least as strong as the printed one).
"Certified at epsilon" (B <= epsilon) is false when it is certified and the true max exceeds
epsilon; it is implied by the first, so it is false at most as often.

* **Synthetic** (``--reps`` runs per curve and per draw count): 18 angles with a known P(FC)
  curve (``plateau``: six tied best angles; ``smooth``: one broad peak, two angles within
  0.002 of it; ``two_peaks``: 0.62 and 0.60, far apart; ``flat``: all 0.5; ``pair``: two
  tied best angles at 0.6, the rest at 0.4, the case where B is set by the one rival that
  matters, so the false rate comes closest to delta; ``near_tie``: 0.600 and 0.598, the rest
  0.45, with weakly correlated angles, rho = phi = 0.5: the case that shows the replaced
  formula failing). Draws are
  correlated Bernoulli with common random numbers: draw i at angle j is in force closure when
  rho Z_i + sqrt(1 - rho^2) W_ji < Phi^-1(p_j), Z_i shared by all angles (the joint noise of
  the draw), W_ji an AR(1) sequence (coefficient phi) along the angles (neighbouring angles
  agree more), so the marginals are exactly p_j; rho = phi = 0.8 unless stated. A run
  chooses the best angle on one set of n draws and computes
  the certificate on n fresh draws, as the optimizer does (all 18 angles evaluated). The
  same runs also score the formula this certificate replaced (the sum over the rivals of
  Phi(mean(d_j) / se(d_j)) on the selection draws, printed as "P(a better evaluated angle was
  missed) <= x"): ``old_formula`` counts, among the runs where it printed x <= delta, those
  where a better evaluated angle had in truth been missed: what the benchmark shows of a
  certificate that does not hold.
* **Real** (``--grasps``): ``optimize_robot_elbow`` itself (fast engine, its coarse grid and
  refinement) with ``--runs`` fresh seeds per grasp at ``--real-samples`` draws per angle;
  the truth of every angle a run evaluated: ``--truth`` draws (20,000 by default) on a seed no
  run uses, the same draws for every angle (their differences are then far more precise than
  each P(FC); each run's margin is reported in units of the truth's standard error of the
  difference, so a run within 2 of them can be seen).

Each false rate comes with its exact (Clopper-Pearson) 95% interval. Writes
``benchmarks/results/bench_elbow_calibration.json`` and prints one summary line.

Usage: ``nice -n 10 python benchmarks/bench_elbow_calibration.py [--reps 400]
[--samples 250,1000] [--grasps spray_flask:4,spray_flask:2] [--runs 30] [--real-samples 250]
[--truth 20000] [--processes 1] [--only both|synthetic|real]``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats as sps

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from kinegrasp_env.toolkit.elbow_certificate import certify  # noqa: E402

ANGLES = 18
RHO, PHI = 0.8, 0.8
SIGMA = 0.0233
TRUTH_SEED = 987_654
RUN_SEED0 = 50_000


def curves() -> dict[str, np.ndarray]:
    """The synthetic truths: P(FC) of 18 angles, (18,) (correlations: :data:`CORRELATION`)."""
    j = np.arange(ANGLES, dtype=float)
    plateau = np.clip(0.60 - 0.02 * np.maximum(np.maximum(6 - j, j - 11), 0), 0, 1)
    smooth = 0.40 + 0.25 * np.exp(-0.5 * ((j - 8.5) / 3.5) ** 2)
    two = np.maximum(0.40 + 0.22 * np.exp(-0.5 * ((j - 4) / 1.5) ** 2),
                     0.40 + 0.20 * np.exp(-0.5 * ((j - 13) / 1.5) ** 2))
    pair = np.full(ANGLES, 0.4)
    pair[[8, 9]] = 0.6
    near = np.full(ANGLES, 0.45)
    near[[6, 7]] = 0.600, 0.598
    return {"plateau": plateau, "smooth": smooth, "two_peaks": two,
            "flat": np.full(ANGLES, 0.5), "pair": pair, "near_tie": near}


#: (rho, phi) of each curve's draws; the near tie's angles agree less (far-apart elbows).
CORRELATION = {"near_tie": (0.5, 0.5)}


def correlated_draws(p: np.ndarray, n: int, rng: np.random.Generator, rho: float = RHO,
                     phi: float = PHI) -> np.ndarray:
    """(m, n) bool force closure of m angles on n common draws (module docstring)."""
    z = rng.standard_normal(n)
    w = np.empty((p.size, n))
    w[0] = rng.standard_normal(n)
    for j in range(1, p.size):
        w[j] = phi * w[j - 1] + math.sqrt(1 - phi ** 2) * rng.standard_normal(n)
    latent = rho * z + math.sqrt(1 - rho ** 2) * w
    return latent < sps.norm.ppf(p)[:, None]


def old_formula(selection: np.ndarray, chosen: int) -> float:
    """The replaced formula on the selection draws (m, n): min(1, sum_j Phi(mean d_j /
    se d_j)), d_j = FC_j - FC_chosen; se = 0 counts 1 if mean d_j > 0, else 0."""
    total = 0.0
    for j in range(selection.shape[0]):
        if j != chosen:
            d = selection[j].astype(float) - selection[chosen]
            se = d.std(ddof=1) / math.sqrt(d.size)
            total += float(sps.norm.cdf(d.mean() / se)) if se > 0 else float(d.mean() > 0)
    return min(total, 1.0)


def rate(k: int, n: int) -> dict:
    """k false of n runs, with the exact 95% interval."""
    ci = sps.binomtest(k, n).proportion_ci(0.95, method="exact") if n else None
    return {"false": k, "runs": n, "rate": k / n if n else None,
            "ci95": [ci.low, ci.high] if ci else None}


def synthetic(reps: int, sizes: list[int], epsilon: float, delta: float, seed: int) -> dict:
    out = {}
    for name, p in curves().items():
        rho, phi = CORRELATION.get(name, (RHO, PHI))
        for n in sizes:
            rng = np.random.default_rng([seed, n, len(out)])
            false = false_eps = certified = old_claims = old_false = 0
            regret = []
            for _ in range(reps):
                selection = correlated_draws(p, n, rng, rho, phi)
                chosen = int(np.argmax(selection.mean(axis=1)))
                if old_formula(selection, chosen) <= delta:
                    old_claims += 1
                    old_false += bool(p.max() > p[chosen])
                fresh = correlated_draws(p, n, rng, rho, phi)
                others = [j for j in range(ANGLES) if j != chosen]
                cert = certify(float(chosen), fresh[chosen], [float(j) for j in others],
                               fresh[others], epsilon, delta)
                truth = float(p[others].max() - p[chosen])
                false += truth > cert.bound
                certified += cert.certified
                false_eps += cert.certified and truth > epsilon
                regret.append(float(p.max() - p[chosen]))
            out[f"{name}/n={n}"] = {
                "curve": name, "draws": n, "rho": rho, "phi": phi, "statement": rate(false, reps),
                "certified_at_epsilon": certified / reps,
                "certified_statement": rate(false_eps, reps),
                "mean_true_regret": float(np.mean(regret)),
                "old_formula": rate(old_false, old_claims)}
            print(f"  synthetic {name:9s} n={n:5d}: false {false}/{reps}, certified "
                  f"{certified}/{reps}; old formula false {old_false}/{old_claims}",
                  file=sys.stderr)
    return out


def real(grasp_names: list[str], runs: int, samples: int, truth_draws: int, epsilon: float,
         delta: float, processes: int = 1) -> dict:
    from kinegrasp_env.montecarlo.execution import LocalExecutor

    with LocalExecutor(processes) as executor:
        return _real(grasp_names, runs, samples, truth_draws, epsilon, delta, executor)


def _real(grasp_names: list[str], runs: int, samples: int, truth_draws: int, epsilon: float,
          delta: float, executor) -> dict:
    from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.toolkit.elbow import reachable_configurations, with_configuration
    from kinegrasp_env.toolkit.elbow_search import optimize_robot_elbow
    from kinegrasp_env.world.grasps import shipped_grasps

    noise = JointNoise(SIGMA)
    out = {}
    for item in grasp_names:
        name, index = item.split(":")
        grasp = shipped_grasps(name)[int(index)]
        start = time.time()
        reach = reachable_configurations(grasp)
        truth: dict[int, np.ndarray] = {}

        def truth_fc(i: int, grasp=grasp, reach=reach, truth=truth) -> np.ndarray:
            """(truth_draws,) force closure of angle reach[i] on the truth seed (cached)."""
            if i not in truth:
                psi, q = reach[i]
                stats = evaluate_grasp(with_configuration(grasp, q, psi), sigma=noise.sigma,
                                       noise=noise.kind, n=truth_draws, seed=TRUTH_SEED,
                                       engine="fast", executor=executor)
                truth[i] = stats.draws.outcome == FORCE_CLOSURE
            return truth[i]

        index_of = {id(q): i for i, (_, q) in enumerate(reach)}
        rows = []
        for r in range(runs):
            result = optimize_robot_elbow(grasp, noise, samples, RUN_SEED0 + r,
                                          evaluate_with="fast", epsilon=epsilon, delta=delta,
                                          reach=reach, executor=executor)
            evaluated = [index_of[id(p.q)] for p in result.curve]
            chosen = index_of[id(result.best_q)]
            best = truth_fc(chosen)
            diffs = []
            for i in evaluated:
                if i != chosen:
                    d = truth_fc(i).astype(float) - best
                    diffs.append((float(d.mean()), float(d.std(ddof=1) / math.sqrt(d.size))))
            cert = result.certificate
            worst, se = max(diffs)
            rows.append({"seed": RUN_SEED0 + r, "chosen_psi": result.best_psi,
                         "angles": len(evaluated), "bound": cert.bound,
                         "certified": cert.certified, "true_max_advantage": worst,
                         "truth_se": se, "false": worst > cert.bound,
                         "margin_in_truth_se": (cert.bound - worst) / se if se else None})
            print(f"  real {item} run {r + 1}/{runs}: B {cert.bound:+.3f}, true max "
                  f"{worst:+.4f}, {len(truth)} truths, {time.time() - start:.0f} s",
                  file=sys.stderr)
        false = sum(row["false"] for row in rows)
        false_eps = sum(row["certified"] and row["true_max_advantage"] > epsilon
                        for row in rows)
        out[item] = {"draws": samples, "truth_draws": truth_draws, "runs": rows,
                     "statement": rate(false, runs),
                     "certified_at_epsilon": sum(r["certified"] for r in rows) / runs,
                     "certified_statement": rate(false_eps, runs),
                     "within_2_truth_se": sum(r["margin_in_truth_se"] is not None
                                              and abs(r["margin_in_truth_se"]) < 2
                                              for r in rows),
                     "seconds": time.time() - start}
    return out


def pooled(parts: dict, key: str = "statement") -> dict:
    k = sum(v[key]["false"] for v in parts.values())
    n = sum(v[key]["runs"] for v in parts.values())
    return rate(k, n)


def percent(r: dict) -> str:
    lo, hi = r["ci95"]
    return (f"{r['false']}/{r['runs']} = {100 * r['rate']:.2f}% (95% CI {100 * lo:.2f}-"
            f"{100 * hi:.2f}%)")


def command(argv: list[str] | None) -> str:
    return " ".join(["python", "benchmarks/bench_elbow_calibration.py",
                     *(argv if argv is not None else sys.argv[1:])])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=400)
    ap.add_argument("--samples", default="250,1000")
    ap.add_argument("--grasps", default="spray_flask:4,spray_flask:2")
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--real-samples", type=int, default=250)
    ap.add_argument("--truth", type=int, default=20_000)
    ap.add_argument("--processes", type=int, default=1)
    ap.add_argument("--epsilon", type=float, default=0.05)
    ap.add_argument("--delta", type=float, default=0.05)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", choices=("both", "synthetic", "real"), default="both",
                    help="run one part and update only its section of an existing --out "
                    "(real: the grasps run, others kept)")
    ap.add_argument("--out",
                    default=str(ROOT / "benchmarks/results/bench_elbow_calibration.json"))
    args = ap.parse_args(argv)
    start = time.time()
    out = Path(args.out)
    result = json.loads(out.read_text()) if args.only != "both" and out.exists() else {}
    result.update(delta=args.delta, epsilon=args.epsilon)
    if args.only in ("both", "synthetic"):
        syn = synthetic(args.reps, [int(s) for s in args.samples.split(",")], args.epsilon,
                        args.delta, args.seed)
        result.update(synthetic=syn, synthetic_pooled=pooled(syn),
                      old_formula_pooled=pooled(syn, "old_formula"),
                      synthetic_command=command(argv))
        print(f"  the replaced formula, where it printed <= {args.delta:g}: false in "
              f"{percent(result['old_formula_pooled'])}", file=sys.stderr)
    if args.only in ("both", "real"):
        rl = real(args.grasps.split(","), args.runs, args.real_samples, args.truth,
                  args.epsilon, args.delta, args.processes)
        if args.only == "real":  # grasps run before (by another --only real) are kept
            rl = {**result.get("real", {}), **rl}
        sizes = sorted({(v["draws"], v["truth_draws"]) for v in rl.values()})
        result.update(sigma=SIGMA, real=rl, real_pooled=pooled(rl),
                      real_setting=f"{', '.join(rl)}; draws per angle, truth draws: "
                                   f"{', '.join(f'{n}, {t}' for n, t in sizes)}")
        result.setdefault("real_commands", []).append(command(argv))
    line = f"elbow certificate, delta {args.delta:g}: printed statement false in "
    if "synthetic_pooled" in result:
        line += f"{percent(result['synthetic_pooled'])} of synthetic runs"
    if "real_pooled" in result:
        line += (f"{', ' if 'synthetic_pooled' in result else ''}"
                 f"{percent(result['real_pooled'])} of real runs ({result['real_setting']})")
    result.update(summary=line, python=platform.python_version())
    result[f"seconds_{args.only}"] = time.time() - start
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
