"""Silence C-level writes to stdout/stderr (pybullet prints its build time and "argv[0]=")."""

from __future__ import annotations

import contextlib
import os
import sys


@contextlib.contextmanager
def quiet_c_output():
    """Redirect file descriptors 1 and 2 to /dev/null inside the block."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError):
            pass
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no real descriptors (embedded interpreters): nothing to silence
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)
