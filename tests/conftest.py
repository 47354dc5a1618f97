"""Shared fixtures."""

from __future__ import annotations

import functools
import io
import os
import shutil
import tempfile

import numpy as np
import pybullet
import pytest
from pybullet_utils.bullet_client import BulletClient

from kinegrasp_env.robot.default_robot import kuka_sdh, urdf_path
from kinegrasp_env.robot.kinematics import Kinematics

_CATALOG = tempfile.mkdtemp(prefix="kinegrasp_home_")


def pytest_configure(config):
    """For the whole test run, before any test module is collected: imported objects of the
    tests go to a folder of their own (the user's catalog is never read or written, and tests
    that list the catalog see the built-in objects only), and the kernels' compile notice of
    in-process commands goes to a sink. On a machine whose kernel cache is empty, the first
    command compiles the kernels and says so on stderr while it lasts; a test that runs a
    command in this process and checks its stderr line by line would find those lines there,
    in whichever test the compile falls (the notice's own tests give it a stream of their
    own; commands run as subprocesses keep theirs)."""
    from kinegrasp_env import kernel_notice

    os.environ["KINEGRASP_HOME"] = _CATALOG
    kernel_notice.install(io.StringIO())


def pytest_unconfigure(config):
    shutil.rmtree(_CATALOG, ignore_errors=True)


@functools.cache
def _default_kinematics() -> Kinematics:
    return Kinematics(kuka_sdh())


@pytest.fixture()
def model():
    """The default robot's model (built once per process: ``kuka_sdh`` is cached)."""
    return kuka_sdh()


@pytest.fixture()
def kin():
    """The default robot's kinematics, built once per process."""
    return _default_kinematics()


@pytest.fixture()
def bullet_robot():
    """(client, body id, joint index by name, link index by name) of the arm+hand."""
    client = BulletClient(connection_mode=pybullet.DIRECT)
    body = client.loadURDF(str(urdf_path()), useFixedBase=True)
    joints, links = {}, {}
    for j in range(client.getNumJoints(body)):
        info = client.getJointInfo(body, j)
        joints[info[1].decode()] = j
        links[info[12].decode()] = j
    yield client, body, joints, links
    client.disconnect()


@pytest.fixture()
def rng():
    return np.random.default_rng(12345)


#: The line closing a run whose browser tests were skipped for want of Chromium.
NO_CHROMIUM = ("browser tests skipped: chromium not on PATH; install it with apt-get install "
               "chromium")


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_terminal_summary(terminalreporter):
    """End the summary with :data:`NO_CHROMIUM` (and how many tests it skipped) when no
    Chromium is found and tests that need it were skipped: their skip reasons alone are easily
    missed among the other lines of the summary. Written after the short summary (``-ra``),
    just above the final counts."""
    yield
    from kinegrasp_env.toolkit.report.browser import find_chromium

    if find_chromium() is not None:
        return
    skipped = [report for report in terminalreporter.stats.get("skipped", [])
               if "chromium" in str(report.longrepr).lower()]
    if skipped:
        count = f"{len(skipped)} test" + ("s" if len(skipped) > 1 else "")
        terminalreporter.write_sep("!", f"{NO_CHROMIUM} ({count})", yellow=True, bold=True)
