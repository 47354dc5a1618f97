"""The closings' speed bounds (:func:`~kinegrasp_env.closing.finger_paths.link_speeds`)
against the motion they bound: a link's points moved along a finger's closing (every
closing joint turning, or only some), their speed measured by finite differences of the
robot model's forward kinematics, never above the link's bound by the joints that turn.
Conservative advancement is exact only while this holds: a step longer than a link's gap
over its true speed could carry it through the object."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from kinegrasp_env.closing.finger_paths import finger_paths, tree_poses
from kinegrasp_env.closing.link_geometry import robot_link_geometry
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.kinematics import Kinematics


@pytest.mark.parametrize("robot", ["kuka_sdh", "panda"])
def test_no_point_of_a_finger_link_moves_faster_than_its_bound(robot):
    description = load_robot(robot)
    geometry = robot_link_geometry(description)
    rng = np.random.default_rng(3)
    dt, checked, tightest = 1e-6, 0, 0.0
    for path in finger_paths(description, geometry, Kinematics(description.model)):
        names = path.tree.model.actuated
        for turning in itertools.product([True, False], repeat=len(path.joints)):
            turning = np.array(turning)
            if not turning.any():
                continue
            # joint values across their ranges (each closing joint within its limits)
            base = {name: np.zeros(1) for name in names}
            for _ in range(20):
                for j, name in enumerate(path.joints):
                    base[name] = np.array([rng.uniform(path.lower[j], path.upper[j])])
                moved = dict(base)
                for j, name in enumerate(path.joints):
                    if turning[j]:
                        moved[name] = base[name] + path.rates[j] * dt
                before = tree_poses(path.tree, np.eye(4)[None], base, path.links)
                after = tree_poses(path.tree, np.eye(4)[None], moved, path.links)
                for k, link in enumerate(path.links):
                    points = geometry[link].extent_points
                    a = points @ before[link][0, :3, :3].T + before[link][0, :3, 3]
                    b = points @ after[link][0, :3, :3].T + after[link][0, :3, 3]
                    speed = float(np.linalg.norm(b - a, axis=1).max()) / dt
                    bound = float(path.speeds[k] @ turning)
                    # 1e-6 relative: the finite difference's own error
                    assert speed <= bound * (1 + 1e-6) + 1e-9, (link, turning, speed, bound)
                    if bound > 0:
                        tightest = max(tightest, speed / bound)
                    checked += 1
    assert checked >= 40
    assert tightest > 0.3  # the bound is not vacuous: some point moves at a third of it
