"""The ``kinegrasp`` command: the parser and the entry point.

Every sub-command validates its input up front and reports a bad value in one line on
stderr with exit status 2 (no traceback); results go to stdout (``--json`` for machines),
progress bars to stderr. One module per command group: ``arms``, ``grasping``, ``toolkit``;
``common`` holds what they share.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence

from kinegrasp_env.cli import arms, grasping, toolkit
from kinegrasp_env.cli.common import CLIError


def build_parser() -> argparse.ArgumentParser:
    """The ``kinegrasp`` parser with every sub-command."""
    parser = argparse.ArgumentParser(
        prog="kinegrasp", description="Grasp quality under kinematic (joint-angle) noise.")
    sub = parser.add_subparsers(dest="command", required=True)
    for group in (arms, grasping, toolkit):
        group.add_commands(sub)
    return parser


_NEGATIVE_VALUE = re.compile(r"^-(\.?\d|inf|nan)", re.IGNORECASE)


def _glue_negative_values(argv: list[str]) -> list[str]:
    """Turn ``--q0 -0.5,1`` into ``--q0=-0.5,1`` (argparse would read -0.5,1 as an option)."""
    out: list[str] = []
    for token in argv:
        if (out and out[-1].startswith("--") and "=" not in out[-1]
                and _NEGATIVE_VALUE.match(token)):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(_glue_negative_values(argv))
    try:
        return int(args.func(args) or 0)
    except (CLIError, ValueError, FileNotFoundError, KeyError) as exc:
        message = exc.args[0] if exc.args else str(exc)
        print(f"kinegrasp {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("kinegrasp: interrupted", file=sys.stderr)
        return 130
