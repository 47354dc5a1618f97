"""Common random numbers across noise settings: the variance of a paired difference of P(FC)
against an unpaired one.

Every source of a noise model draws from its own stream, so two settings evaluated with the
same seed share the draws of every source they have in common. For pairs of settings
(A, B) on the spray-flask Table I grasps this prints, over ``--replicates`` seeds of
``--samples`` draws each, the variance of p_A - p_B when both use the same seed (paired) and
when B uses another seed (unpaired), and their ratio; and the same from one run's per-draw
indicators: Var(Y_A - Y_B) / n against (Var Y_A + Var Y_B) / n.

    python benchmarks/crn_variance.py --samples 500 --replicates 20

The figures (differences, variances, ratios, seconds) also go to
``benchmarks/results/crn_variance.json`` (``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from results_file import add_options, settings, write_result

from kinegrasp_env.montecarlo.chunks import robot_engine
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.sampling.noise_spec import noise_model_from_spec
from kinegrasp_env.world.grasps import shipped_grasps

DEXNET = {"preset": "dexnet"}
FRICTION = {"distribution": "gaussian", "mean": 0.5, "sigma": 0.1}
PAIRS = {
    "joint sigma 0.0233 vs 0.0333 (+ Dex-Net)": ({**DEXNET, "joints": {"sigma": 0.0233}},
                                                 {**DEXNET, "joints": {"sigma": 0.0333}}),
    "with vs without friction (joints 0.0233)": ({"joints": {"sigma": 0.0233},
                                                  "friction": FRICTION},
                                                 {"joints": {"sigma": 0.0233}}),
    "object pose 1 cm vs 5 mm (+ joints 0.0233)": (
        {"joints": {"sigma": 0.0233}, "object": {"translation_sigma": 0.01,
                                                 "rotation_sigma": 0.01}},
        {"joints": {"sigma": 0.0233}, "object": {"translation_sigma": 0.005,
                                                 "rotation_sigma": 0.01}}),
}


def indicators(grasp, spec: dict, samples: int, seed: int) -> np.ndarray:
    engine = robot_engine("fast", grasp.robot, grasp.object)  # built once, kept
    stats = evaluate_grasp(grasp, noise_model=noise_model_from_spec(spec), n=samples,
                           seed=seed, engine=engine)
    return (stats.draws.outcome == FORCE_CLOSURE).astype(float)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=500)
    parser.add_argument("--replicates", type=int, default=20)
    parser.add_argument("--grasps", default="0,1,4")
    add_options(parser, __file__)
    args = parser.parse_args()
    start = time.perf_counter()
    rows = []
    print(f"{'pair':<44} {'grasp':>5} {'p_A - p_B':>9} {'var paired':>11} "
          f"{'var unpaired':>12} {'ratio':>6} | per-draw ratio")
    for name, (spec_a, spec_b) in PAIRS.items():
        for index in (int(i) for i in args.grasps.split(",")):
            grasp = shipped_grasps("spray_flask")[index]
            seeds = range(args.replicates)
            y_a = [indicators(grasp, spec_a, args.samples, s) for s in seeds]
            y_b = [indicators(grasp, spec_b, args.samples, s) for s in seeds]
            p_a, p_b = np.array([y.mean() for y in y_a]), np.array([y.mean() for y in y_b])
            paired = np.var(p_a - p_b, ddof=1)
            unpaired = np.var(p_a - np.roll(p_b, 1), ddof=1)  # B from another seed
            per_draw = [np.var(a - b, ddof=1) / (np.var(a, ddof=1) + np.var(b, ddof=1))
                        for a, b in zip(y_a, y_b, strict=True)]
            print(f"{name:<44} {index:>5} {np.mean(p_a - p_b):>9.4f} {paired:>11.2e} "
                  f"{unpaired:>12.2e} {paired / unpaired:>6.3f} | {np.mean(per_draw):.3f}",
                  flush=True)
            rows.append({"pair": name, "grasp": index, "p_a_minus_p_b": np.mean(p_a - p_b),
                         "var_paired": paired, "var_unpaired": unpaired,
                         "paired_over_unpaired": paired / unpaired,
                         "per_draw_ratio": np.mean(per_draw)})
    seconds = time.perf_counter() - start
    print(f"{args.samples} draws x {args.replicates} seeds per setting, "
          f"{seconds:.0f} s")
    if not args.no_json:
        write_result(__file__, {"wall_s": seconds, "pairs": rows, "settings": settings(args)},
                     args.json_out)


if __name__ == "__main__":
    main()
