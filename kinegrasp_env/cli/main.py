"""The ``kinegrasp`` command: the parser and the entry point.

Every sub-command validates its input up front and reports a bad value in one line on
stderr with exit status 2 (no traceback), usage errors included; results go to stdout
(``--json`` for machines), progress bars to stderr; a reader that closes stdout early
(``| head``) ends the command quietly. Any other exception is a bug: its traceback, then
one line asking to report it, exit status 1. One module per command group:
``arms``, ``objects``, ``robots``, ``grasping``, ``toolkit``, ``elbow``, ``report``,
``sensitivity``, ``validate``; ``common`` holds what they share.
"""

from __future__ import annotations

import argparse
import atexit
import errno
import os
import re
import signal
import sys
import threading
import traceback
from collections.abc import Sequence
from typing import NoReturn

from kinegrasp_env import __version__, kernel_notice
from kinegrasp_env.cli import (
    arms,
    elbow,
    grasping,
    objects,
    report,
    robots,
    sensitivity,
    toolkit,
    validate,
)
from kinegrasp_env.cli.common import CLIError, Parser
from kinegrasp_env.robot.default import DEFAULT_ROBOT

#: OS errors that are the machine's state, not a bug (disk full, no permission): one line.
ENVIRONMENT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM,
                                errno.EROFS})
BUG_HINT = "this is a bug in kinegrasp; please report it with the command you ran"


def build_parser() -> argparse.ArgumentParser:
    """The ``kinegrasp`` parser with every sub-command."""
    parser = Parser(prog="kinegrasp",
                    description="Grasp quality under kinematic (joint-angle) noise.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for group in (arms, objects, robots, grasping, toolkit, elbow, report, sensitivity, validate):
        group.add_commands(sub)
    for command_parser in sub.choices.values():  # its errors name the command
        command_parser.set_defaults(command_parser=command_parser)
        for action in command_parser._actions:  # and an action's (objects place) name both
            if isinstance(action, argparse._SubParsersAction):
                for action_parser in action.choices.values():
                    action_parser.set_defaults(command_parser=action_parser)
    accept_negative_values(parser)
    return parser


#: A token that starts like a negative number: a value, never an option.
_NEGATIVE_VALUE = re.compile(r"^-(\.?\d|inf|nan)", re.IGNORECASE)


def accept_negative_values(parser: argparse.ArgumentParser) -> None:
    """Let ``parser`` and its subcommands read a token that starts like a negative number
    (``-0.5,1``, ``-1e-3``, ``-inf``) as a value, not as an option: argparse's own rule takes
    plain decimals alone (``-0.5``), and ``--q0 -0.5,1`` or ``--position -1e-3 0.6 0`` were
    refused. No option of the CLI looks like a negative number."""
    parser._negative_number_matcher = _NEGATIVE_VALUE
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in set(action.choices.values()):
                accept_negative_values(sub)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        args.command_parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    kernel_notice.install()  # the first run on a machine compiles the kernels: say so
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        check_robot_option(args)
        return int(args.func(args) or 0)
    except CLIError as exc:
        print(f"{args.command_parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    except Terminated:
        print("kinegrasp: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        print("kinegrasp: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return _reader_gone()
    except OSError as exc:
        if exc.errno not in ENVIRONMENT_ERRNOS:
            return _bug(args.command_parser.prog)
        print(f"{args.command_parser.prog}: error: {exc}", file=sys.stderr)
        return 1
    except Exception:
        return _bug(args.command_parser.prog)
    finally:
        signal.signal(signal.SIGTERM, previous)


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived: the command stops as on Ctrl-C (its worker pool and open files closed
    on the way out, a resumable run's partial results kept), exit status 128 + 15."""


def _terminate(signum, frame) -> NoReturn:
    raise Terminated


def check_robot_option(args) -> None:
    """Refuse an unknown ``--robot`` before the command runs: one line naming the known
    robots (every command's ``--robot`` is a catalog name, resolved by
    :func:`kinegrasp_env.robot.catalog.check_robot_name`). The default robot is built in, so
    naming it (or none) loads nothing."""
    robot = getattr(args, "robot", None)
    if robot is None or robot == DEFAULT_ROBOT:
        return
    from kinegrasp_env.robot.catalog import check_robot_name
    from kinegrasp_env.robot.description import RobotDescriptionError

    try:
        check_robot_name(robot)
    except RobotDescriptionError as exc:
        raise CLIError(f"--robot: {exc}") from None


def _reader_gone() -> int:
    """The program reading stdout closed it (``kinegrasp ... | head``): stop quietly, as a
    Unix tool stopped by SIGPIPE does (exit status 128 + 13), with stdout pointed at the null
    device so that the final flush writes nowhere instead of failing again."""
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, sys.stdout.fileno())
    os.close(null)
    return 128 + 13


def _bug(prog: str) -> int:
    """Report the exception being handled as a bug: its traceback and a hint naming the
    command ``prog`` (``kinegrasp evaluate``); exit status 1."""
    traceback.print_exc()
    print(f"{prog}: {BUG_HINT}", file=sys.stderr)
    return 1


def run() -> NoReturn:
    """The ``kinegrasp`` console script and ``python -m kinegrasp_env.cli``: :func:`main`,
    then :func:`finish`."""
    finish(main())


def finish(code: int) -> NoReturn:
    """Leave the process with exit status ``code`` once its work is done: the exit handlers
    run (``atexit``: the kernel notice's summary, multiprocessing's clean-up), stdout and
    stderr are flushed, then the process ends without Python's finalization, which with the
    compiled kernels loaded tears down numba's LLVM objects, a noticeable delay after every
    command (timed by ``benchmarks/bench_coldstart.py``). Every file a command writes is
    closed by the command itself. While a thread other than the main one and daemons still runs, the
    ordinary exit waits for it instead."""
    if any(t is not threading.main_thread() and not t.daemon and t.is_alive()
           for t in threading.enumerate()):
        sys.exit(code)
    atexit._run_exitfuncs()  # what the interpreter's own exit would run first
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more can reach it
            pass
    os._exit(code)

