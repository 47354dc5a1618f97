"""Which source of error dominates, per grasp: the Table I spray-flask grasps (shipped grasps
0-4) at the paper's joint sigmas plus the Dex-Net preset (object pose 1 cm / 0.01 rad,
gripper pose 5 mm / 0.001 rad, friction N(0.5, 0.1^2) truncated at 0).

For every grasp and sigma: P(FC) with every source, per source the gain of making it exact
(P(FC) without it minus with all, paired) and its total Sobol index; the dominant source (the
largest total index) and the one with the most to gain. Fast engine, ``--samples`` draws per
setting (about 11 settings per cell).

    python benchmarks/sensitivity_table.py --samples 400 [--json-out out.json | --no-json]

The table's rows (with P(FC)'s 95% interval) also go to
``benchmarks/results/sensitivity_table.json``.
"""

from __future__ import annotations

import argparse
import time

from results_file import add_options, settings, write_result

from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.sampling.noise_spec import noise_model_from_spec
from kinegrasp_env.toolkit.sensitivity import analyze
from kinegrasp_env.world.grasps import shipped_grasps

SIGMAS = (0.0133, 0.0233, 0.0333, 0.0433)
SOURCES = ("joints", "palm", "object", "friction")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=400)
    parser.add_argument("--bootstrap", type=int, default=300)
    parser.add_argument("--grasps", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    add_options(parser, __file__)
    args = parser.parse_args()
    engine = make_engine("fast", "kuka_sdh", "spray_flask")
    rows = []
    start = time.perf_counter()
    header = (f"{'grasp':>5} {'sigma':>6} {'P(FC)':>6} | gain if exact: {'joints':>6} "
              f"{'palm':>6} {'object':>6} {'frict.':>6} | total ST: {'joints':>5} {'palm':>5} "
              f"{'object':>6} {'frict.':>6} | dominant  most to gain")
    print(header)
    for index, grasp in enumerate(shipped_grasps("spray_flask")[:args.grasps]):
        for sigma in SIGMAS:
            model = noise_model_from_spec({"preset": "dexnet", "joints": {"sigma": sigma}})
            result = analyze(grasp, model, args.samples, args.seed, engine=engine,
                             bootstrap=args.bootstrap)
            effects = {e.source: e for e in result.effects}
            gains = " ".join(f"{effects[s].gain:>6.3f}" for s in ("joints", "palm", "object",
                                                                  "friction"))
            totals = " ".join(f"{effects[s].total:>{w}.3f}" for s, w in (
                ("joints", 5), ("palm", 5), ("object", 6), ("friction", 6)))
            print(f"{index:>5} {sigma:>6.4f} {result.p_all:>6.3f} | {'':>15}{gains} | "
                  f"{'':>10}{totals} | {result.dominant:<9} {result.most_to_gain}", flush=True)
            rows.append({"grasp": index, "sigma": sigma, "p_fc": result.p_all,
                         "p_fc_lo": result.p_all_ci[0], "p_fc_hi": result.p_all_ci[1],
                         **{f"gain_{s}": effects[s].gain for s in SOURCES},
                         **{f"total_{s}": effects[s].total for s in SOURCES},
                         "dominant": result.dominant, "most_to_gain": result.most_to_gain})
    seconds = time.perf_counter() - start
    print(f"{args.samples} draws per setting, {seconds:.0f} s")
    if not args.no_json:
        write_result(__file__, {"wall_s": seconds, "table": rows, "settings": settings(args)},
                     args.json_out)


if __name__ == "__main__":
    main()
