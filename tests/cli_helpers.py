"""Run the ``kinegrasp`` command in a subprocess (as a user would)."""

from __future__ import annotations

import subprocess
import sys

COMMAND = (sys.executable, "-m", "kinegrasp_env.cli")


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*COMMAND, *args], capture_output=True, text=True, check=False)


def start_cli(*args: str) -> subprocess.Popen:
    """The command running in the background; its stderr is a text pipe (read it line by
    line to follow the run), its stdout is discarded."""
    return subprocess.Popen([*COMMAND, *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
