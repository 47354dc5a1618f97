"""Arm commands: ``planar`` (end-effector noise of a planar arm), ``ee`` (palm-position noise
of any catalog robot's arm, sampled and first order) and ``convergence`` (the estimators'
convergence, the paper's Fig. 3).
"""

from __future__ import annotations

from kinegrasp_env.cli.common import (
    CLIError,
    add_noise_args,
    float_list,
    format_moments,
    noise_from,
    parse_seed,
    plural,
    positive_int,
    print_json,
    reported,
)
from kinegrasp_env.cli.output_paths import output_file
from kinegrasp_env.robot.default import DEFAULT_ROBOT


def cmd_planar(args) -> int:
    import numpy as np

    from kinegrasp_env.robot.planar import PlanarArm
    from kinegrasp_env.sampling.stats import moments

    links = float_list(args.links, "--links")
    q0 = float_list(args.q0, "--q0")
    if len(links) != len(q0):
        raise CLIError(f"--links has {plural(len(links), 'length')} but --q0 has "
                       f"{plural(len(q0), 'angle')}")
    if any(v <= 0 for v in links):
        raise CLIError(f"--links: link lengths must be > 0, got {args.links}")
    noise, sigma, samples, seed = noise_from(args)
    if args.plot is not None:
        output_file(args.plot, "--plot")
    arm = PlanarArm(tuple(links))
    ee = arm.sample(np.array(q0), noise, samples, np.random.default_rng(seed))
    mom = moments(ee)
    exact_mean, exact_cov = arm.exact_moments(np.array(q0), noise)
    if args.plot:
        from kinegrasp_env.toolkit.plots import plot_planar

        plot_planar(arm.joint_positions(np.array(q0)), ee, mom.mean, mom.cov, args.plot,
                    title=f"{len(links)}-link arm, sigma = {sigma:g} rad ({args.noise})")
    if args.json:
        print_json({"mean": mom.mean, "cov": mom.cov, "skew": mom.skew, "samples": samples,
                    "exact_mean": exact_mean, "exact_cov": exact_cov, "sigma": sigma,
                    "noise": args.noise, "seed": seed})
    else:
        print(format_moments(f"end effector of a {len(links)}-link planar arm "
                              f"({samples} draws)", mom.mean, mom.cov, mom.skew))
        print(format_moments("closed form", exact_mean, exact_cov))
        if args.plot:
            print(f"plot written to {args.plot}")
    return 0


def cmd_ee(args) -> int:
    """``kinegrasp ee --robot NAME``: the palm position's mean and covariance under joint
    noise on the robot's arm, sampled and to first order (J Sigma J^T)."""
    import numpy as np

    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.robot.endeffector import ArmEndEffector
    from kinegrasp_env.sampling.stats import moments

    with reported(RobotDescriptionError):
        description = load_robot(args.robot)
    effector = ArmEndEffector.of(description)
    q0 = description.home_arm() if args.q0 is None else float_list(args.q0, "--q0")
    try:
        q0 = effector.check_q0(q0)
    except ValueError as exc:
        raise CLIError(f"--q0: {exc}") from None
    noise, sigma, samples, seed = noise_from(args)
    ee = effector.sample(q0, noise, samples, np.random.default_rng(seed))
    mom = moments(ee)
    linear_mean, linear_cov = effector.first_order(q0, noise)
    if args.json:
        print_json({"robot": args.robot, "palm_link": effector.palm, "q0": q0,
                    "mean": mom.mean, "cov": mom.cov, "skew": mom.skew,
                    "first_order_mean": linear_mean, "first_order_cov": linear_cov,
                    "samples": samples, "sigma": sigma, "noise": args.noise, "seed": seed})
    else:
        print(format_moments(f"{args.robot} palm position ({effector.palm} origin, "
                              f"{samples} draws)", mom.mean, mom.cov, mom.skew))
        print(format_moments("first order (mean p(q0), cov J Sigma J^T)", linear_mean,
                              linear_cov))
    return 0


def cmd_convergence(args) -> int:
    """``kinegrasp convergence``: the estimators' convergence (the paper's Fig. 3) for the
    2-link planar arm and a catalog robot's arm (``--robot``, its end-effector study's
    description's ``home`` configuration)."""
    import numpy as np

    from kinegrasp_env.progress_bar import progress_bar
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.robot.endeffector import (
        DEFAULT_PLANAR_LINKS,
        DEFAULT_PLANAR_Q0,
        PAPER_SIGMAS,
        ArmEndEffector,
        arm_convergence,
        planar_convergence,
    )
    from kinegrasp_env.robot.planar import PlanarArm
    from kinegrasp_env.toolkit.plots import plot_convergence

    with reported(RobotDescriptionError):
        description = load_robot(args.robot)
    effector = ArmEndEffector.of(description)
    robot_label = description.arm_name
    trials = positive_int(args.trials, "--trials")
    truth = positive_int(args.truth_samples, "--truth-samples")
    max_n = positive_int(args.max_samples, "--max-samples")
    if max_n < 10:
        raise CLIError(f"--max-samples must be >= 10, got {max_n}")
    seed = parse_seed(args.seed)
    output_file(args.out, "--out", figure=True)
    sizes = np.unique(np.round(np.logspace(1, np.log10(max_n), 10)).astype(int))
    arm = PlanarArm(DEFAULT_PLANAR_LINKS)
    jobs = [(label, s) for label in ("2-link planar arm", robot_label) for s in PAPER_SIGMAS]
    curves: dict[str, dict[float, object]] = {}
    for i, (label, sigma) in enumerate(progress_bar(jobs, desc="convergence")):
        stream = np.random.default_rng([seed, i])  # independent stream per curve
        if label.startswith("2-link"):
            curve = planar_convergence(arm, DEFAULT_PLANAR_Q0, sigma, sizes=sizes, trials=trials,
                                       truth_samples=truth, seed=stream)
        else:
            curve = arm_convergence(effector, description.home_arm(), sigma,
                                    sizes=sizes, trials=trials, truth_samples=truth,
                                    seed=stream)
        curves.setdefault(label, {})[sigma] = curve
    path = plot_convergence(curves, args.out)
    summary = {label: {f"{s:g}": {"samples": c.sizes.tolist(), "mean_error": c.mean_error.tolist(),
                                  "cov_error": c.cov_error.tolist(),
                                  "skew_error": c.skew_error.tolist()}
                       for s, c in by.items()} for label, by in curves.items()}
    if args.json:
        print_json(summary)
    else:
        print(f"convergence figure written to {path}")
    return 0


def add_commands(sub) -> None:
    """Register ``planar``, ``ee`` and ``convergence``."""
    p = sub.add_parser("planar", help="end-effector statistics of a planar arm under joint noise")
    p.add_argument("--links", default="2,2", help="comma-separated link lengths, metres")
    p.add_argument("--q0", default="0.0,1.5708", help="comma-separated joint angles, radians")
    add_noise_args(p, 0.0175)
    p.add_argument("--plot", help="write a PNG of the arm, the sampled cloud and its ellipse")
    p.set_defaults(func=cmd_planar)

    p = sub.add_parser("ee", help="palm-position statistics of a catalog robot's arm under "
                       "joint noise, sampled and first order (J Sigma J^T)")
    p.add_argument("--robot", default=DEFAULT_ROBOT, help="catalog robot")
    p.add_argument("--q0", help="the arm's joint angles, comma-separated, radians (default: "
                   "the description's home configuration)")
    add_noise_args(p, 0.0133)
    p.set_defaults(func=cmd_ee)

    p = sub.add_parser("convergence", help="Fig. 3: estimator convergence, a planar arm and a "
                       "catalog robot's arm (the KUKA by default)")
    p.add_argument("--robot", default=DEFAULT_ROBOT, help="catalog robot whose arm is studied "
                   f"(default {DEFAULT_ROBOT}), from its description's home configuration")
    p.add_argument("--out", default="convergence.png", help="output PNG")
    p.add_argument("--trials", default="10", help="independent estimates per sample size")
    p.add_argument("--truth-samples", default="100000",
                   help="draws of the reference estimate the errors are measured against")
    p.add_argument("--max-samples", default="10000",
                   help="largest sample size (10 sizes from 10 up to it)")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    p.add_argument("--json", action="store_true", help="print the curves as JSON")
    p.set_defaults(func=cmd_convergence)
