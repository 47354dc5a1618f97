"""``kinegrasp sensitivity``: which source of error limits a grasp's P(FC).

P(FC) with every source of a noise spec, with each source alone and with all but one, and the
first-order and total Sobol indices of force closure per source, with bootstrap intervals
(:func:`kinegrasp_env.toolkit.sensitivity.analyze`, by the robot's engine); optionally a bar
chart. ``--factors joints`` splits the joints into one factor per arm joint.

The robot is ``--robot NAME``, else the grasp file's, else the default one; the grasp is
``--grasp`` of the robot's shipped set of ``--object``, or of ``--grasps FILE`` (an id, else an
index; a grasp of another robot is refused).
"""

from __future__ import annotations

import json

from kinegrasp_env.cli.common import (
    CLIError,
    add_engine_arg,
    add_friction_arg,
    add_object_arg,
    check_spec_noise,
    friction_from,
    grasp_index_help,
    parse_seed,
    positive_int,
    reported,
    shipped_grasp,
)
from kinegrasp_env.cli.grasp_choice import grasp_shown
from kinegrasp_env.cli.output_paths import input_files, output_file
from kinegrasp_env.robot.default import DEFAULT_ROBOT

#: The object without --object or --grasps.
DEFAULT_OBJECT = "spray_flask"
#: ``--factors`` choices: the model's sources, or one factor per arm joint beside the others.
FACTORS = ("sources", "joints")


def cmd_sensitivity(args) -> int:
    from kinegrasp_env.sampling.noise_model import NoiseSpecError
    from kinegrasp_env.sampling.noise_spec import load_noise_model

    with reported(NoiseSpecError):
        model = load_noise_model(args.noise_spec)
    samples = positive_int(args.samples, "--samples", low=2)
    friction = friction_from(args, model, simulated=args.engine == "physics")
    bootstrap = positive_int(args.bootstrap, "--bootstrap", low=0)
    seed = parse_seed(args.seed)
    index, grasp = _request(args, model)
    if args.plot is not None:
        output_file(args.plot, "--plot", inputs=input_files(args))
    result = _analyze(grasp, model, samples, seed, args.engine, bootstrap, friction,
                      per_joint=args.factors == "joints")
    payload = result.to_json()
    written = None
    if args.plot:  # before the results are printed: a failing figure is a warning
        from kinegrasp_env.toolkit.plots import plot_sensitivity, safe_figure

        shown = grasp_shown(args, index, grasp)
        title = (f"robot {result.robot}, {grasp.object} grasp {shown}: P(FC) "
                 f"{result.p_all:.3f} with every source, {samples} draws per setting")
        written = safe_figure(lambda: plot_sensitivity(payload, args.plot, title=title),
                              args.plot)
    if args.json:
        print(json.dumps(payload if written is None else {**payload, "plot": str(args.plot)}))
    else:
        print(result.table())
        if written is not None:
            print(f"plot written to {args.plot}")
    return 0


def _request(args, model) -> tuple[int, object]:
    """``(index, grasp)``: grasp ``--grasp`` of ``--grasps FILE`` or of the robot's shipped set
    of ``--object``; one line for what the robot's engines cannot take (checked before any
    work)."""
    from kinegrasp_env.cli.grasp_choice import grasp_of_file
    from kinegrasp_env.montecarlo.evaluate import ENGINES
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.toolkit.sensitivity import check_factors
    from kinegrasp_env.world.grasps import check_robot

    index, grasp = grasp_of_file(args) if args.grasps is not None else (None, None)
    robot = args.robot or (DEFAULT_ROBOT if grasp is None else grasp.robot)
    with reported(RobotDescriptionError):
        arm = load_robot(robot).arm_dof
    if args.engine not in ENGINES:
        raise CLIError(f"--engine {args.engine}: robot {robot!r} is evaluated by the "
                       f"{' or '.join(ENGINES)} engine only")
    if not model.sources:
        raise CLIError(f"--noise-spec {args.noise_spec}: the model has no source of error; "
                       "nothing to analyze")
    check_spec_noise(args, model, robot, args.engine)
    try:
        check_factors(model, args.factors == "joints")
    except ValueError as exc:
        raise CLIError(f"--noise-spec {args.noise_spec}: {exc} (--factors joints)") from None
    if grasp is None:
        args.object = args.object or DEFAULT_OBJECT
        index, grasp = shipped_grasp(args.object, args.grasp, robot)
    with reported(ValueError):
        check_robot(grasp, robot, "--robot")
        model.sigma_vector(arm)
    return index, grasp


def _analyze(grasp, noise, samples: int, seed: int, engine: str, bootstrap: int,
             friction: float, per_joint: bool):
    """The analysis by ``engine``, the one ``evaluate`` closes the robot's draws with
    (:func:`~kinegrasp_env.montecarlo.engines.make_engine`), with a progress bar
    on stderr (one step per setting)."""
    from kinegrasp_env.progress_bar import progress_bar
    from kinegrasp_env.toolkit.sensitivity import analyze

    bar = progress_bar(desc="sensitivity", unit="setting")

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    try:
        return analyze(grasp, noise, samples, seed, engine=engine, bootstrap=bootstrap,
                       progress=progress, per_joint=per_joint, friction=friction)
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
    p.add_argument("--grasps", help="grasp file (from `kinegrasp plan`) or palm-pose file: "
                   "analyze its grasp --grasp (its robot unless --robot names one; a grasp of "
                   "another robot is refused)")
    p.add_argument("--noise-spec", required=True,
                   help="YAML or JSON noise model: joints, hand, palm, object, friction "
                   "(or preset: dexnet); every source present is a factor (the arm joints one, "
                   "or one each with --factors joints)")
    p.add_argument("--samples", default="1000",
                   help="draws per setting (the analysis runs about 2 + 3 x factors settings)")
    p.add_argument("--bootstrap", default="1000",
                   help="bootstrap resamples of the Sobol intervals (0: none)")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_engine_arg(p)
    p.set_defaults(engine="fast")
    add_friction_arg(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="write a PNG bar chart of the indices and P(FC)s")
    p.add_argument("--robot", help=f"catalog robot (default {DEFAULT_ROBOT}, or --grasps' "
                   "robot): the grasp from its shipped set, closed by its engine")
    p.add_argument("--factors", default="sources", choices=FACTORS,
                   help="sources: one factor per source of the spec (the arm joints one); "
                   "joints: one per arm joint, beside the hand, palm, object and friction "
                   "sources")
    p.set_defaults(func=cmd_sensitivity)
