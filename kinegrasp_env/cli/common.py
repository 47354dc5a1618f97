"""What every ``kinegrasp`` sub-command shares: the user-error type, the parser class (one-line
usage errors, defaults in ``--help``), value parsers, the noise, seed and execution options,
and JSON output.

Error policy: a command validates the user's values here, at the CLI boundary, and raises
:class:`CLIError` (one line, exit 2). A library error is turned into a ``CLIError`` only at
the call that checks a user's value, by its own type (:func:`reported`); any other exception
is a bug and reaches ``main`` as a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
from collections.abc import Iterator

from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.wording import plural  # noqa: F401  (the commands take it from here)

# Building the parser imports nothing heavy (no NumPy, SciPy, trimesh, pybullet or numba):
# ``kinegrasp --help`` answers at once. The choices below are copies of the library's
# definitions, kept here for that reason and tested equal to them.

#: ``--engine`` choices; equal to ``montecarlo.grasp_stats.ENGINES`` (tested).
ENGINE_NAMES = ("pybullet", "fast", "physics")
#: ``--noise`` choices; equal to ``sampling.noise.DISTRIBUTIONS`` (tested).
DISTRIBUTION_NAMES = ("gaussian", "uniform", "triangular")
#: ``--backend`` choices; equal to ``montecarlo.execution.BACKENDS`` (tested).
BACKEND_NAMES = ("local", "ray")
#: ``--friction``'s default and the friction cones' edges every command uses; equal to
#: ``quality.wrenches.DEFAULT_FRICTION`` and ``DEFAULT_NUM_EDGES`` (tested).
DEFAULT_FRICTION, NUM_EDGES = 0.5, 8


class CLIError(ValueError):
    """A user error: printed as one line, exit status 2."""


@contextlib.contextmanager
def reported(*errors: type[Exception]) -> Iterator[None]:
    """Report the listed library input errors raised inside as :class:`CLIError`.

    Wrap only the call that checks a user's value (a file, an address), never a whole
    command: anything else that goes wrong is a bug and must show its traceback.
    """
    try:
        yield
    except errors as exc:
        raise CLIError(str(exc)) from None


class HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default (unless None or False)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if (action.option_strings and "%(default)" not in text
                and action.default not in (None, False, argparse.SUPPRESS)):
            text += " (default: %(default)s)"
        return text


class Parser(argparse.ArgumentParser):
    """``kinegrasp``'s parsers: a usage error is one line with a hint to ``--help``."""

    def __init__(self, *args, formatter_class=HelpFormatter, **kwargs) -> None:
        super().__init__(*args, formatter_class=formatter_class, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


# ----------------------------------------------------------------------------- parsing helpers
def finite_float(text: str, name: str = "value") -> float:
    try:
        value = float(text)
    except ValueError:
        raise CLIError(f"{name}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise CLIError(f"{name}: {text!r} is not a finite number")
    return value


def float_list(text: str, name: str) -> list[float]:
    parts = [p.strip() for p in text.split(",")]
    if not text.strip() or any(p == "" for p in parts):
        raise CLIError(f"{name}: {text!r} is not a comma-separated list of numbers")
    return [finite_float(p, name) for p in parts]


def nonnegative(value: float, name: str) -> float:
    if value < 0:
        raise CLIError(f"{name} must be >= 0, got {value:g}")
    return value


def positive_int(text: str | int, name: str, low: int = 1) -> int:
    """An integer >= ``low`` (1 unless given)."""
    try:
        value = int(text)
    except ValueError:
        raise CLIError(f"{name}: {text!r} is not an integer") from None
    if value < low:
        raise CLIError(f"{name} must be >= {low}, got {value}")
    return value


def positive_float(text: str, name: str) -> float:
    """A finite number > 0."""
    value = finite_float(text, name)
    if value <= 0:
        raise CLIError(f"{name} must be > 0, got {value:g}")
    return value


def to_jsonable(value):
    """``value`` with NumPy arrays and scalars turned into lists and Python numbers, and
    NaN and infinities (nested in lists and mappings too) into None: strict JSON, which a
    browser's ``JSON.parse`` reads (Python's ``json`` writes ``NaN``, which it does not)."""
    if hasattr(value, "tolist") and hasattr(value, "dtype"):  # ndarray or NumPy scalar
        value = value.tolist()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {k: to_jsonable(v) for k, v in value.items()}
    return value


def print_json(payload: dict) -> None:
    """Print ``payload`` as one line of strict JSON (:func:`to_jsonable`)."""
    print(json.dumps(to_jsonable(payload), allow_nan=False))


def format_moments(label: str, mean, cov, skew=None) -> str:
    import numpy as np

    with np.printoptions(precision=6, suppress=False):
        text = f"{label}\n  mean: {np.asarray(mean)}\n  cov:\n{np.asarray(cov)}"
        return text if skew is None else f"{text}\n  skew: {np.asarray(skew)}"


def add_noise_args(p: argparse.ArgumentParser, sigma_default: float) -> None:
    p.add_argument("--sigma", default=str(sigma_default),
                   help="standard deviation of the noise on each joint, radians (0 .. pi)")
    p.add_argument("--noise", default="gaussian", choices=DISTRIBUTION_NAMES,
                   help="distribution of the joint noise (all with standard deviation sigma)")
    p.add_argument("--samples", default="10000", help="number of Monte Carlo draws")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def sigma_value(text: str, option: str = "--sigma") -> float:
    """A joint sigma option (radians): a finite number >= 0 within the library's bound
    (:func:`~kinegrasp_env.sampling.noise.check_sigma_bound`)."""
    from kinegrasp_env.sampling.noise import check_sigma_bound

    sigma = nonnegative(finite_float(text, option), option) + 0.0  # -0 is 0 (printed so)
    with reported(ValueError):
        check_sigma_bound(sigma, option)
    return sigma


def certificate_levels(args) -> tuple[float, float]:
    """``--epsilon`` and ``--delta`` of a certificate, checked by the library's rule
    (:func:`~kinegrasp_env.toolkit.certificates.check_levels`), or a one-line CLIError."""
    from kinegrasp_env.toolkit.certificates import check_levels

    epsilon = finite_float(args.epsilon, "--epsilon")
    delta = finite_float(args.delta, "--delta")
    with reported(ValueError):
        check_levels(epsilon, delta, ("--epsilon", "--delta"))
    return epsilon, delta


def joint_noise(sigma, kind: str, model) -> dict:
    """``evaluate_grasp``'s noise keywords: ``noise_model=model`` where a noise spec gave
    one, else ``sigma`` (radians) and the distribution ``kind``."""
    return {"noise_model": model} if model is not None else {"sigma": sigma, "noise": kind}


def noise_from(args) -> tuple:
    """(noise, sigma, samples, seed) of ``--sigma/--noise`` or ``--noise-spec`` (then the
    noise is the model and sigma its joints' sigma: a number or 7)."""
    from kinegrasp_env.sampling.noise import JointNoise

    model = noise_spec_from(args)
    if model is not None:
        sigma = model.sigma if isinstance(model.sigma, float) else list(model.sigma)
        return model, sigma, positive_int(args.samples, "--samples"), parse_seed(args.seed)
    sigma = sigma_value(args.sigma)
    samples = positive_int(args.samples, "--samples")
    seed = parse_seed(args.seed)
    return JointNoise(sigma, args.noise), sigma, samples, seed


def add_noise_spec_arg(p: argparse.ArgumentParser) -> None:
    """``--noise-spec FILE`` (see :func:`noise_spec_from`)."""
    p.add_argument("--noise-spec", help="YAML or JSON noise model of every source of error: "
                   "joints, hand, palm, object, friction, or preset: dexnet (see "
                   "docs/conventions.md); replaces --sigma and --noise")


def noise_spec_from(args):
    """The :class:`~kinegrasp_env.sampling.noise_model.NoiseModel` of ``--noise-spec``, or
    None without it; a bad spec, and ``--sigma`` or ``--noise`` next to it, are
    :class:`CLIError` lines."""
    path = getattr(args, "noise_spec", None)
    if path is None:
        return None
    parser = getattr(args, "command_parser", None)
    for option in ("sigma", "noise"):
        if parser is not None and getattr(args, option) != parser.get_default(option):
            raise CLIError(f"--{option} and --noise-spec both given: the spec's joints "
                           "section is the joint noise")
    from kinegrasp_env.montecarlo.noise_rows import check_engine_noise
    from kinegrasp_env.sampling.noise_model import NoiseSpecError
    from kinegrasp_env.sampling.noise_spec import load_noise_model

    with reported(NoiseSpecError):
        model = load_noise_model(path)
    try:
        check_engine_noise(model, getattr(args, "engine", "pybullet"))
    except ValueError as exc:
        raise CLIError(f"--noise-spec {path}: {exc}") from None
    return model


def check_spec_noise(args, model, robot, engine: str, static_hold: bool = False) -> None:
    """One :class:`CLIError` line naming ``--noise-spec``'s file for what a robot's run
    cannot take from its model (:func:`~kinegrasp_env.montecarlo.noise_rows.
    check_robot_noise`; ``robot`` a catalog name or a description, an unknown one its own
    line)."""
    from kinegrasp_env.montecarlo.noise_rows import check_robot_noise
    from kinegrasp_env.robot.catalog import as_description
    from kinegrasp_env.robot.description import RobotDescriptionError

    with reported(RobotDescriptionError):
        description = as_description(robot)
    try:
        check_robot_noise(model, description, description.arm_dof, engine, static_hold)
    except ValueError as exc:
        raise CLIError(f"--noise-spec {args.noise_spec}: {exc}") from None


def parse_seed(text: str) -> int:
    """A ``--seed`` value: an integer >= 0."""
    try:
        seed = int(text)
    except ValueError:
        raise CLIError(f"--seed: {text!r} is not an integer") from None
    if seed < 0:
        raise CLIError(f"--seed must be >= 0, got {seed}")
    return seed


def add_friction_arg(parser: argparse.ArgumentParser) -> None:
    """``--friction MU`` (see :func:`friction_from`)."""
    parser.add_argument("--friction",
                        help="Coulomb friction coefficient mu at every contact: the friction "
                        "cones of the quality and of the hold checks, the simulated mu in "
                        f"physics (a number >= 0; default {DEFAULT_FRICTION:g}; refused beside "
                        "a noise spec's friction source, whose nominal mu the noise-free "
                        "grasp then takes)")


def friction_per_draw(noise) -> bool:
    """Whether ``noise`` (a noise model, joint noise or None) draws mu per draw: a noise
    spec's friction source of a distribution (a ``fixed`` one gives every draw its value,
    which is then the run's mu)."""
    source = getattr(noise, "friction", None)
    return source is not None and source.distribution != "fixed"


def friction_setting(noise, friction: float) -> float | str:
    """What a page's settings say of mu: ``friction``, or that ``noise`` draws it per
    draw (:func:`friction_per_draw`) and the noise-free grasp takes ``friction``, the
    source's nominal mu."""
    return (f"per draw (the noise spec's friction source); nominal Q at mu {friction:g}"
            if friction_per_draw(noise) else friction)


def friction_from(args, noise=None, simulated: bool = False) -> float:
    """``--friction``: a finite mu >= 0 (:func:`~kinegrasp_env.quality.wrenches.
    check_parameters`' rule; default :data:`DEFAULT_FRICTION`), > 0 where a simulator runs
    the contacts (``simulated``: the physics engine, the holding test;
    :func:`~kinegrasp_env.physics.protocol.check_simulated_friction`). Given beside a noise
    model (``noise``) with a friction source, which sets mu per draw, it is a
    :class:`CLIError` line; without it the noise-free grasp (its nominal Q, the drawn cones)
    takes the source's nominal mu (:func:`~kinegrasp_env.sampling.noise_model.
    nominal_friction`)."""
    from kinegrasp_env.quality.wrenches import check_parameters
    from kinegrasp_env.sampling.noise_model import nominal_friction

    text = getattr(args, "friction", None)
    if getattr(noise, "friction", None) is not None and text is not None:
        raise CLIError("--friction and the noise spec's friction source both set mu: give "
                       "one of them")
    value = DEFAULT_FRICTION if text is None else finite_float(text, "--friction")
    try:
        check_parameters(value, NUM_EDGES)
    except ValueError:
        raise CLIError(f"--friction must be >= 0, got {text}") from None
    if simulated:
        from kinegrasp_env.physics.protocol import check_simulated_friction

        try:
            check_simulated_friction(value)
        except ValueError:
            raise CLIError(f"--friction must be > 0 where a simulator runs the contacts (the "
                           f"physics engine, the holding test), got {text}") from None
    return nominal_friction(noise, value)


def add_engine_arg(parser: argparse.ArgumentParser, default: str = "pybullet") -> None:
    """``--engine``: pybullet, fast or physics (``default`` unless given)."""
    parser.add_argument("--engine", default=default, choices=ENGINE_NAMES,
                        help="pybullet (the reference), fast (batched, same draws) or "
                             "physics (pybullet dynamics, same draws; slow)")


def add_static_hold_arg(parser: argparse.ArgumentParser, shows: str) -> None:
    """``--static-hold``: the static hold check of every draw; ``shows``: what the command
    then prints."""
    parser.add_argument("--static-hold", action="store_true",
                        help="also check each draw's static hold: can its contacts carry the "
                        "object's weight (catalog mass) in six gravity directions and the "
                        "lift with forces in the friction cones and the hand's effort "
                        f"limits; {shows}")


def add_hold_simulator_arg(parser: argparse.ArgumentParser) -> None:
    """``--hold-simulator``: where the quick holding test runs (pybullet or MuJoCo)."""
    parser.add_argument("--hold-simulator", default="pybullet", choices=("pybullet", "mujoco"),
                        help="the simulator of the quick holding test (default pybullet; "
                        "mujoco: pip install mujoco)")


def engine_name(value: str) -> str:
    """Validated ``--engine`` value."""
    from kinegrasp_env.montecarlo.grasp_stats import ENGINES

    if value not in ENGINES:
        raise CLIError(f"--engine must be one of {', '.join(ENGINES)}, got {value!r}")
    return value


def parse_index(text: str) -> int:
    """A grasp index given on the command line."""
    try:
        return int(text)
    except ValueError:
        raise CLIError(f"--grasp: {text!r} is not an integer") from None


def object_name(text: str) -> str:
    """``--object``: a built-in or imported object's name (argparse ``type``; a bad name is a
    usage error)."""
    from kinegrasp_env.world.names import is_object, unknown_object

    if not is_object(text):
        raise argparse.ArgumentTypeError(str(unknown_object(text)))
    return text


def add_object_arg(parser: argparse.ArgumentParser, default: str, help: str) -> None:
    """``--object`` with the catalog's names (built-in and imported) as choices."""
    from kinegrasp_env.world.names import object_names

    parser.add_argument("--object", default=default, type=object_name, choices=object_names(),
                        help=help)


def grasp_index_help() -> str:
    """Help of ``--grasp``: an index in the robot's shipped set of the object, with the
    default robot's index range of every object's set (another robot's sets may hold
    another number: an index out of range is refused naming the range)."""
    from kinegrasp_env.world.names import OBJECT_NAMES, shipped_grasp_count

    ranges = {name: f"0..{shipped_grasp_count(name) - 1}" for name in OBJECT_NAMES}
    if len(set(ranges.values())) == 1:
        return (f"index in the robot's shipped grasp set of the object ({DEFAULT_ROBOT}'s: "
                f"{next(iter(ranges.values()))})")
    return (f"index in the robot's shipped grasp set of the object ({DEFAULT_ROBOT}'s: "
            + ", ".join(f"{name} {r}" for name, r in ranges.items()) + ")")


def shipped_grasp(object_name: str, text: str, robot: str | None = None):
    """``(index, grasp)``: entry ``--grasp`` of the object's shipped set for ``robot`` (None:
    the default robot), range-checked (an imported object has none: one line suggesting
    ``kinegrasp plan``)."""
    from kinegrasp_env.world.grasps import NoGraspSetError, shipped_grasps

    index = parse_index(text)
    robot = robot or DEFAULT_ROBOT
    with reported(NoGraspSetError):
        grasps = shipped_grasps(object_name, robot)
    if not 0 <= index < len(grasps):
        raise CLIError(f"--grasp: grasp index {index} out of range: {object_name} has "
                       f"{len(grasps)} grasps of robot {robot} (0..{len(grasps) - 1})")
    return index, grasps[index]
