"""What every ``kinegrasp`` sub-command shares: the user-error type, value parsers, the noise,
seed and execution options, and JSON output.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np


class CLIError(ValueError):
    """A user error: printed as one line, exit status 2."""


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


def positive_int(text: str | int, name: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise CLIError(f"{name}: {text!r} is not an integer") from None
    if value < 1:
        raise CLIError(f"{name} must be >= 1, got {value}")
    return value


def to_jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


def print_json(payload: dict) -> None:
    print(json.dumps({k: to_jsonable(v) for k, v in payload.items()}))


def format_moments(label: str, mean, cov, skew=None) -> str:
    with np.printoptions(precision=6, suppress=False):
        text = f"{label}\n  mean: {np.asarray(mean)}\n  cov:\n{np.asarray(cov)}"
        return text if skew is None else f"{text}\n  skew: {np.asarray(skew)}"


def add_noise_args(p: argparse.ArgumentParser, sigma_default: float) -> None:
    p.add_argument("--sigma", default=str(sigma_default),
                   help=f"joint noise standard deviation, radians (default {sigma_default})")
    p.add_argument("--noise", default="gaussian", choices=("gaussian", "uniform", "triangular"))
    p.add_argument("--samples", default="10000", help="number of Monte Carlo draws")
    p.add_argument("--seed", default="0", help="random seed")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def noise_from(args) -> tuple:
    from kinegrasp_env.sampling.noise import JointNoise

    sigma = nonnegative(finite_float(args.sigma, "--sigma"), "--sigma")
    samples = positive_int(args.samples, "--samples")
    seed = parse_seed(args.seed)
    return JointNoise(sigma, args.noise), sigma, samples, seed


def parse_seed(text: str) -> int:
    """A ``--seed`` value: an integer >= 0."""
    try:
        seed = int(text)
    except ValueError:
        raise CLIError(f"--seed: {text!r} is not an integer") from None
    if seed < 0:
        raise CLIError(f"--seed must be >= 0, got {seed}")
    return seed


def add_execution_args(parser: argparse.ArgumentParser, default_processes: int) -> None:
    """``--backend``, ``--address`` and ``--processes`` (see :func:`executor_from`)."""
    parser.add_argument("--backend", default="local",
                        help="local (a process pool on this machine, the default) or ray")
    parser.add_argument("--address", help="Ray cluster to use with --backend ray (e.g. "
                        "ray://head:10001); without it a local Ray instance is started")
    parser.add_argument("--processes", default=None,
                        help=f"local worker processes (default {default_processes}); with "
                        "--backend ray and no --address, the local Ray instance's CPUs "
                        "(default: all)")
    parser.set_defaults(default_processes=default_processes)


def executor_from(args):
    """The :class:`~kinegrasp_env.montecarlo.execution.Executor` that the command line asks for."""
    from kinegrasp_env.montecarlo.execution import BACKENDS, make_executor

    if args.backend not in BACKENDS:
        raise CLIError(f"--backend must be one of {', '.join(BACKENDS)}, got {args.backend!r}")
    processes = None if args.processes is None else positive_int(args.processes, "--processes")
    if args.backend == "local" and processes is None:
        processes = args.default_processes
    return make_executor(args.backend, processes, args.address)


def engine_name(value: str) -> str:
    """Validated ``--engine`` value."""
    from kinegrasp_env.montecarlo.evaluate import ENGINES

    if value not in ENGINES:
        raise CLIError(f"--engine must be one of {', '.join(ENGINES)}, got {value!r}")
    return value


def parse_index(text: str) -> int:
    """A grasp index given on the command line."""
    try:
        return int(text)
    except ValueError:
        raise CLIError(f"--grasp: {text!r} is not an integer") from None
