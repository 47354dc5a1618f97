"""``kinegrasp elbow``: the most robust elbow angle of a grasp, with its certificate (and,
with ``--report FILE``, its HTML page: :func:`kinegrasp_env.cli.report.write_elbow_report`).

The certificate (:mod:`kinegrasp_env.toolkit.elbow_certificate`) is printed as the claim it
makes: "with 95% confidence no evaluated elbow angle beats psi = ... by more than B in P(FC)",
then whether B is within ``--epsilon`` (certified) or not.

A description robot (``--robot NAME``, or ``--grasps FILE`` of one) takes the reference
engine; its variants are the self-motion of a 7-joint arm, or the IK branches of a 6-joint
one (:func:`kinegrasp_env.toolkit.robot_elbow.optimize_robot_branches`: every branch, the
best on fresh draws, the same certificate over the other branches)."""

from __future__ import annotations

import json
import sys

from kinegrasp_env.cli.common import (
    CLIError,
    add_execution_args,
    add_friction_arg,
    add_noise_args,
    add_object_arg,
    executor_from,
    finite_float,
    friction_from,
    grasp_index_help,
    noise_from,
    output_file,
    plural,
    positive_int,
    reported,
    shipped_grasp,
)
from kinegrasp_env.robot.default import DEFAULT_ROBOT

#: ``--epsilon`` and ``--delta`` defaults: equal to ``toolkit.elbow_certificate``'s
#: ``DEFAULT_EPSILON`` and ``DEFAULT_DELTA`` (tested), copied so that building the parser
#: imports no NumPy.
DEFAULT_EPSILON, DEFAULT_DELTA = 0.05, 0.05
#: The object without --object or --grasps.
DEFAULT_OBJECT = "spray_flask"
#: ``--ik-starts`` default (equal to ``toolkit.ik_branches.DEFAULT_STARTS``; copied, as above).
DEFAULT_IK_STARTS = 200
#: Options a description robot's elbow does not take: flag -> its value when not given.
ROBOT_REFUSED = {"--report": None}


def certificate_levels(args) -> tuple[float, float]:
    """``--epsilon`` in [0, 1) and ``--delta`` in (0, 1), or a one-line CLIError."""
    epsilon = finite_float(args.epsilon, "--epsilon")
    delta = finite_float(args.delta, "--delta")
    if not 0 <= epsilon < 1:
        raise CLIError(f"--epsilon must be a P(FC) margin in [0, 1), got {args.epsilon}")
    if not 0 < delta < 1:
        raise CLIError(f"--delta must be an error level in (0, 1), got {args.delta}")
    return epsilon, delta


def file_choice(args):
    """``(index, grasp)`` of ``--grasps FILE`` (its robot taken for ``--robot`` when not
    given; a grasp of another robot than ``--robot`` is one line), or None without it (then
    ``--object`` defaults to :data:`DEFAULT_OBJECT`)."""
    if getattr(args, "grasps", None) is None:
        args.object = getattr(args, "object", None) or DEFAULT_OBJECT
        return None
    from kinegrasp_env.cli.grasp_choice import file_grasp
    from kinegrasp_env.world.grasps import check_robot

    index, grasp = file_grasp(args)
    args.robot = getattr(args, "robot", None) or grasp.robot
    with reported(ValueError):
        check_robot(grasp, args.robot)
    return index, grasp


def cmd_elbow(args) -> int:
    chosen = file_choice(args)
    if getattr(args, "robot", None) not in (None, DEFAULT_ROBOT):
        return cmd_elbow_robot(args, chosen)
    if getattr(args, "ik_starts", None) is not None:
        raise CLIError(f"--ik-starts is for a 6-joint arm's IK branches; {DEFAULT_ROBOT}'s arm "
                       "has 7 joints (its variants: the self-motion)")
    args.engine = getattr(args, "engine", None) or "fast"
    from tqdm import tqdm

    from kinegrasp_env.cli.report import report_path, write_elbow_report
    from kinegrasp_env.toolkit.elbow import optimize_elbow

    noise, sigma, samples, seed = noise_from(args)
    friction = friction_from(args, noise)
    epsilon, delta = certificate_levels(args)
    index, grasp = chosen or shipped_grasp(args.object, args.grasp)
    if args.plot:
        output_file(args.plot, "--plot")
    report_path(args.report)
    if args.method == "direct" and args.batch is not None:
        raise CLIError("--batch is the closings of --method reweight's batch; --method direct "
                       "takes none")
    if args.method == "reweight":
        result, evidence = reweighted_elbow(args, grasp, index, noise, samples, seed, epsilon,
                                            delta, friction)
    else:
        evidence = None
        bar = tqdm(desc=f"elbow angles of {args.object} grasp {index} (selection, then fresh "
                   "draws)", unit="angle", file=sys.stderr, disable=None)
        with executor_from(args) as executor:
            result = optimize_elbow(grasp, noise, samples, seed, engine=args.engine,
                                    epsilon=epsilon, delta=delta, executor=executor,
                                    friction=friction,
                                    progress=lambda done: bar.update(done - bar.n))
        bar.close()
    payload = result.to_json()
    if evidence is not None:
        payload["reweight"] = evidence.to_json()
    if args.plot:
        elbow_plot(payload, result, evidence, args.plot,
                   f"{args.object} grasp {index}, sigma = {sigma:g} rad: P(FC) along the "
                   "self-motion")
    if args.json:
        print(json.dumps(payload))
    else:
        print(text_summary(payload, index))
        if evidence is not None:
            print(reweight_lines(payload["reweight"], samples))
        if args.plot:
            print(f"  plot written to {args.plot}")
    if args.report:
        write_elbow_report(args, grasp, index, result, noise, evidence, friction)
    return 0


def reweighted_elbow(args, grasp, index, noise, samples, seed, epsilon, delta,
                     friction: float = 0.5):
    """``elbow --method reweight``: (ElbowResult, ReweightEvidence) from one batch of
    closings (:func:`kinegrasp_env.toolkit.elbow_reweight.optimize_elbow_reweighted`; a
    robot given with ``--robot``: :func:`kinegrasp_env.toolkit.robot_elbow_reweight.
    optimize_robot_elbow_reweighted`)."""
    from tqdm import tqdm

    batch = None if args.batch is None else positive_int(args.batch, "--batch")
    robot = getattr(args, "robot", None) not in (None, DEFAULT_ROBOT)
    if robot:
        from kinegrasp_env.toolkit.robot_elbow_reweight import (
            check_robot_reweight as check,
        )
        from kinegrasp_env.toolkit.robot_elbow_reweight import (
            optimize_robot_elbow_reweighted as optimize,
        )
    else:
        from kinegrasp_env.toolkit.elbow_reweight import check_reweight as check
        from kinegrasp_env.toolkit.elbow_reweight import optimize_elbow_reweighted as optimize
    with reported(ValueError):  # noise, robot, object, batch: refused before any closing
        check(grasp, noise, samples, epsilon, delta, batch)
    who = f" of {args.robot}" if robot else ""
    bar = tqdm(desc=f"elbow of {args.object} grasp {index}{who} (batch, fresh draws, "
               "certificate)", total=3, unit="stage", file=sys.stderr, disable=None)
    with executor_from(args) as executor:
        out = optimize(grasp, noise, samples, seed, engine=args.engine, epsilon=epsilon,
                       delta=delta, batch=batch, executor=executor, friction=friction,
                       progress=lambda stage: bar.update(1))
    bar.close()
    return out


def reweight_lines(evidence: dict, samples: int) -> str:
    """What the batch method adds to the summary (``ReweightEvidence.to_json()``)."""
    points = evidence["points"]
    ess = [p["ess"] for p in points]
    fallback = evidence["fallback_angles"]
    lines = [f"  one batch of {evidence['batch']} closings re-weighted to every angle "
             f"(effective sample size {min(ess):.0f} .. {max(ess):.0f}; "
             + (f"{plural(len(fallback), 'angle')} below {samples} evaluated directly: "
                + ", ".join(f"{p:+.3f}" for p in fallback) if fallback
                else "no angle needed direct draws") + ")",
             f"  re-weighted P(FC) at the best elbow {evidence['chosen_reweighted_p_fc']:.3f}: "
             + ("agrees with the fresh draws" if evidence["chosen_agrees_with_fresh_draws"]
                else "DISAGREES with the fresh draws beyond both sampling errors (the "
                     "linearisation may not hold here: rerun with --method direct)")]
    return "\n".join(lines)


def cmd_elbow_robot(args, chosen=None) -> int:
    """``kinegrasp elbow --robot NAME``: a description robot's grasp along its self-motion
    (:func:`kinegrasp_env.toolkit.robot_elbow.optimize_robot_elbow`, any of its engines),
    or for a 6-joint arm across its IK branches (:func:`cmd_elbow_branches`). ``chosen``:
    ``(index, grasp)`` of ``--grasps FILE``, else grasp ``--grasp`` of the robot's shipped set
    of ``--object``."""
    from tqdm import tqdm

    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError

    robot = args.robot
    for flag, unset in ROBOT_REFUSED.items():
        if getattr(args, flag.lstrip("-").replace("-", "_"), unset) != unset:
            raise CLIError(f"{flag} is not available for robot {robot!r} (only for "
                           f"{DEFAULT_ROBOT})")
    args.engine = args.engine or "pybullet"
    noise, sigma, samples, seed = noise_from(args)
    friction = friction_from(args, noise)
    epsilon, delta = certificate_levels(args)
    with reported(RobotDescriptionError):
        description = load_robot(robot)
    branches = description.arm_dof == 6
    if not branches and (description.arm_dof != 7 or description.arm_angle_links is None):
        raise CLIError(f"robot {robot!r} has {description.arm_dof} arm joints; the elbow's "
                       "variants are the self-motion of 7 with arm_angle_links or the IK "
                       "branches of 6")
    starts = ik_starts(args, branches, robot)
    if branches and args.plot:
        raise CLIError(f"--plot draws P(FC) against the elbow angle; robot {robot!r}'s "
                       "6-joint arm has IK branches instead (no self-motion)")
    if args.method == "direct" and args.batch is not None:
        raise CLIError("--batch is the closings of --method reweight's batch; --method direct "
                       "takes none")
    if branches and args.method == "reweight":
        raise CLIError(f"--method reweight moves a 7-joint arm along its self-motion; robot "
                       f"{robot!r}'s 6-joint arm has IK branches: use --method direct")
    index, grasp = chosen or shipped_grasp(args.object, args.grasp, robot)
    if args.plot:
        output_file(args.plot, "--plot")
    if branches:
        return cmd_elbow_branches(args, index, grasp, noise, samples, seed, epsilon, delta,
                                  starts, friction)
    from kinegrasp_env.toolkit.robot_elbow import optimize_robot_elbow

    evidence = None
    if args.method == "reweight":
        result, evidence = reweighted_elbow(args, grasp, index, noise, samples, seed, epsilon,
                                            delta, friction)
    else:
        bar = tqdm(desc=f"elbow angles of {args.object} grasp {index} of {robot} "
                   "(selection, then fresh draws)", unit="angle", file=sys.stderr,
                   disable=None)
        with executor_from(args) as executor:
            result = optimize_robot_elbow(grasp, noise, samples, seed, epsilon=epsilon,
                                          delta=delta,
                                          progress=lambda done: bar.update(done - bar.n),
                                          friction=friction, evaluate_with=args.engine,
                                          executor=executor)
        bar.close()
    payload = {"robot": robot, **result.to_json()}
    if evidence is not None:
        payload["reweight"] = evidence.to_json()
    if args.plot:
        elbow_plot(payload, result, evidence, args.plot,
                   f"{robot}: {args.object} grasp {index}, sigma = {sigma:g} rad: P(FC) along "
                   "the self-motion")
    if args.json:
        print(json.dumps(payload))
    else:
        print(f"robot {robot}, " + text_summary(payload, index))
        if evidence is not None:
            print(reweight_lines(payload["reweight"], samples))
        if args.plot:
            print(f"  plot written to {args.plot}")
    return 0


def elbow_plot(payload: dict, result, evidence, path: str, title: str) -> None:
    """``--plot``: P(FC) along the self-motion, with the fragile directions and both elbows'
    ellipses where a re-weighted run's batch has failing draws."""
    picture = None if evidence is None else evidence.picture()
    if picture is not None:
        from kinegrasp_env.toolkit.plots import plot_elbow_fragility

        plot_elbow_fragility(payload["curve"], result.nominal_psi, result.best_psi, picture,
                             path, title=f"{title}, and why")
    else:
        from kinegrasp_env.toolkit.plots import plot_elbow_curve

        plot_elbow_curve(payload["curve"], result.nominal_psi, result.best_psi, path,
                         title=title)


def ik_starts(args, branches: bool, robot: str) -> int | None:
    """``--ik-starts``: a positive count for a 6-joint arm (default: ``ik_branches``'), None
    otherwise (where giving it is one line)."""
    if getattr(args, "ik_starts", None) is None:
        return DEFAULT_IK_STARTS if branches else None
    if not branches:
        raise CLIError(f"--ik-starts is for a 6-joint arm's IK branches; robot {robot!r}'s "
                       "variants are its self-motion")
    return positive_int(args.ik_starts, "--ik-starts")


def cmd_elbow_branches(args, index, grasp, noise, samples, seed, epsilon, delta,
                       starts, friction: float = 0.5) -> int:
    """A 6-joint arm's grasp across its IK branches
    (:func:`kinegrasp_env.toolkit.robot_elbow.optimize_robot_branches`)."""
    from tqdm import tqdm

    from kinegrasp_env.toolkit.robot_elbow import optimize_robot_branches

    bar = tqdm(desc=f"IK branches of {args.object} grasp {index} of {args.robot} (selection, "
               "then fresh draws)", unit="branch", file=sys.stderr, disable=None)
    with executor_from(args) as executor:
        result = optimize_robot_branches(grasp, noise, samples, seed, starts=starts,
                                         epsilon=epsilon, delta=delta, friction=friction,
                                         progress=lambda done: bar.update(done - bar.n),
                                         evaluate_with=args.engine, executor=executor)
    bar.close()
    payload = {"robot": args.robot, "ik_starts": starts, **result.to_json()}
    if args.json:
        print(json.dumps(payload))
    else:
        print(branch_summary(payload, index))
    return 0


def branch_summary(result: dict, index: int) -> str:
    """The console summary of a 6-joint arm's IK-branch search (``BranchResult.to_json()``
    with ``robot`` and ``ik_starts``)."""
    lo, hi = result["best_p_fc_ci"]
    nlo, nhi = result["nominal_p_fc_ci"]
    glo, ghi = result["gain_ci"]
    n, cert = len(result["branches"]), result["certificate"]
    lines = [
        f"robot {result['robot']}: a 6-joint arm has no self-motion; the variants of "
        f"{result['object']} grasp {index} are its {plural(n, 'IK branch', 'IK branches')} "
        f"({result['ik_starts']} IK starts)",
        f"{result['object']} grasp {index}, sigma = {result['sigma']} rad, "
        f"{plural(n, 'IK branch', 'IK branches')} x {result['samples']} draws, then again on "
        f"{result['samples']} fresh draws ({result['engine']} engine)",
        f"  nominal branch {result['nominal_branch']} ({result['nominal_label']}): P(FC) "
        f"{result['nominal_p_fc']:.3f} ({nlo:.3f} .. {nhi:.3f})",
        f"  best branch    {result['best_branch']} ({result['best_label']}): P(FC) "
        f"{result['best_p_fc']:.3f} ({lo:.3f} .. {hi:.3f})  [fresh draws]",
        f"  gain over nominal {result['gain']:+.3f} (95% CI {glo:+.3f} .. {ghi:+.3f}, paired)",
        f"  {cert['statement']}"]
    if cert["bound"] is not None:
        verdict = (f"certified at epsilon {cert['epsilon']:g}" if cert["certified"] else
                   f"not certified at epsilon {cert['epsilon']:g} (branch "
                   f"{cert['worst_branch']} is the rival it cannot rule out)")
        rivals = plural(len(cert["rivals"]), "other branch", "other branches")
        lines.append(f"    {verdict}; {rivals}, exact one-sided binomial bounds on "
                     f"{cert['fresh_draws']} fresh draws; branches the IK starts did not find "
                     "not covered")
    for point in result["curve"]:
        lines.append(f"  branch {point['branch']} ({point['label']}): P(FC) {point['p_fc']:.3f} "
                     f"selection, {point['fresh_p_fc']:.3f} fresh")
    return "\n".join(lines)


def text_summary(result: dict, index: int) -> str:
    """The console summary of an elbow optimization (``ElbowResult.to_json()``)."""
    lo, hi = result["best_p_fc_ci"]
    nlo, nhi = result["nominal_p_fc_ci"]
    glo, ghi = result["gain_ci"]
    if "reweight" in result:
        how = (f"{len(result['curve'])} elbow angles from one batch of "
               f"{result['reweight']['batch']} closings, the best and the nominal again on "
               f"{result['samples']} fresh draws")
    else:
        how = (f"{len(result['curve'])} elbow angles x {result['samples']} draws, then again "
               f"on {result['samples']} fresh draws")
    return "\n".join([
        f"{result['object']} grasp {index}, sigma = {result['sigma']} rad, {how} "
        f"({result['engine']} engine)",
        f"  nominal elbow {result['nominal_psi']:+.3f} rad: P(FC) "
        f"{result['nominal_p_fc']:.3f} ({nlo:.3f} .. {nhi:.3f})",
        f"  best elbow    {result['best_psi']:+.3f} rad: P(FC) "
        f"{result['best_p_fc']:.3f} ({lo:.3f} .. {hi:.3f})  [fresh draws]",
        f"  gain over nominal {result['gain']:+.3f} (95% CI {glo:+.3f} .. {ghi:+.3f}, paired)",
        *certificate_lines(result["certificate"], result["grid_step"])])


def certificate_lines(cert: dict, grid_step: float) -> list[str]:
    """The certificate (``Certificate.to_json()``) in words: the claim, then the verdict."""
    if cert["bound"] is None:
        return [f"  {cert['statement']}"]
    verdict = (f"certified at epsilon {cert['epsilon']:g}" if cert["certified"] else
               f"not certified at epsilon {cert['epsilon']:g} (psi = {cert['worst_psi']:+.3f} "
               "rad is the rival it cannot rule out)")
    from kinegrasp_env.toolkit.elbow_certificate import METHOD

    how = (f"exact one-sided binomial bounds on {cert['fresh_draws']} fresh draws"
           if cert["method"] == METHOD
           else f"{cert['method']} ({cert['fresh_draws']} closings)")
    return [f"  {cert['statement']}",
            f"    {verdict}; {plural(len(cert['rivals']), 'other angle')}, {how}; angles "
            f"between the {grid_step:.3f} rad grid points not covered"]


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
    p.add_argument("--engine", default=None, choices=("fast", "pybullet"),
                   help="fast (the default robot's default: many angles x draws) or pybullet "
                   "(the reference; the default of a robot given with --robot, whose "
                   "self-motion is checked for clearance by pybullet either way)")
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
    p.add_argument("--plot", help="write a PNG of P(FC) against the elbow angle")
    p.add_argument("--report", help="write a self-contained interactive HTML page: P(FC) "
                   "along the self-motion, the arm at the nominal and at the best elbow in 3-D")
    p.add_argument("--robot", help=f"catalog robot (default {DEFAULT_ROBOT}, or --grasps' "
                   "robot; another one: its shipped grasps, its arm's self-motion (7 joints) "
                   "or IK branches (6 joints), the pybullet engine)")
    p.add_argument("--grasps", help="a grasp file (e.g. `kinegrasp plan`'s output): its grasp "
                   "--grasp (an id, else an index) instead of a shipped one")
    p.add_argument("--ik-starts", help="random IK starts that find a 6-joint arm's IK "
                   f"branches (default {DEFAULT_IK_STARTS})")
    p.set_defaults(func=cmd_elbow)
