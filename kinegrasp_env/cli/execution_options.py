"""The executor options every Monte Carlo command takes: ``--backend``, ``--address`` and
``--processes``, and the :class:`~kinegrasp_env.montecarlo.execution.Executor` they ask for."""

from __future__ import annotations

import argparse

from kinegrasp_env.cli.common import BACKEND_NAMES, CLIError, positive_int, reported


def add_execution_args(parser: argparse.ArgumentParser, default_processes: int) -> None:
    """``--backend``, ``--address`` and ``--processes`` (see :func:`executor_from`)."""
    parser.add_argument("--backend", default="local", choices=BACKEND_NAMES,
                        help="local (a process pool on this machine) or ray")
    parser.add_argument("--address", help="Ray cluster to use with --backend ray (e.g. "
                        "ray://head:10001); without it a local Ray instance is started")
    parser.add_argument("--processes", default=None,
                        help=f"local worker processes (default {default_processes}); more "
                        "than this machine's cores is capped to them, with a warning; with "
                        "--backend ray and no --address, the local Ray instance's CPUs "
                        "(default: all)")
    parser.set_defaults(default_processes=default_processes)


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity, else ``os.cpu_count()``)."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def processes_from(text: str | int, name: str = "--processes") -> int:
    """A worker count >= 1, capped to :func:`available_cores` (more workers than cores only
    add start-up and switching): the cap is said in one warning line on stderr."""
    import sys

    wanted = positive_int(text, name)
    cores = available_cores()
    if wanted > cores:
        print(f"kinegrasp: warning: {name} {wanted} is more than the {cores} cores this machine "
              f"gives the command; using {cores}", file=sys.stderr)
        return cores
    return wanted


def check_execution(args) -> None:
    """CLIError for a ``--backend`` or ``--processes`` that :func:`executor_from` would
    refuse: for a command that does other work (solving candidates) before it starts its
    workers, so that the refusal comes first."""
    from kinegrasp_env.montecarlo.execution import BACKENDS

    if args.backend not in BACKENDS:
        raise CLIError(f"--backend must be one of {', '.join(BACKENDS)}, got {args.backend!r}")
    if args.processes is not None:
        positive_int(args.processes, "--processes")


def executor_from(args):
    """The :class:`~kinegrasp_env.montecarlo.execution.Executor` that the command line asks for."""
    from kinegrasp_env.montecarlo.execution import make_executor

    check_execution(args)
    if args.processes is None:
        processes = None
    elif args.backend == "local" or args.address is None:  # processes on this machine
        processes = processes_from(args.processes)
    else:  # a cluster's processes: not bounded by this machine's cores
        processes = positive_int(args.processes, "--processes")
    if args.backend == "local" and processes is None:
        processes = min(args.default_processes, available_cores())
    # make_executor's ValueErrors are about these settings: Ray missing, an unreachable or
    # malformed --address
    with reported(ValueError):
        return make_executor(args.backend, processes, args.address)
