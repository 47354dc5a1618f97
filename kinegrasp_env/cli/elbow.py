"""``kinegrasp elbow``: the most robust elbow of a grasp of any robot, with its certificate
(and, with ``--report FILE``, its HTML page: :func:`kinegrasp_env.cli.report.
write_elbow_report`).

The variants are the self-motion of a 7-joint arm (:func:`~kinegrasp_env.toolkit.
elbow_search.optimize_robot_elbow`, or re-weighted :func:`~kinegrasp_env.toolkit.
elbow_reweight_search.optimize_robot_elbow_reweighted`) or the IK branches of a 6-joint one
(:mod:`kinegrasp_env.cli.elbow_branches`, with their own plot and page). The certificate
(:mod:`kinegrasp_env.toolkit.elbow_certificate`) is printed as the claim it makes: "with 95%
confidence no evaluated elbow angle beats psi = ... by more than B in P(FC)", then whether B is
within ``--epsilon`` (certified) or not; the printed summary and the plot:
:mod:`kinegrasp_env.cli.elbow_output`."""

from __future__ import annotations

from kinegrasp_env.cli.common import (
    CLIError,
    add_friction_arg,
    add_noise_args,
    add_object_arg,
    certificate_levels,
    friction_from,
    grasp_index_help,
    noise_from,
    positive_int,
    reported,
    shipped_grasp,
)
from kinegrasp_env.cli.elbow_output import (
    DEFAULT_DELTA,
    DEFAULT_EPSILON,
    DEFAULT_IK_STARTS,
    reweighted_elbow,
    show_elbow,
)
from kinegrasp_env.cli.execution_options import add_execution_args, executor_from
from kinegrasp_env.cli.grasp_choice import grasp_shown
from kinegrasp_env.cli.output_paths import input_files, output_file, report_path
from kinegrasp_env.robot.default import DEFAULT_ROBOT

#: The object without --object or --grasps.
DEFAULT_OBJECT = "spray_flask"


def file_choice(args):
    """``(index, grasp)`` of ``--grasps FILE`` (its robot taken for ``--robot`` when not
    given; a grasp of another robot than ``--robot`` is one line), or None without it (then
    ``--object`` defaults to :data:`DEFAULT_OBJECT`)."""
    if getattr(args, "grasps", None) is None:
        args.object = getattr(args, "object", None) or DEFAULT_OBJECT
        return None
    from kinegrasp_env.cli.grasp_choice import grasp_of_file
    from kinegrasp_env.world.grasps import check_robot

    index, grasp = grasp_of_file(args)
    args.robot = getattr(args, "robot", None) or grasp.robot
    with reported(ValueError):
        check_robot(grasp, args.robot, "--robot")
    return index, grasp


def cmd_elbow(args) -> int:
    """``kinegrasp elbow``: a grasp (of ``--grasps FILE``, else grasp ``--grasp`` of the
    robot's shipped set of ``--object``) along its robot's self-motion, or for a 6-joint arm
    across its IK branches (:func:`~kinegrasp_env.cli.elbow_branches.cmd_elbow_branches`)."""
    from kinegrasp_env.cli.report import write_elbow_report
    from kinegrasp_env.progress_bar import progress_bar
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError

    report_path(args.report, inputs=input_files(args))  # before a palm pose is solved
    if args.plot is not None:
        output_file(args.plot, "--plot", inputs=input_files(args))
    chosen = file_choice(args)
    robot = args.robot = getattr(args, "robot", None) or DEFAULT_ROBOT
    noise, sigma, samples, seed = noise_from(args)
    friction = friction_from(args, noise)
    epsilon, delta = certificate_levels(args)
    with reported(RobotDescriptionError):
        description = load_robot(robot)
    branches = description.arm_dof == 6
    if not branches and not description.has_self_motion:
        raise CLIError(f"robot {robot!r} has {description.arm_dof} arm joints; the elbow's "
                       "variants are the self-motion of 7 with arm_angle_links or the IK "
                       "branches of 6")
    starts = ik_starts(args, branches, robot)
    if args.method == "direct" and args.batch is not None:
        raise CLIError("--batch is the closings of --method reweight's batch; --method direct "
                       "takes none")
    index, grasp = chosen or shipped_grasp(args.object, args.grasp, robot)
    if branches:
        from kinegrasp_env.cli.elbow_branches import cmd_elbow_branches

        return cmd_elbow_branches(args, index, grasp, noise, samples, seed, epsilon, delta,
                                  starts, friction)
    from kinegrasp_env.toolkit.elbow_search import optimize_robot_elbow

    evidence, shown = None, grasp_shown(args, index, grasp)
    if args.method == "reweight":
        result, evidence = reweighted_elbow(args, grasp, index, noise, samples, seed, epsilon,
                                            delta, friction)
    else:
        bar = progress_bar(desc=f"elbow angles of {args.object} grasp {shown} of {robot} "
                           "(selection, then fresh draws)", unit="angle")
        with executor_from(args) as executor:
            result = optimize_robot_elbow(grasp, noise, samples, seed, epsilon=epsilon,
                                          delta=delta,
                                          progress=lambda done: bar.update(done - bar.n),
                                          friction=friction, evaluate_with=args.engine,
                                          executor=executor)
        bar.close()
    show_elbow(args, {"robot": robot, **result.to_json()}, result, evidence, shown, samples,
               f"{robot}: {args.object} grasp {shown}, sigma = {sigma:g} rad")
    if args.report:
        write_elbow_report(args, description, grasp, index, result, noise, evidence, friction)
    return 0


def ik_starts(args, branches: bool, robot: str) -> int | None:
    """``--ik-starts``: a positive count for a 6-joint arm (default: ``ik_branches``'), None
    otherwise (where giving it is one line)."""
    if getattr(args, "ik_starts", None) is None:
        return DEFAULT_IK_STARTS if branches else None
    if not branches:
        raise CLIError(f"--ik-starts is for a 6-joint arm's IK branches; the variants of robot "
                       f"{robot!r} are its self-motion")
    return positive_int(args.ik_starts, "--ik-starts")


def add_commands(sub) -> None:
    """Register ``elbow``."""
    p = sub.add_parser("elbow", help="P(FC) along a grasp's self-motion: the most robust elbow "
                       "angle, its gain over the nominal one, with intervals")
    add_object_arg(p, DEFAULT_OBJECT, f"catalog object (default {DEFAULT_OBJECT}; with --grasps: "
                   "the file's)")
    p.set_defaults(object=None)  # resolved in cmd_elbow: --grasps names its own
    p.add_argument("--grasp", default="0", help=grasp_index_help())
    add_noise_args(p, 0.0133)
    p.set_defaults(samples="1000")
    add_execution_args(p, 1)
    p.add_argument("--engine", default="fast", choices=("fast", "pybullet"),
                   help="fast (batched) or pybullet (the reference); the self-motion is "
                   "checked for clearance by pybullet either way")
    add_friction_arg(p)
    p.add_argument("--epsilon", default=str(DEFAULT_EPSILON),
                   help="margin in P(FC) of the certificate: certified when, with confidence "
                   "1 - delta, no evaluated angle beats the chosen one by more than it")
    p.add_argument("--delta", default=str(DEFAULT_DELTA),
                   help="error level of the certificate (0.05: 95%% confidence)")
    p.add_argument("--method", default="direct", choices=("direct", "reweight"),
                   help="direct: fresh closings at every angle; reweight: one batch of "
                   "closings over the palm's deviation re-weighted to every angle (Gaussian "
                   "joint noise; the best angle still scored on fresh direct draws)")
    p.add_argument("--batch", help="closings per batch with --method reweight (default twice "
                   "--samples)")
    p.add_argument("--plot", help="write a PNG of P(FC) against the elbow angle (a 6-joint "
                   "arm: per IK branch)")
    p.add_argument("--report", help="write a self-contained interactive HTML page: P(FC) "
                   "along the self-motion (or per IK branch), the robot at the nominal and at "
                   "the best elbow in 3-D")
    p.add_argument("--robot", help=f"catalog robot (default {DEFAULT_ROBOT}, or --grasps' "
                   "robot): its shipped grasps, its arm's self-motion (7 joints) or IK "
                   "branches (6 joints)")
    p.add_argument("--grasps", help="a grasp file (e.g. `kinegrasp plan`'s output) or a "
                   "palm-pose file: its grasp --grasp (an id, else an index) instead of a "
                   "shipped one")
    p.add_argument("--ik-starts", help="random IK starts that find a 6-joint arm's IK "
                   f"branches (default {DEFAULT_IK_STARTS})")
    p.set_defaults(func=cmd_elbow)
