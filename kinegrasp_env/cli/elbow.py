"""``kinegrasp elbow``: the most robust elbow angle of a grasp, with its certificate (and,
with ``--report FILE``, its HTML page: :func:`kinegrasp_env.cli.report.write_elbow_report`)."""

from __future__ import annotations

import json
import sys

from kinegrasp_env.cli.common import (
    add_execution_args,
    add_noise_args,
    add_object_arg,
    executor_from,
    grasp_index_help,
    noise_from,
    output_file,
    shipped_grasp,
)


def cmd_elbow(args) -> int:
    from tqdm import tqdm

    from kinegrasp_env.cli.report import report_path, write_elbow_report
    from kinegrasp_env.toolkit.elbow import optimize_elbow

    noise, sigma, samples, seed = noise_from(args)
    index, grasp = shipped_grasp(args.object, args.grasp)
    if args.plot:
        output_file(args.plot, "--plot")
    report_path(args.report)
    bar = tqdm(desc=f"elbow angles of {args.object} grasp {index}", unit="angle",
               file=sys.stderr, disable=None)
    with executor_from(args) as executor:
        result = optimize_elbow(grasp, noise, samples, seed, engine=args.engine,
                                executor=executor,
                                progress=lambda done: bar.update(done - bar.n))
    bar.close()
    payload = result.to_json()
    if args.plot:
        from kinegrasp_env.toolkit.plots import plot_elbow_curve

        plot_elbow_curve(payload["curve"], result.nominal_psi, result.best_psi, args.plot,
                         title=f"{args.object} grasp {index}, sigma = {sigma:g} rad: P(FC) "
                               f"along the self-motion")
    if args.json:
        print(json.dumps(payload))
    else:
        print(text_summary(payload, index))
        if args.plot:
            print(f"  plot written to {args.plot}")
    if args.report:
        write_elbow_report(args, grasp, index, result, noise)
    return 0


def text_summary(result: dict, index: int) -> str:
    """The console summary of an elbow optimization (``ElbowResult.to_json()``)."""
    lo, hi = result["best_p_fc_ci"]
    nlo, nhi = result["nominal_p_fc_ci"]
    glo, ghi = result["gain_ci"]
    return "\n".join([
        f"{result['object']} grasp {index}, sigma = {result['sigma']} rad, "
        f"{len(result['curve'])} elbow angles x {result['samples']} draws "
        f"({result['engine']} engine)",
        f"  nominal elbow {result['nominal_psi']:+.3f} rad: P(FC) "
        f"{result['nominal_p_fc']:.3f} ({nlo:.3f} .. {nhi:.3f})",
        f"  best elbow    {result['best_psi']:+.3f} rad: P(FC) "
        f"{result['best_p_fc']:.3f} ({lo:.3f} .. {hi:.3f})  [independent draws]",
        f"  gain over nominal {result['gain']:+.3f} (95% CI {glo:+.3f} .. {ghi:+.3f}, paired)",
        f"  P(a better evaluated angle was missed) <= {result['miss_probability']:.3f} "
        f"(grid step {result['grid_step']:.3f} rad)"])


def add_commands(sub) -> None:
    """Register ``elbow``."""
    p = sub.add_parser("elbow", help="P(FC) along a grasp's self-motion: the most robust elbow "
                       "angle, its gain over the nominal one, with intervals")
    add_object_arg(p, "spray_flask", "catalog object")
    p.add_argument("--grasp", default="0", help=grasp_index_help())
    add_noise_args(p, 0.0133)
    p.set_defaults(samples="1000")
    add_execution_args(p, 1)
    p.add_argument("--engine", default="fast", choices=("fast", "pybullet"),
                   help="fast (default: many angles x draws) or pybullet (the reference)")
    p.add_argument("--plot", help="write a PNG of P(FC) against the elbow angle")
    p.add_argument("--report", help="write a self-contained interactive HTML page: P(FC) "
                   "along the self-motion, the arm at the nominal and at the best elbow in 3-D")
    p.set_defaults(func=cmd_elbow)
