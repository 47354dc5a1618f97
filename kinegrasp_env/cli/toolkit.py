"""Toolkit commands: ``plan`` (grasp planning), ``rank`` (candidates by robustness, resumable:
:mod:`kinegrasp_env.cli.ranking`) and ``sweep`` (a grid of evaluations on a process pool or
Ray).
"""

from __future__ import annotations

import sys

from kinegrasp_env.cli.common import (
    CLIError,
    add_engine_arg,
    add_friction_arg,
    add_hold_simulator_arg,
    add_noise_args,
    add_noise_spec_arg,
    add_object_arg,
    add_static_hold_arg,
    friction_from,
    parse_seed,
    plural,
    positive_float,
    positive_int,
    reported,
)
from kinegrasp_env.cli.execution_options import add_execution_args, executor_from
from kinegrasp_env.cli.output_paths import output_file, output_folder
from kinegrasp_env.cli.ranking import ADAPTIVE_DEFAULTS, cmd_rank
from kinegrasp_env.robot.default import DEFAULT_ROBOT

#: ``--criterion`` choices: equal to ``toolkit.ranking.CRITERIA`` (tested), copied so that
#: building the parser imports no NumPy or SciPy.
CRITERIA = ("pfc", "q_mean", "pfc_lcb", "weighted", "hold_static", "hold", "hold_margin")


def cmd_plan(args) -> int:
    """``kinegrasp plan``: grasps of any catalog robot, each in force closure at its nominal
    closing (antipodal pairs for parallel jaws, sampled approaches and pre-shapes for any
    other hand), written with their robot."""
    from dataclasses import replace

    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.toolkit.grasp_planner import plan_grasps
    from kinegrasp_env.toolkit.plan_checks import PlannerSettings, PlanTally, attempts_for
    from kinegrasp_env.world.grasps import save_grasps

    robot = args.robot or DEFAULT_ROBOT
    count = positive_int(args.count, "--count")
    variants = positive_int(args.variants, "--variants", low=0)
    budget = positive_float(args.time_budget, "--time-budget") if args.time_budget else None
    attempts = (positive_int(args.max_attempts, "--max-attempts") if args.max_attempts
                else attempts_for(count))
    settings = replace(PlannerSettings(), attempts=attempts)
    seed = parse_seed(args.seed)
    friction = friction_from(args)
    output_file(args.out, "--out")
    with reported(RobotDescriptionError):
        description = load_robot(robot)
    branches = description.arm_dof == 6  # its variants: the IK branches of the palm pose
    if variants and not (description.has_self_motion or branches):
        raise CLIError(f"--variants: robot {robot!r} has {description.arm_dof} arm "
                       "joints; variants move a 7-joint arm with arm_angle_links along its "
                       "self-motion, or take a 6-joint arm's IK branches")
    from kinegrasp_env.robot.description import never_in_force_closure

    reason = never_in_force_closure(description)
    if reason is not None:  # before any palm pose is drawn: none could be a grasp
        raise CLIError(f"robot {robot!r}: {reason}; nothing planned")
    tally = PlanTally()
    with reported(ValueError):
        grasps = plan_grasps(description, args.object, count=count, seed=seed,
                             friction=friction, settings=settings, time_budget=budget,
                             tally=tally)
    if not grasps:
        limit = f"; a {budget:g} s budget" if budget else ""
        raise CLIError(f"no force-closure grasp of {args.object} found for robot {robot} "
                       f"({tally.summary()}{limit}){_reach_note(tally, args.object)}; "
                       "nothing written")
    out = list(grasps)
    if variants:
        from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
        from kinegrasp_env.toolkit.arm_variants import variants_of

        with RobotReferenceEngine(description, args.object, friction=friction) as engine:
            for grasp in grasps:
                out += variants_of(grasp, engine, variants)
    save_grasps(out, args.out, planner_seed=seed)
    kind = "IK-branch" if branches else "null-space"
    extra = f" ({len(out) - len(grasps)} {kind} variants)" if variants else ""
    print(f"{plural(len(grasps), 'grasp')}{extra} of {args.object} for robot {robot} "
          f"written to {args.out}")
    return 0


#: Fewest palm poses around an object, every one out of the arm's reach, that make the plan
#: say the object may stand out of reach (a few poses can all miss an object in reach).
REACH_NOTE_POSES = 20


def _reach_note(tally, object_name: str) -> str:
    """Where every palm pose a plan asked the arm's IK for, :data:`REACH_NOTE_POSES` at
    least, was out of its reach: how far the object stands from the robot's base (the
    world origin), else nothing."""
    reached_for = tally.drawn - tally.dropped["facing up"]  # the poses the IK was asked for
    if not (reached_for >= REACH_NOTE_POSES
            and tally.dropped["out of reach"] == reached_for):
        return ""
    import numpy as np

    from kinegrasp_env.world.objects import load_object

    obj = load_object(object_name)
    centre = obj.to_world(obj.center_of_mass[None])[0]
    return (f": {object_name} stands {np.linalg.norm(centre):.2f} m from the robot's base; "
            "place it within reach (`kinegrasp objects place`)")


def cmd_sweep(args) -> int:
    from kinegrasp_env.montecarlo.sweep import (
        SpecError,
        SweepSpec,
        figure_names,
        run_sweep,
        summary_table,
    )
    from kinegrasp_env.toolkit.plots import plot_sweep

    with reported(SpecError):
        spec = SweepSpec.from_file(args.spec, robot=args.robot)
    if args.friction is not None:  # every cell's mu: refused beside a model's friction source
        import dataclasses

        drawn = spec.friction_sources()
        friction = friction_from(args, drawn[0][1] if drawn else None)
        with reported(SpecError):
            spec = dataclasses.replace(spec, friction=friction)
    out = output_folder(args.out)
    robot = "" if spec.robot == DEFAULT_ROBOT else f" of robot {spec.robot}"
    from kinegrasp_env.montecarlo.sweep_noise import replaced_joint_sigmas

    for label, sigma in replaced_joint_sigmas(spec.models):
        print(f"sweep: noise model {label}: its joints.sigma {sigma} is replaced by each "
              f"cell's sigma (sigmas: {', '.join(f'{s:g}' for s in spec.sigmas)})",
              file=sys.stderr)
    with executor_from(args) as executor:
        print(f"sweep: {len(spec.cells())} cells x {spec.samples} draws{robot} on "
              f"{executor.description}", file=sys.stderr)
        with reported(SpecError):  # the store in --out was made with other settings or draws
            rows, ran, skipped = run_sweep(spec, out, executor, plot=plot_sweep)
    print(summary_table(rows), end="")
    figures = ", ".join(name for _, _, name in figure_names(spec))
    print(f"{ran} tasks run, {skipped} found finished in {out / 'results.sqlite'}; "
          f"written in {out}: summary.csv, summary.txt, {figures}")
    return 0


def add_commands(sub) -> None:
    """Register ``plan``, ``rank`` and ``sweep``."""
    p = sub.add_parser("plan", help="plan force-closure grasps of an object")
    add_object_arg(p, "drill", "catalog object")
    p.add_argument("--count", default="20", help="force-closure grasps to find")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    p.add_argument("--out", default="grasps.json", help="grasp file to write")
    p.add_argument("--variants", default="0",
                   help="null-space variants per grasp (same palm pose, other elbow angles)")
    p.add_argument("--time-budget", help="seconds at most (default: no limit)")
    # the default is toolkit.plan_checks.attempts_for (tested against this help;
    # copied: no NumPy to build this)
    p.add_argument("--max-attempts", help="palm poses to try at most (default: 50 per grasp "
                   "asked, at least 200)")
    p.add_argument("--robot", help=f"catalog robot (default {DEFAULT_ROBOT}): antipodal grasps "
                   "of parallel jaws, sampled approaches and pre-shapes of any other hand, "
                   "recorded in the file")
    add_friction_arg(p)
    p.set_defaults(func=cmd_plan)

    p = sub.add_parser("rank", help="rank candidate grasps by robustness under joint noise")
    p.add_argument("candidates", help="grasp file (from `kinegrasp plan`), or a palm-pose "
                   "file (docs/palm_pose_candidates.json; rejected ones: <out>.rejected.csv)")
    add_noise_args(p, 0.0133)
    add_noise_spec_arg(p)
    p.set_defaults(samples="2000")
    p.add_argument("--criterion", default="pfc", choices=CRITERIA,
                   help="order of the ranking: P(FC), mean Q, the lower end of P(FC)'s 95%% "
                   "interval, P(FC) x (1 + mean Q), P(hold, static): the fraction of draws "
                   "whose contacts can carry the object's weight in six directions with the "
                   "hand's effort limits, P(hold): the fraction the quick holding test "
                   "holds (in --hold-simulator; the "
                   "holding test runs dynamics per draw, far slower than the kinematic "
                   "criteria: benchmarks/quick_hold.py), or the mean margin of that test "
                   "(hold_margin: how far each draw got through it, in [0, 1]); the means "
                   "(q_mean, weighted, hold_margin) rank at fixed n only")
    add_hold_simulator_arg(p)
    add_static_hold_arg(p, "adds the column P(hold, static)")
    p.add_argument("--adaptive", action="store_true",
                   help="stop drawing once a top k is certified: exact tests on the paired "
                   "draws of every two candidates (common noise); the table lists the "
                   "certified top k first (column 'certified': top-k, rest, unresolved), "
                   "each label wrong with probability <= --delta; not certified within the "
                   "--samples budget, the run says so")
    p.add_argument("--top-k", help="size of the top set --adaptive separates (default "
                   f"{ADAPTIVE_DEFAULTS['top_k']}, or one less than the candidates where they "
                   "are fewer)")
    # the default is toolkit.adaptive_ranking.DEFAULT_EPSILON (tested; copied: no NumPy to
    # build this)
    p.add_argument("--epsilon", help="--adaptive's indifference zone: certify a top k each "
                   "of whose members has P(FC) within EPSILON of the true k-th best (default "
                   f"{ADAPTIVE_DEFAULTS['epsilon']}; 0: exactly the top k, which a near tie "
                   "can keep from being certified at any budget)")
    p.add_argument("--delta", help="--adaptive's probability of a wrong certified label "
                   f"(default {ADAPTIVE_DEFAULTS['delta']})")
    p.add_argument("--best-elbow", metavar="SAMPLES", help="first move each candidate to its "
                   "most robust elbow angle (`kinegrasp elbow`, SAMPLES draws per angle, chosen "
                   "on seed + 1); the ranked ids get an 'e', and the columns elbow_angle "
                   "(radians; 7-joint arms) or ik_branch (6-joint arms) name the choice")
    add_execution_args(p, 1)
    add_engine_arg(p)
    add_friction_arg(p)
    p.add_argument("--out", default="ranked.csv",
                   help="CSV to write; an interrupted run keeps its finished candidates in "
                   "<out>.partial.jsonl and the same command resumes from them")
    p.add_argument("--report", help="also write a self-contained HTML page: the sortable "
                   "table and each candidate's 3-D views")
    p.add_argument("--robot", help="catalog robot (default: the grasp or palm-pose file's, "
                   f"else {DEFAULT_ROBOT}); a grasp of another robot is refused, and a "
                   "palm-pose file naming another robot is an error")
    p.set_defaults(func=cmd_rank)

    p = sub.add_parser("sweep", help="a grid of evaluations (objects x grasps x sigmas x noise "
                       "x engines), resumable, on a process pool or Ray")
    p.add_argument("spec", help="YAML file with objects, grasps, grasp_files (object: grasp "
                   "file, needed for an imported object), sigmas, noise, engines, samples, "
                   "chunk, seed, robot, friction")
    p.add_argument("--out", required=True, help="folder of the results store and summary")
    p.add_argument("--robot", help=f"catalog robot (replaces the spec's robot, default "
                   f"the robot of its grasp_files' grasps, else {DEFAULT_ROBOT}); another "
                   "robot's grasps are its shipped sets or the spec's grasp files, with joint "
                   "noise on its arm joints")
    p.add_argument("--friction", help="Coulomb friction coefficient mu at every contact "
                   "(replaces the spec's friction, default 0.5; a number >= 0)")
    add_execution_args(p, 1)
    p.set_defaults(func=cmd_sweep)
