"""Grasp commands: ``evaluate`` (Monte Carlo P(FC) of one grasp) and
``reproduce`` (the paper's tables and figures: its protocol run on this project's stand-in
hand, objects and grasps; with ``--robot NAME`` on another robot's grasps).
"""

from __future__ import annotations

from kinegrasp_env.cli.common import (
    CLIError,
    add_engine_arg,
    add_friction_arg,
    add_hold_simulator_arg,
    add_noise_args,
    add_noise_spec_arg,
    add_object_arg,
    add_static_hold_arg,
    engine_name,
    friction_from,
    grasp_index_help,
    noise_from,
    positive_int,
)
from kinegrasp_env.cli.evaluation import run_evaluate
from kinegrasp_env.cli.execution_options import add_execution_args
from kinegrasp_env.cli.figure_grasps import (
    FIG7_VARIANTS,
    FIGURE_GRASPS,
    TABLE1_GRASPS,
    TABLE1_OBJECT,
    is_count,
)
from kinegrasp_env.cli.grasp_choice import EVALUATE_OBJECT, chosen_grasp
from kinegrasp_env.cli.output_paths import input_files, output_file, report_path
from kinegrasp_env.robot.default import DEFAULT_ROBOT


def cmd_evaluate(args) -> int:
    noise, sigma, samples, seed = noise_from(args)
    friction = friction_from(args, noise, simulated=args.engine == "physics"
                             or bool(getattr(args, "hold_test", False)))
    report_path(args.report, inputs=input_files(args))  # before a palm pose is solved
    if args.plot is not None:
        output_file(args.plot, "--plot", inputs=input_files(args))
    _, grasp = chosen_grasp(args)
    return run_evaluate(args, grasp, args.robot or grasp.robot, sigma, samples, seed,
                          friction, noise)


def cmd_reproduce(args) -> int:
    samples = positive_int(args.samples, "--samples")
    engine_name(args.engine)
    friction = friction_from(args, simulated=args.engine == "physics")
    if args.figure not in ("table1", "fig7", "fig9", "fig10"):
        raise CLIError(f"unknown experiment {args.figure!r}; available: table1, fig7, fig9, "
                       "fig10")
    method = getattr(args, "method", "direct")
    if method != "direct" and args.figure != "fig10":
        raise CLIError(f"--method {method} is for fig10 (variants of one palm pose); "
                       f"{args.figure} runs direct")
    if args.robot is None and args.grasps and not is_count(args.grasps):
        from kinegrasp_env.cli.grasp_report import grasp_file_robot

        args.robot = grasp_file_robot(args)  # a grasp file names its robot
    from kinegrasp_env.cli.reproduce import reproduce

    args.robot = args.robot or DEFAULT_ROBOT
    return reproduce(args, samples, friction)


def add_commands(sub) -> None:
    """Register ``evaluate`` and ``reproduce``."""
    p = sub.add_parser("evaluate", help="Monte Carlo P(FC) and quality of a shipped grasp or "
                       "of a grasp in a file")
    add_object_arg(p, None, f"catalog object, built-in or imported (default {EVALUATE_OBJECT}; "
                   "with --grasps: the grasp's own)")
    p.add_argument("--grasps", help="a grasp file (e.g. `kinegrasp plan`'s output) or a "
                   "palm-pose file (docs/palm_pose_candidates.json); --grasp is then an id in "
                   "it, or an index")
    p.add_argument("--grasp", default="0", help=grasp_index_help() + "; or with --grasps, an "
                   "id or index in that file")
    add_noise_args(p, 0.0133)
    add_noise_spec_arg(p)
    add_execution_args(p, 1)
    add_engine_arg(p)
    add_friction_arg(p)
    p.add_argument("--elbow", help="evaluate the grasp with the arm moved along its "
                   "self-motion to this elbow angle, radians (same palm pose and contacts; "
                   "see `kinegrasp elbow`)")
    p.add_argument("--plot", help="write a PNG of the draws' contacts on the object")
    p.add_argument("--report", help="write a self-contained interactive HTML page of the "
                   "evaluation (as `kinegrasp report`)")
    p.add_argument("--robot", help="catalog robot (default: the grasp file's, else "
                   f"{DEFAULT_ROBOT}); a grasp of another robot is refused")
    add_static_hold_arg(p, "prints P(hold, static)")
    p.add_argument("--hold-test", action="store_true",
                   help="also run the quick holding test on the same draws and print P(hold) "
                   "(it runs dynamics per draw, far slower than the kinematic draws: "
                   "benchmarks/quick_hold.py)")
    add_hold_simulator_arg(p)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("reproduce", help="run the protocol of a table or figure of the "
                       "paper on this project's stand-in models (hand, objects, grasps), or "
                       "on any catalog robot's grasps (--robot NAME)")
    p.add_argument("figure", choices=("table1", "fig7", "fig9", "fig10"),
                   help="the table or figure")
    add_object_arg(p, None, f"catalog object: table1's (default {TABLE1_OBJECT}); fig7, fig9, "
                   "fig10: only this one (default: every object the robot has shipped "
                   "grasps of)")
    p.add_argument("--samples", default="10000", help="Monte Carlo draws per cell")
    p.add_argument("--grasps", help=f"a count: the first N shipped grasps (table1, default "
                   f"{TABLE1_GRASPS} or the whole set where it has fewer, at most the set; "
                   f"fig9, default {FIGURE_GRASPS}) or N arm configurations of grasp 0 (fig7, "
                   f"default {FIG7_VARIANTS}; fig10, default {FIGURE_GRASPS}); or a grasp file "
                   f"(`kinegrasp plan`'s output; needed for an imported object): table1 all "
                   f"its grasps, fig9 its first {FIGURE_GRASPS}, fig7 and fig10 arm "
                   f"configurations of its first")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_execution_args(p, 2)
    # fast by default: the same draws as the reference, and the same outcome for all but a few
    # in 10,000 of them (benchmarks/robot_agreement.py); --engine pybullet runs the reference
    add_engine_arg(p, "fast")
    add_friction_arg(p)
    p.add_argument("--out", help="output folder (default out/<figure>)")
    p.add_argument("--method", default="direct", choices=("direct", "reweight"),
                   help="fig10: direct (each variant on its own draws) or reweight (every "
                   "variant from one batch of closings over the palm's deviation, each row's "
                   "samples its effective sample size; the robust and fragile pair still on "
                   "fresh direct draws); the other experiments run direct")
    p.add_argument("--robot", help=f"catalog robot (default {DEFAULT_ROBOT}, the paper's: "
                   "scripts/paper_side_by_side.py sets its results beside the paper's values), "
                   "on its shipped grasps "
                   "or --grasps FILE; fig7 and fig10 move a 7-joint arm along its "
                   "self-motion, or compare a 6-joint arm's IK branches")
    p.set_defaults(func=cmd_reproduce)
