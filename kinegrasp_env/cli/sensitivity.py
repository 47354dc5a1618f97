"""``kinegrasp sensitivity``: which source of error limits a grasp's P(FC).

P(FC) with every source of a noise spec, with each source alone and with all but one, and the
first-order and total Sobol indices of force closure per source, with bootstrap intervals
(:mod:`kinegrasp_env.toolkit.sensitivity`); optionally a bar chart.

``--robot NAME`` (a catalog robot other than ``kuka_sdh``): the factors are the robot's arm
joints, the noise the spec's joints section (a distribution and a sigma, scalar or one per
joint; other sources refused in one line), the grasp one of the robot's shipped set, closed
by the robot's engine (:func:`kinegrasp_env.toolkit.sensitivity.analyze_joints`).
``--grasps FILE`` takes grasp ``--grasp`` (an id, else an index) of a grasp file instead; the
robot is then the file's unless ``--robot`` names it (a grasp of another robot is refused).
"""

from __future__ import annotations

import json
import sys

from kinegrasp_env.cli.common import (
    CLIError,
    add_engine_arg,
    add_friction_arg,
    add_object_arg,
    engine_name,
    friction_from,
    grasp_index_help,
    output_file,
    parse_seed,
    positive_int,
    reported,
    shipped_grasp,
)
from kinegrasp_env.robot.default import DEFAULT_ROBOT

#: The object without --object or --grasps.
DEFAULT_OBJECT = "spray_flask"


def cmd_sensitivity(args) -> int:
    from kinegrasp_env.montecarlo.evaluate import check_noise_engine
    from kinegrasp_env.sampling.noise_model import NoiseSpecError
    from kinegrasp_env.sampling.noise_spec import load_noise_model

    with reported(NoiseSpecError):
        model = load_noise_model(args.noise_spec)
    if not model.sources:
        raise CLIError(f"--noise-spec {args.noise_spec}: the model has no source of error; "
                       "nothing to analyze")
    samples = positive_int(args.samples, "--samples", low=2)
    friction = friction_from(args, model)
    bootstrap = positive_int(args.bootstrap, "--bootstrap", low=0)
    seed = parse_seed(args.seed)
    from kinegrasp_env.cli.grasp_choice import file_grasp

    index, grasp = file_grasp(args) if args.grasps is not None else (None, None)
    robot = args.robot or (DEFAULT_ROBOT if grasp is None else grasp.robot)
    if robot != DEFAULT_ROBOT:
        index, grasp, noise = _robot_request(args, model, robot, index, grasp)
        if args.plot:
            output_file(args.plot, "--plot")
        result = _analyze_robot(grasp, noise, samples, seed, args.engine, bootstrap, friction)
    else:
        if grasp is None:
            args.object = args.object or DEFAULT_OBJECT
            index, grasp = shipped_grasp(args.object, args.grasp)
        else:
            from kinegrasp_env.world.grasps import check_robot

            with reported(ValueError):
                check_robot(grasp, robot)
        engine = engine_name(args.engine)
        with reported(ValueError):
            check_noise_engine(model, engine)
        if args.plot:
            output_file(args.plot, "--plot")
        result = _analyze(grasp, model, samples, seed, engine, bootstrap, friction)
    payload = result.to_json()
    if args.json:
        print(json.dumps(payload))
    else:
        print(result.table())
    if args.plot:  # after the results: a failing figure is a warning, the results stand
        from kinegrasp_env.toolkit.plots import plot_sensitivity, safe_figure

        robot = "" if result.robot is None else f"robot {result.robot}, "
        title = (f"{robot}{args.object} grasp {index}: P(FC) {result.p_all:.3f} with every source, "
                 f"{samples} draws per setting")
        written = safe_figure(lambda: plot_sensitivity(payload, args.plot, title=title),
                              args.plot)
        if written is not None and not args.json:
            print(f"plot written to {args.plot}")
    return 0


def _robot_request(args, model, robot: str, index: int | None, grasp):
    """``(index, grasp, model)`` of a description robot: ``grasp`` (from ``--grasps``) or the
    robot's shipped grasp ``--grasp`` of ``--object``, and the spec's model (its arm joints,
    hand, palm, object and friction: :mod:`~kinegrasp_env.montecarlo.robot_noise`); one line for
    what the robot's engines cannot take (checked before any work)."""
    from kinegrasp_env.montecarlo.robot_evaluate import ENGINES
    from kinegrasp_env.montecarlo.robot_noise import check_robot_noise
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.world.grasps import check_robot

    with reported(RobotDescriptionError):
        arm = load_robot(robot).arm_dof
    if args.engine not in ENGINES:
        raise CLIError(f"--engine {args.engine}: robot {robot!r} is evaluated by the "
                       f"{' or '.join(ENGINES)} engine only")
    with reported(ValueError):
        check_robot_noise(model, robot, arm, args.engine)
    if model.joints is not None and (model.joints.covariance is not None
                                     or model.joints.bias is not None):
        raise CLIError(f"--noise-spec {args.noise_spec}: one factor per arm joint needs "
                       "independent, zero-mean joint errors (sigma and distribution), not a "
                       "joints covariance or bias")
    if grasp is None:
        args.object = args.object or DEFAULT_OBJECT
        index, grasp = shipped_grasp(args.object, args.grasp, robot)
    with reported(ValueError):
        check_robot(grasp, robot)
        model.sigma_vector(arm)
    return index, grasp, model


def _progress_bar():
    """(tqdm bar on stderr, progress callback(done, total)) of one step per setting."""
    from tqdm import tqdm

    bar = tqdm(total=None, desc="sensitivity", unit="setting", file=sys.stderr, disable=None)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    return bar, progress


def _analyze(grasp, model, samples: int, seed: int, engine: str, bootstrap: int,
             friction: float):
    """The analysis with a progress bar on stderr (one step per setting), friction mu
    ``friction`` (where the model has no friction source)."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.toolkit.sensitivity import analyze

    runner = make_engine(engine, grasp.object, friction)
    bar, progress = _progress_bar()
    try:
        return analyze(grasp, model, samples, seed, engine=runner, bootstrap=bootstrap,
                       progress=progress)
    finally:
        bar.close()
        runner.close()


def _analyze_robot(grasp, noise, samples: int, seed: int, engine: str, bootstrap: int,
                   friction: float):
    """A description robot's analysis over its arm joints, with the progress bar."""
    from kinegrasp_env.montecarlo.robot_evaluate import make_engine
    from kinegrasp_env.toolkit.sensitivity import analyze_joints

    bar, progress = _progress_bar()
    try:
        with make_engine(engine, grasp.robot, grasp.object, friction=friction) as runner:
            return analyze_joints(grasp, noise, samples, seed, engine=runner,
                                  bootstrap=bootstrap, progress=progress)
    finally:
        bar.close()


def add_commands(sub) -> None:
    """Register ``sensitivity``."""
    p = sub.add_parser("sensitivity", help="P(FC) per source of error and Sobol indices of "
                       "force closure: which source limits a grasp")
    add_object_arg(p, DEFAULT_OBJECT, f"catalog object (default {DEFAULT_OBJECT}; with "
                   "--grasps: the grasp's)")
    p.set_defaults(object=None)  # resolved in cmd_sensitivity: --grasps names its own
    p.add_argument("--grasp", default="0", help=grasp_index_help() + "; with --grasps: an id "
                   "in the file, else an index")
    p.add_argument("--grasps", help="grasp file (from `kinegrasp plan`): analyze its grasp "
                   "--grasp (its robot unless --robot names one; a grasp of another robot is "
                   "refused)")
    p.add_argument("--noise-spec", required=True,
                   help="YAML or JSON noise model: joints, hand, palm, object, friction "
                   "(or preset: dexnet); every source present is a factor")
    p.add_argument("--samples", default="1000",
                   help="draws per setting (the analysis runs about 2 + 3 x sources settings)")
    p.add_argument("--bootstrap", default="1000",
                   help="bootstrap resamples of the Sobol intervals (0: none)")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_engine_arg(p)
    p.set_defaults(engine="fast")
    add_friction_arg(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="write a PNG bar chart of the indices and P(FC)s")
    p.add_argument("--robot", help=f"catalog robot (default {DEFAULT_ROBOT}); another robot: "
                   "one factor per arm joint and one per hand, palm, object and friction "
                   "source of "
                   "the spec, the grasp from the robot's shipped set")
    p.set_defaults(func=cmd_sensitivity)
