"""Grasp commands: ``evaluate`` (Monte Carlo P(FC) of one grasp) and
``reproduce`` (the paper's tables and figures: its protocol run on this project's stand-in
hand, objects and grasps; with ``--robot NAME`` on another robot's grasps).
"""

from __future__ import annotations

import json
from pathlib import Path

from kinegrasp_env.cli.common import (
    CLIError,
    add_engine_arg,
    add_execution_args,
    add_friction_arg,
    add_noise_args,
    add_noise_spec_arg,
    add_object_arg,
    add_static_hold_arg,
    engine_name,
    executor_from,
    finite_float,
    friction_from,
    grasp_index_help,
    noise_from,
    output_file,
    output_folder,
    parse_seed,
    positive_int,
    reported,
)
from kinegrasp_env.cli.figure_grasps import FIGURE_GRASPS, figure_grasps, is_count
from kinegrasp_env.cli.grasp_choice import EVALUATE_OBJECT, chosen_grasp
from kinegrasp_env.cli.robot_grasps import (
    DEFAULT_ROBOT,
    IN_PROCESS,
    _check_engine,
    _refuse,
    evaluate_robot,
    refuse_hold_scores,
)

#: ``reproduce table1``'s object without --object, and its number of grasps without --grasps.
TABLE1_OBJECT, TABLE1_GRASPS = "spray_flask", "5"
#: The experiments that move a 7-joint arm along its self-motion.
SELF_MOTION_EXPERIMENTS = ("fig7", "fig10")


def cmd_evaluate(args) -> int:
    from kinegrasp_env.cli.report import evaluate_report, report_path
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp

    noise, sigma, samples, seed = noise_from(args)
    friction = friction_from(args, noise)
    index, grasp = chosen_grasp(args)
    robot = args.robot or grasp.robot
    if robot != DEFAULT_ROBOT or grasp.robot != DEFAULT_ROBOT:
        return evaluate_robot(args, index, grasp, robot, sigma, samples, seed, friction,
                              noise)
    refuse_hold_scores(args, robot)
    if args.elbow is not None:
        grasp = grasp_at_elbow(grasp, args.elbow)
    engine = engine_name(args.engine)
    if args.plot:
        output_file(args.plot, "--plot")
    report_path(args.report)
    with executor_from(args) as executor:
        stats = evaluate_grasp(grasp, noise, samples, seed, engine=engine, friction=friction,
                               return_draws=bool(args.plot or args.report), progress=True,
                               executor=executor)
    label = f"noise spec {args.noise_spec}" if args.noise_spec else f"sigma = {sigma:g} rad"
    per_draw = getattr(noise, "friction", None) is not None  # the spec's source sets mu
    if args.json:
        print(json.dumps({**stats.to_json(), **({} if per_draw else {"friction": friction})}))
    else:
        lo, hi = stats.p_fc_ci
        full = label if args.noise_spec else f"{label} ({args.noise})"
        mu = "friction mu per draw" if per_draw else f"friction mu {friction:g}"
        print(f"{args.object} grasp {index}, {full}, {samples} draws, {mu}")
        print(f"  P(FC)   = {stats.p_fc:.4f}  (95% CI {lo:.4f} .. {hi:.4f})")
        print(f"  Q (Ferrari-Canny, dimensionless; mean, std, skewness over the force-closure "
              f"draws): nominal {stats.q_nominal:.5f}, mean {stats.q_mean:.5f}, std "
              f"{stats.q_std:.5f}, skewness {stats.q_skew:.3f}, error (nominal - mean) "
              f"{stats.error:.5f}")
        print("  outcomes: " + ", ".join(f"{k} {v}" for k, v in stats.outcomes.items()))
    if args.plot:  # after the results: a failing figure is a warning, the results stand
        from kinegrasp_env.toolkit.plots import plot_contacts, safe_figure
        from kinegrasp_env.world.objects import load_object

        written = safe_figure(lambda: plot_contacts(
            load_object(args.object).mesh, stats.draws, args.plot,
            title=f"{args.object} grasp {index}, {label}: P(FC) = {stats.p_fc:.3f}"),
            args.plot)
        if written is not None and not args.json:
            print(f"  plot written to {args.plot}")
    if args.report:
        evaluate_report(args, grasp, index, stats)
    return 0


def grasp_at_elbow(grasp, text: str):
    """``--elbow PSI``: the grasp reached with the arm moved along its self-motion to elbow
    angle PSI (radians; same palm pose, same nominal contacts)."""
    from kinegrasp_env.toolkit.elbow import configuration_at, with_configuration

    psi = finite_float(text, "--elbow")
    with reported(ValueError):  # out of reach: the message names the reachable range
        q = configuration_at(grasp, psi)
    return with_configuration(grasp, q, psi)


def cmd_reproduce(args) -> int:
    from kinegrasp_env.toolkit import experiments
    from kinegrasp_env.toolkit.experiments import markdown_table1, table1
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
    if args.robot not in (None, DEFAULT_ROBOT):
        if method != "direct":
            raise CLIError(f"--method {method} is not available for robot {args.robot!r} "
                           f"(only for {DEFAULT_ROBOT})")
        return reproduce_robot(args, samples, friction)
    out = str(output_folder(args.out or f"out/{args.figure}"))  # before any work
    seed = parse_seed(args.seed)
    if args.figure == "table1":
        args.object = args.object or TABLE1_OBJECT
        grasps = table1_grasps(args.grasps or TABLE1_GRASPS, args.object)
    elif args.figure in ("fig9", "fig10"):
        objects, sets, count = figure_grasps(args.object, args.grasps)
    with executor_from(args) as executor:
        if args.figure == "fig7":
            rows = experiments.fig7(out, samples=samples, seed=seed, engine=engine,
                                    executor=executor, progress=True, friction=friction)
            print(f"robust and fragile arm configurations {provenance(samples, seed)}")
            print_pairs(rows)
            figures = [f"fig7_{name}.png" for name in dict.fromkeys(r["object"] for r in rows)]
            print(written(out, ["fig7.csv", *figures]))
        elif args.figure in ("fig9", "fig10"):
            with reported(ValueError):  # variants that do not share a palm pose
                rows = experiments.fig9_10(args.figure, out, samples=samples, seed=seed,
                                           count=count, engine=engine, executor=executor,
                                           progress=True, objects=objects, grasp_sets=sets,
                                           method=method, friction=friction)
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
            print(written(out, [f"{args.figure}.csv", f"{args.figure}.png"]))
        else:
            rows = table1(args.object, samples, out, grasps=grasps, seed=seed, progress=True,
                          engine=engine, executor=executor, friction=friction)
            print(markdown_table1(rows, args.object, samples))
            print(written(out, ["table1.csv", "table1.md", "pfc_vs_sigma.png"]))
    return 0


def robot_grasp_sets(args, robot: str, only: str | None = None
                     ) -> tuple[dict[str, list], int]:
    """``reproduce EXPERIMENT --robot NAME``'s (grasp sets by object, grasps or variants per
    object): the robot's shipped sets (of ``only``, else ``--object``, else of every object
    it has one for) and a count, or a grasp file of the robot."""
    from kinegrasp_env.cli.figure_grasps import grasp_file
    from kinegrasp_env.world.grasps import (
        NoGraspSetError,
        check_robot,
        shipped_grasps,
        shipped_objects,
    )

    if args.grasps is None or is_count(args.grasps):
        count = positive_int(args.grasps or str(FIGURE_GRASPS), "--grasps")
        objects = (only or args.object,) if only or args.object else shipped_objects(robot)
        if not objects:
            raise CLIError(f"robot {robot!r} has no shipped grasps; give them with --grasps "
                           f"FILE (e.g. from `kinegrasp plan --robot {robot} --object cube "
                           "--out grasps.json`)")
        with reported(NoGraspSetError):
            return {name: shipped_grasps(name, robot) for name in objects}, count
    grasps = grasp_file(args.grasps)
    if args.object is not None and args.object != grasps[0].object:
        raise CLIError(f"--object {args.object}: {args.grasps} holds grasps of "
                       f"{grasps[0].object}")
    with reported(ValueError):
        for g in grasps:
            check_robot(g, robot)
    return {grasps[0].object: grasps}, FIGURE_GRASPS


def reproduce_robot(args, samples: int, friction: float = 0.5) -> int:
    """``reproduce EXPERIMENT --robot NAME`` of a description robot's grasps: Table I, Fig. 7
    and Fig. 9 (:mod:`kinegrasp_env.toolkit.robot_tables`), Fig. 10
    (:func:`kinegrasp_env.toolkit.robot_reproduce.robot_fig10`); Figs. 7 and 10 move a
    7-joint arm along its self-motion (another arm is one line)."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError

    robot = args.robot
    _refuse(args, IN_PROCESS, robot)
    _check_engine(args.engine, robot)
    with reported(RobotDescriptionError):
        description = load_robot(robot)
    if args.figure in SELF_MOTION_EXPERIMENTS and (
            description.arm_dof != 7 or description.arm_angle_links is None):
        raise CLIError(f"reproduce {args.figure} --robot {robot}: the robot has "
                       f"{description.arm_dof} arm joints"
                       f"{'' if description.arm_angle_links else ' and no elbow angle'}; "
                       f"{args.figure} moves a 7-joint arm along its self-motion")
    if args.figure == "table1":
        return robot_table1_command(args, description, samples, friction)
    sets, count = robot_grasp_sets(args, robot)
    out = str(output_folder(args.out or f"out/{args.figure}"))
    seed = parse_seed(args.seed)
    if args.figure in ("fig7", "fig9"):
        return robot_figure_command(args, description, sets, count, out, samples, seed,
                                    friction)
    from kinegrasp_env.toolkit.robot_reproduce import robot_fig10

    with reported(ValueError):
        rows = robot_fig10(description, out, grasp_sets=sets, samples=samples, count=count,
                           seed=seed, engine=args.engine, friction=friction)
    for r in rows:
        print(f"{r['object']:<12} id {r['id']:<5} elbow {r['elbow_angle']:+.3f} rad P(FC) "
              f"{r['p_fc']:.3f} Q mean {r['q_mean']:.5f} nominal {r['q_nominal']:.5f}")
    pairs = [r for r in rows if r["config"]]
    if pairs:
        print(f"robust and fragile variants chosen on {samples} draws per variant (seed "
              f"{seed}), reported on {samples} fresh draws (SeedSequence [{seed}, 1])")
    for r in pairs:
        print(f"{r['object']:<12} {r['config']:<8} id {r['id']:<5} P(FC) "
              f"{r['fresh_p_fc']:.3f} (95% CI {r['fresh_p_fc_lo']:.3f} .. "
              f"{r['fresh_p_fc_hi']:.3f}), chosen at {r['selection_p_fc']:.3f}")
        if r["config"] == "fragile":
            print(f"{r['object']:<12} robust - fragile {r['gap']:+.3f} (95% CI "
                  f"{r['gap_lo']:+.3f} .. {r['gap_hi']:+.3f}), paired")
    print(written(out, ["fig10.csv", "fig10.png"]))
    return 0


def robot_figure_command(args, description, sets: dict, count: int, out: str, samples: int,
                         seed: int, friction: float) -> int:
    """``reproduce fig7|fig9 --robot NAME`` (:mod:`kinegrasp_env.toolkit.robot_tables`)."""
    from kinegrasp_env.toolkit.robot_tables import robot_fig7, robot_fig9

    with reported(ValueError):
        if args.figure == "fig9":
            rows = robot_fig9(description, out, grasp_sets=sets, samples=samples, count=count,
                              seed=seed, engine=args.engine, friction=friction)
        else:
            rows = robot_fig7(description, out, grasp_sets=sets, samples=samples, seed=seed,
                              engine=args.engine, friction=friction)
    if args.figure == "fig7":
        print(f"robust and fragile configurations chosen on {samples} draws each (seed "
              f"{seed}), reported on {samples} fresh draws (SeedSequence [{seed}, 1])")
    for r in rows:
        if args.figure == "fig9":
            print(f"{r['object']:<12} id {r['id']:<5} P(FC) {r['p_fc']:.3f} Q mean "
                  f"{r['q_mean']:.5f} nominal {r['q_nominal']:.5f}")
            continue
        print(f"{r['object']:<12} {r['config']:<8} id {r['id']:<5} elbow "
              f"{r['elbow_angle']:+.3f} rad P(FC) {r['fresh_p_fc']:.3f} (95% CI "
              f"{r['fresh_p_fc_lo']:.3f} .. {r['fresh_p_fc_hi']:.3f}), chosen at "
              f"{r['selection_p_fc']:.3f}")
        if r["config"] == "fragile":
            print(f"{r['object']:<12} robust - fragile {r['gap']:+.3f} (95% CI "
                  f"{r['gap_lo']:+.3f} .. {r['gap_hi']:+.3f}), paired")
    pngs = ([f"fig7_{name}.png" for name in dict.fromkeys(r["object"] for r in rows)]
            if args.figure == "fig7" else ["fig9.png"])
    print(written(out, [f"{args.figure}.csv", *pngs]))
    return 0


def robot_table1_command(args, description, samples: int, friction: float) -> int:
    """``reproduce table1 --robot NAME``: Table I of the robot's first ``--grasps`` (default
    5) grasps of ``--object`` (default: the first object it has shipped grasps of), or of a
    grasp file's."""
    from kinegrasp_env.toolkit.robot_tables import robot_table1

    robot = description.name
    if args.grasps is not None and not is_count(args.grasps):
        from kinegrasp_env.cli.figure_grasps import grasp_file
        from kinegrasp_env.world.grasps import check_robot

        grasps = grasp_file(args.grasps)
        with reported(ValueError):
            for g in grasps:
                check_robot(g, robot)
        name = grasps[0].object
    else:
        from kinegrasp_env.world.grasps import shipped_objects

        args.grasps = args.grasps or TABLE1_GRASPS
        objects = (args.object,) if args.object else shipped_objects(robot)
        if not objects:
            raise CLIError(f"robot {robot!r} has no shipped grasps; give them with --grasps "
                           f"FILE (e.g. from `kinegrasp plan --robot {robot} --object cube "
                           "--out grasps.json`)")
        sets, _ = robot_grasp_sets(args, robot, objects[0])
        name, grasps = objects[0], sets[objects[0]][:positive_int(args.grasps, "--grasps")]
    out = str(output_folder(args.out or "out/table1"))
    rows = robot_table1(description, name, grasps, samples, out, seed=parse_seed(args.seed),
                        engine=args.engine, friction=friction)
    from kinegrasp_env.toolkit.experiments import markdown_table1

    print(markdown_table1(rows, f"{name} (robot {robot})", samples))
    print(written(out, ["table1.csv", "table1.md", "pfc_vs_sigma.png"]))
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


def table1_grasps(text: str, object_name: str) -> int:
    """``--grasps``: how many of the object's shipped grasps Table I uses (1..set size)."""
    from kinegrasp_env.world.grasps import NoGraspSetError, shipped_grasps

    if not is_count(text):
        raise CLIError(f"--grasps: table1 takes a count of the object's shipped grasps, got "
                       f"{text!r} (a grasp file is for fig9 and fig10)")
    count = positive_int(text, "--grasps")
    with reported(NoGraspSetError):  # an imported object: suggests `kinegrasp plan`
        available = len(shipped_grasps(object_name))
    if count > available:
        raise CLIError(f"--grasps must be between 1 and {available} ({object_name} has "
                       f"{available} shipped grasps), got {count}")
    return count


def written(out: str, names: list[str]) -> str:
    """``written: <out>/a, b`` for the files that exist (a figure that failed is left out;
    its warning was printed)."""
    present = [name for name in names if (Path(out) / name).exists()]
    return f"written: {out}/" + ", ".join(present)


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
                   help="also run the quick holding test in pybullet on the same draws and "
                   "print P(hold) (robots other than the default; it runs pybullet dynamics "
                   "per draw, far slower than the kinematic draws: benchmarks/quick_hold.py)")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("reproduce", help="run the protocol of a table or figure of the "
                       "paper on this project's stand-in models (hand, objects, grasps); "
                       "with --robot NAME: fig10 of another 7-joint arm")
    p.add_argument("figure", choices=("table1", "fig7", "fig9", "fig10"),
                   help="the table or figure")
    add_object_arg(p, None, f"catalog object: table1's (default {TABLE1_OBJECT}); fig9, "
                   "fig10: only this one (default: the four built-in objects)")
    p.add_argument("--samples", default="10000", help="Monte Carlo draws per cell")
    p.add_argument("--grasps", help=f"a count: the first N shipped grasps (table1, default "
                   f"{TABLE1_GRASPS}; fig9, default {FIGURE_GRASPS}) or N null-space variants "
                   f"of grasp 0 (fig10, default {FIGURE_GRASPS}); or for fig9, fig10 a grasp "
                   "file (`kinegrasp plan`'s output; needed for an imported object): its "
                   f"first {FIGURE_GRASPS} grasps, or variants of its first")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_execution_args(p, 2)
    # fast by default: the same draws as the reference, and the same outcome for all but a few
    # in 10,000 of them (benchmarks/agreement.py); --engine pybullet runs the reference
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
                   "(engine pybullet, fast or physics, in this process; no paper values "
                   "beside them); fig7 and fig10 move a 7-joint arm with an elbow angle along "
                   "its self-motion")
    p.set_defaults(func=cmd_reproduce)
