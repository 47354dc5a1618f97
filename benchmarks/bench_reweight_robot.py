"""Re-weighted P(FC) against direct draws for a description robot (default: the Panda).

The calibration of ``bench_reweight.py`` on another robot's grasps: for the first
``--grasps`` shipped grasps of each object (fixed before any run), at ``--angles`` elbow
angles spread over each grasp's reachable self-motion (``elbow --robot``'s) and the paper's
four noise levels, one batch of ``--batch`` closings over the palm's deviation (the robot's
palm error, closed by its fast engine at the grasp's own configuration) is re-weighted to
each case (``--replicates`` independent batches, each judged on every case) and compared
with ``--direct`` joint-noise draws at that angle (each case its own draws) (``evaluate
--robot``'s, fast engine), and with ``--direct`` deltas drawn from the Gaussian model,
closed at the grasp's own configuration as the batch is (the model's own bias,
sampling error aside, the arm's links included: they stay where that configuration puts
them). The verdicts are ``bench_reweight.py``'s.

Writes ``benchmarks/results/bench_reweight_robot.json`` and the table in
docs/guides/elbow.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_reweight import (
    calibration_rows,
    calibration_table,
    case_seeds,
    judged_cases,
    spread_angles,
    summary,
)
from results_file import add_options, publish, settings

from kinegrasp_env.montecarlo.evaluate import (
    RobotReferenceEngine,
    evaluate_grasp,
    make_engine,
)
from kinegrasp_env.montecarlo.palm_batch import (
    PalmJacobian,
    close_batch,
    close_deltas,
    linear_draws,
)
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.endeffector import PAPER_SIGMAS
from kinegrasp_env.toolkit.elbow import nominal_index
from kinegrasp_env.toolkit.elbow_search import robot_reachable_configurations
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
    means = np.concatenate([jac.mean(qs, s) for s in args.sigmas])
    seeds = case_seeds(seed)
    batches = [close_batch(q0, grasp.object, covs, args.batch, seeds["batch"](r),
                           robot=grasp.robot) for r in range(args.replicates)]
    with make_engine("fast", description, grasp.object) as engine:

        def direct(psi, q, sigma, k) -> float:
            return evaluate_grasp(dataclasses.replace(grasp, q0=q), sigma=sigma,
                                  n=args.direct, seed=seeds["direct"](k),
                                  engine=engine).p_fc

        def linear(q, cov, mean, k) -> np.ndarray:  # closed where the batch is: the grasp's q
            return close_deltas(q0, linear_draws(cov, args.direct, seeds["linear"](k), mean),
                                grasp.object, robot=grasp.robot)[0]

        return judged_cases({"robot": grasp.robot, "object": grasp.object, "grasp": grasp.id},
                            angles, covs, means, batches, direct, linear, args)


def markdown(result: dict) -> str:
    s, run = result["summary"], result["settings"]
    return "\n".join([
        f"Robot {run['robot']}: re-weighted P(FC) against {run['direct']:,} direct draws per "
        f"case ({s['cases']} cases: {run['angles']} elbow angles x {len(run['sigmas'])} "
        f"noise levels x {len(result['grasps'])} grasps, each case's draws its own; "
        f"{s['replicates']} independent batches of {run['batch']:,} closings per grasp, the "
        "fast engine). Written by `python benchmarks/bench_reweight_robot.py`.", "",
        "| figure | value |", "|---|---|", *calibration_rows(result), "",
        *calibration_table(result)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default="panda")
    parser.add_argument("--grasps", type=int, default=1, help="first N shipped grasps each")
    parser.add_argument("--angles", type=int, default=18)
    parser.add_argument("--sigmas", type=float, nargs="+", default=list(PAPER_SIGMAS))
    parser.add_argument("--batch", type=int, default=40000)
    parser.add_argument("--direct", type=int, default=20000)
    parser.add_argument("--replicates", type=int, default=5,
                        help="independent batches per grasp, each judged on every case")
    add_options(parser, __file__)
    args = parser.parse_args()
    grasps = [g for obj in shipped_objects(args.robot)
              for g in shipped_grasps(obj, args.robot)[:args.grasps]]
    cases = [c for i, g in enumerate(grasps) for c in calibration(g, args, seed=10 * i)]
    result = {"summary": summary(cases, [], []),
              "grasps": [f"{g.object} {g.id}" for g in grasps], "cases": cases,
              "settings": settings(args)}
    publish(__file__, result, args, markdown(result), DOC, (START, END))


if __name__ == "__main__":
    main()
