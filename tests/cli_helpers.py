"""Run the ``kinegrasp`` command in a subprocess (as a user would), or in-process."""

from __future__ import annotations

import signal
import subprocess
import sys

COMMAND = (sys.executable, "-m", "kinegrasp_env.cli")


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*COMMAND, *args], capture_output=True, text=True, check=False)


def _as_in_a_terminal() -> None:
    """A command typed at a terminal takes Ctrl-C; a test runner's worker, or a job started
    in the background, may run with SIGINT ignored, which a child inherits."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_cli(*args: str) -> subprocess.Popen:
    """The command running in the background, as if typed at a terminal (SIGINT stops it);
    its stderr is a text pipe (read it line by line to follow the run), its stdout is
    discarded."""
    return subprocess.Popen([*COMMAND, *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_as_in_a_terminal)


def run_in_process(capsys, *argv: str) -> str:
    """``kinegrasp ARGV`` in this process; its stdout (exit status 0 asserted, stderr shown
    when not)."""
    from kinegrasp_env.cli import main

    capsys.readouterr()
    status = main(list(argv))
    out, err = capsys.readouterr()
    assert status == 0, err
    return out
