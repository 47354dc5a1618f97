"""Re-weighted P(FC) against direct draws for a description robot (default: the Panda).

The calibration of ``bench_reweight.py`` on another robot's grasps: for the first
``--grasps`` shipped grasps of each object (fixed before any run), at ``--angles`` elbow
angles spread over each grasp's reachable self-motion (``elbow --robot``'s) and the paper's
four noise levels, one batch of ``--batch`` closings over the palm's deviation (the robot's
palm error, closed by its fast engine at the grasp's own configuration) is re-weighted to
each case and compared with ``--direct`` joint-noise draws at that angle (``evaluate
--robot``'s, fast engine), and with ``--direct`` deltas drawn from the linear-Gaussian model,
closed at the grasp's own configuration as the batch is (the method's first-order bias,
sampling error aside, the arm's links included: they stay where that configuration puts
them). The verdicts are ``bench_reweight.py``'s.

Writes ``benchmarks/results/bench_reweight_robot.json`` and the table in
docs/guides/elbow.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_reweight import judged_cases, spread_angles, summary
from results_file import add_options, publish, settings

from kinegrasp_env.montecarlo.palm_batch import (
    PalmJacobian,
    close_batch,
    close_deltas,
    linear_draws,
)
from kinegrasp_env.montecarlo.robot_evaluate import (
    RobotReferenceEngine,
    evaluate_robot_grasp,
    make_engine,
)
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.endeffector import PAPER_SIGMAS
from kinegrasp_env.toolkit.elbow import nominal_index
from kinegrasp_env.toolkit.robot_elbow import robot_reachable_configurations
from kinegrasp_env.world.grasps import shipped_grasps, shipped_objects

DOC = Path(__file__).resolve().parents[1] / "docs" / "guides" / "elbow.md"
START, END = "<!-- reweight-robot-calibration:start -->", "<!-- reweight-robot-calibration:end -->"


def calibration(grasp, args, seed: int) -> list[dict]:
    """One record per (angle, sigma) case of one grasp."""
    import dataclasses

    description = load_robot(grasp.robot)
    with RobotReferenceEngine(description, grasp.object) as reference:
        reach = robot_reachable_configurations(grasp, reference)
    angles = spread_angles(reach, args.angles)
    q0 = reach[nominal_index(grasp, reach)][1]
    jac = PalmJacobian(description)
    qs = np.stack([q for _, q in angles])
    covs = np.concatenate([jac.covariance(qs, s) for s in args.sigmas])
    batch = close_batch(q0, grasp.object, covs, args.batch, seed, robot=grasp.robot)
    with make_engine("fast", description, grasp.object) as engine:

        def direct(psi, q, sigma) -> float:
            return evaluate_robot_grasp(dataclasses.replace(grasp, q0=q), sigma=sigma,
                                        n=args.direct, seed=seed + 1, engine=engine).p_fc

        def linear(q, cov) -> np.ndarray:  # closed where the batch is: the grasp's own q
            return close_deltas(q0, linear_draws(cov, args.direct, seed + 2), grasp.object,
                                robot=grasp.robot)[0]

        return judged_cases({"robot": grasp.robot, "object": grasp.object, "grasp": grasp.id},
                            angles, covs, batch, direct, linear, args)


def markdown(result: dict) -> str:
    s, run = result["summary"], result["settings"]
    lines = [
        f"Robot {run['robot']}: re-weighted P(FC) against {run['direct']:,} direct draws per "
        f"case ({s['cases']} cases: {run['angles']} elbow angles x {len(run['sigmas'])} "
        f"noise levels x {len(result['grasps'])} grasps; one batch of {run['batch']:,} "
        "closings per grasp, the fast engine). Written by "
        "`python benchmarks/bench_reweight_robot.py`.", "",
        "| figure | value |", "|---|---|",
        f"| cases within the 95% interval of their difference (ESS and draws, pooled) | "
        f"{s['agree']} / {s['cases']} ({100 * s['agree_share']:.1f}%) |",
        f"| the weights alone: against {run['direct']:,} direct linear-Gaussian deviations "
        f"| {s['agree_with_linear']} / {s['cases']} |",
        f"| differences in standard errors: mean, s.d. | {s['z_mean']:+.2f}, "
        f"{s['z_sd']:.2f} |",
        f"| smallest effective sample size | {s['min_ess']:.0f} |",
        f"| linearisation bias, largest / mean absolute | {s['max_abs_linear_bias']:.4f} / "
        f"{s['mean_abs_linear_bias']:.4f} |",
        f"| cases whose bias is above 0.01 beyond its interval | "
        f"{s['linear_bias_surely_above_0.01']} |", "",
        "| object | sigma | cases agreeing | weights alone agreeing | largest abs. "
        "difference | mean bias of the linearisation | largest abs. bias |",
        "|---|---|---|---|---|---|---|"]
    for obj in dict.fromkeys(c["object"] for c in result["cases"]):
        for sigma in run["sigmas"]:
            rows = [c for c in result["cases"] if c["object"] == obj and c["sigma"] == sigma]
            lines.append(
                f"| {obj} | {sigma:g} | {sum(c['agrees'] for c in rows)} / {len(rows)} | "
                f"{sum(c['agrees_with_linear'] for c in rows)} / {len(rows)} | "
                f"{max(abs(c['difference']) for c in rows):.4f} | "
                f"{np.mean([c['linear_bias'] for c in rows]):+.4f} | "
                f"{max(abs(c['linear_bias']) for c in rows):.4f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default="panda")
    parser.add_argument("--grasps", type=int, default=1, help="first N shipped grasps each")
    parser.add_argument("--angles", type=int, default=18)
    parser.add_argument("--sigmas", type=float, nargs="+", default=list(PAPER_SIGMAS))
    parser.add_argument("--batch", type=int, default=40000)
    parser.add_argument("--direct", type=int, default=20000)
    add_options(parser, __file__)
    args = parser.parse_args()
    grasps = [g for obj in shipped_objects(args.robot)
              for g in shipped_grasps(obj, args.robot)[:args.grasps]]
    cases = [c for i, g in enumerate(grasps) for c in calibration(g, args, seed=10 * i)]
    result = {"summary": summary(cases, [{"ratio": float("nan")}], [{"ratio": float("nan")}]),
              "grasps": [f"{g.object} {g.id}" for g in grasps], "cases": cases,
              "settings": settings(args)}
    publish(__file__, result, args, markdown(result), DOC, (START, END))


if __name__ == "__main__":
    main()
