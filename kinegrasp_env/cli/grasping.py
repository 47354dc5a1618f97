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
    output_folder,
    parse_seed,
    positive_int,
    reported,
)
from kinegrasp_env.cli.elbow_output import batch_sized, twice_samples
from kinegrasp_env.cli.evaluation import run_evaluate
from kinegrasp_env.cli.execution_options import add_execution_args, executor_from
from kinegrasp_env.cli.figure_grasps import (
    FIGURE_GRASPS,
    TABLE1_GRASPS,
    TABLE1_OBJECT,
    figure_grasps,
    is_count,
    written,
)
from kinegrasp_env.cli.grasp_choice import EVALUATE_OBJECT, chosen_grasp
from kinegrasp_env.robot.default import DEFAULT_ROBOT


def cmd_evaluate(args) -> int:
    noise, sigma, samples, seed = noise_from(args)
    friction = friction_from(args, noise)
    index, grasp = chosen_grasp(args)
    return run_evaluate(args, index, grasp, args.robot or grasp.robot, sigma, samples, seed,
                          friction, noise)


def cmd_reproduce(args) -> int:
    from kinegrasp_env.toolkit import experiments
    from kinegrasp_env.toolkit.selection import provenance

    samples = positive_int(args.samples, "--samples")
    engine = engine_name(args.engine)
    friction = friction_from(args)
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
    from kinegrasp_env.cli.robot_reproduce import EVERY_ROBOT, reproduce_robot

    args.robot = args.robot or DEFAULT_ROBOT
    if args.robot != DEFAULT_ROBOT or args.figure in EVERY_ROBOT:
        return reproduce_robot(args, samples, friction)
    # the default robot's fig7 and fig10: its own planner's variants of each palm pose
    out = str(output_folder(args.out or f"out/{args.figure}"))  # before any work
    seed = parse_seed(args.seed)
    if args.figure == "fig10":
        objects, sets, count = figure_grasps(args.object, args.grasps)
    with executor_from(args) as executor:
        if args.figure == "fig7":
            rows = experiments.fig7(out, samples=samples, seed=seed, engine=engine,
                                    executor=executor, progress=True, friction=friction)
            print(f"robust and fragile arm configurations {provenance(samples, seed)}")
            print_pairs(rows)
            figures = [f"fig7_{name}.png" for name in dict.fromkeys(r["object"] for r in rows)]
            print(written(out, ["fig7.csv", *figures]))
            return 0
        with reported(ValueError), batch_sized(twice_samples):  # other palm poses
            rows = experiments.fig10(out, samples=samples, seed=seed, count=count,
                                     engine=engine, executor=executor, progress=True,
                                     objects=objects, grasp_sets=sets, method=method,
                                     friction=friction)
    for r in rows:
        shown = "" if method == "direct" else f" (effective sample {r['samples']})"
        print(f"{r['object']:<12} id {r['id']:<5} P(FC) {r['p_fc']:.3f} Q mean "
              f"{r['q_mean']:.5f} nominal {r['q_nominal']:.5f}{shown}")
    pairs = [{**r, "p_fc": r["fresh_p_fc"], "p_fc_lo": r["fresh_p_fc_lo"],
              "p_fc_hi": r["fresh_p_fc_hi"]} for r in rows if r.get("config")]
    if pairs:
        from kinegrasp_env.montecarlo.palm_batch import BATCH_FACTOR

        batch = None if method == "direct" else BATCH_FACTOR * samples
        print(f"robust and fragile variants {provenance(samples, seed, batch=batch)}")
        print_pairs(pairs)
    print(written(out, ["fig10.csv", "fig10.png"]))
    return 0


def print_pairs(rows: list[dict]) -> None:
    """The robust and fragile rows of fig7/fig10 (fresh draws), and per object their paired
    gap."""
    from kinegrasp_env.toolkit.selection import format_gap

    objects = list(dict.fromkeys(r["object"] for r in rows))
    order = {"robust": 0, "fragile": 1}
    for r in sorted(rows, key=lambda r: (objects.index(r["object"]), order[r["config"]])):
        print(f"{r['object']:<12} {r['config']:<8} id {r['id']:<5} P(FC) {r['p_fc']:.3f} "
              f"(95% CI {r['p_fc_lo']:.3f} .. {r['p_fc_hi']:.3f}), chosen at "
              f"{r['selection_p_fc']:.3f}")
        if r["config"] == "fragile":
            print(f"{r['object']:<12} robust - fragile {format_gap(r)}, paired")


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
    add_object_arg(p, None, f"catalog object: table1's (default {TABLE1_OBJECT}); fig9, "
                   "fig10: only this one (default: the four built-in objects)")
    p.add_argument("--samples", default="10000", help="Monte Carlo draws per cell")
    p.add_argument("--grasps", help=f"a count: the first N shipped grasps (table1, default "
                   f"{TABLE1_GRASPS} or the whole set where it has fewer, at most the set; "
                   f"fig9, default {FIGURE_GRASPS}) or N variants of grasp 0 (fig10, default "
                   f"{FIGURE_GRASPS}); or a grasp file (`kinegrasp plan`'s output; needed for "
                   f"an imported object): table1 all its grasps, fig9 its first "
                   f"{FIGURE_GRASPS}, fig10 variants of its first")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_execution_args(p, 2)
    # fast by default: the same draws as the reference, and the same outcome for all but a few
    # in 10,000 of them (benchmarks/robot_agreement.py; the default robot's own engines of
    # fig7 and fig10: benchmarks/agreement.py); --engine pybullet runs the reference
    add_engine_arg(p, "fast")
    add_friction_arg(p)
    p.add_argument("--out", help="output folder (default out/<figure>)")
    p.add_argument("--method", default="direct", choices=("direct", "reweight"),
                   help="fig10: direct (each variant on its own draws) or reweight (every "
                   "variant from one batch of closings over the palm's deviation, each row's "
                   "samples its effective sample size; the robust and fragile pair still on "
                   "fresh direct draws); the other experiments run direct")
    p.add_argument("--robot", help=f"catalog robot (default {DEFAULT_ROBOT}, the paper's). "
                   "Another robot: the same protocols on its shipped grasps or --grasps FILE "
                   "(no paper values beside them); fig7 and fig10 move a 7-joint arm along "
                   "its self-motion, or compare a 6-joint arm's IK branches")
    p.set_defaults(func=cmd_reproduce)
