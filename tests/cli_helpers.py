"""Run the ``kinegrasp`` command in a subprocess (as a user would)."""

from __future__ import annotations

import subprocess
import sys


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "kinegrasp_env.cli", *args],
                          capture_output=True, text=True, check=False)
