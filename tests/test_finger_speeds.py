"""The closings' speed bounds (:meth:`~kinegrasp_env.closing.finger_paths.FingerPath.
speed_bounds`: the sum of the joints' own bounds, or a linkage's net turning) against the
motion they bound: a link's points moved along a finger's closing (every closing joint
turning, or only some), their speed measured by finite differences of the robot model's
forward kinematics, never above the link's bound by the joints that turn. Conservative
advancement is exact only while this holds: a step longer than a link's gap over its true
speed could carry it through the object. The xArm 6's gripper (pybullet_data) is a
four-bar linkage whose finger keeps its orientation: its finger link moves at exactly the
crank's speed, which the net bound gives (the sum of the joints' bounds is 3.4 times it)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pybullet_data
import pytest
import yaml

from kinegrasp_env.closing.finger_paths import finger_paths, tree_poses
from kinegrasp_env.closing.link_geometry import robot_link_geometry
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.description import load_description
from kinegrasp_env.robot.kinematics import Kinematics

XARM = Path(pybullet_data.getDataPath()) / "xarm" / "xarm6_with_gripper.urdf"


def xarm6(folder: Path):
    """The xArm 6 with its gripper as a user describes it (docs/guides/robot.md)."""
    path = folder / "xarm6.yaml"
    path.write_text(yaml.safe_dump({
        "name": "xarm6", "urdf": str(XARM), "arm_joints": [f"joint{i}" for i in range(1, 7)],
        "palm_link": "xarm_gripper_base_link", "hand_joints": ["drive_joint"],
        "close": {"drive_joint": 1}, "open": {"drive_joint": 0.0},
        "finger_links": ["left_finger", "right_finger"], "contact_model": "soft"}))
    return load_description(path)


def paths_of(description):
    """Every finger's :class:`~kinegrasp_env.closing.finger_paths.FingerPath`."""
    return finger_paths(description, robot_link_geometry(description),
                        Kinematics(description.model))


@pytest.mark.parametrize("robot", ["kuka_sdh", "panda", "xarm6"])
def test_no_point_of_a_finger_link_moves_faster_than_its_bound(robot, tmp_path):
    description = xarm6(tmp_path) if robot == "xarm6" else load_robot(robot)
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
                    bound = float(path.speed_bounds(turning)[k])
                    # 1e-6 relative: the finite difference's own error
                    assert speed <= bound * (1 + 1e-6) + 1e-9, (link, turning, speed, bound)
                    if bound > 0:
                        tightest = max(tightest, speed / bound)
                    checked += 1
    assert checked >= 40
    assert tightest > 0.3  # the bound is not vacuous: some point moves at a third of it
    if robot == "xarm6":  # the bar's speed is the crank's: the net bound is exact
        assert tightest > 1 - 1e-5


def test_a_linkage_bar_is_bounded_by_its_net_turning(tmp_path):
    """Which fingers take the net bound: the xArm's (its bar's joint turns against its
    crank's about a parallel axis), not the SDH's (its joints turn one way) or the Panda's
    (prismatic); and the net bound of the xArm's finger link with both joints turning is
    the crank's length (hand-derived: the distance between the two joints' axes, the
    URDF's left_finger_joint origin, 0.0355 m and 0.042 m across the axis: 0.05499 m)."""
    for name in ("kuka_sdh", "panda"):
        assert all(path.net is None for path in paths_of(load_robot(name)))
    for path in paths_of(xarm6(tmp_path)):
        np.testing.assert_array_equal(np.abs(path.net), [1.0, 1.0])
        assert path.net[0] == -path.net[1]
        k = path.links.index(path.links[-1])
        both = path.speed_bounds(np.array([True, True]))[k]
        assert both == pytest.approx(np.hypot(0.0355, 0.042), rel=1e-3)
        assert float(path.speeds[k].sum()) > 3 * both


def test_a_step_under_the_net_bound_stops_at_the_next_joint_limit(tmp_path):
    """The net bound holds for the joints turning now (:meth:`FingerPath.turning`): a joint
    that reaches its limit stops turning and the bar turns with the crank, so a step may
    not pass the next limit (hand-derived rooms for limits at t = 0.3 and 0.5); a stopped
    (held) joint does not turn; the sum of the joints' bounds holds for any subset, so a
    finger without the net bound has no such limit (the SDH's)."""
    path = paths_of(xarm6(tmp_path))[0]
    ends = np.array([[0.5, 0.3], [0.5, 0.3], [0.5, 0.3]])
    held = np.array([[np.inf, np.inf], [np.inf, np.inf], [np.inf, 0.1]])
    turning, room = path.turning(held, np.array([0.1, 0.4, 0.2]), np.zeros_like(ends), ends)
    np.testing.assert_array_equal(turning, [[True, True], [True, False], [True, False]])
    np.testing.assert_allclose(room, [0.2, 0.1, 0.3])
    crank_only = path.speed_bounds(turning[1])[-1]
    assert crank_only == pytest.approx(float(path.speeds[-1][0]))  # the whole finger turns
    sdh = paths_of(load_robot("kuka_sdh"))[0]
    turning, room = sdh.turning(np.full((1, 2), np.inf), np.array([0.4]), np.zeros((1, 2)),
                                ends[:1])
    assert turning.all() and np.isinf(room).all()


def _two_bar_finger(folder: Path):
    """A one-joint arm and a palm carrying a finger of two links turning about parallel x
    axes, the second following the first with multiplier -1 (a linkage's bar) but limited to
    [-3, -0.3]: at the pre-shape (0) it lies outside its limits, clipped to -0.3, and stands
    still until the first joint has turned 0.3 rad."""
    def box(name, y):
        return (f'<link name="{name}"><collision><origin xyz="0 {y} 0"/><geometry>'
                f'<box size="0.01 0.01 0.01"/></geometry></collision></link>')

    def revolute(name, parent, child, y, limits, mimic=""):
        return (f'<joint name="{name}" type="revolute"><origin xyz="0 {y} 0"/><parent '
                f'link="{parent}"/><child link="{child}"/><axis xyz="1 0 0"/><limit '
                f'lower="{limits[0]}" upper="{limits[1]}" effort="1" velocity="1"/>{mimic}'
                '</joint>')

    urdf = folder / "bars.urdf"
    urdf.write_text(
        '<robot name="bars"><link name="base"/><link name="arm"/>'
        '<link name="palm"><collision><geometry><box size="0.05 0.05 0.02"/></geometry>'
        '</collision></link>' + box("l0", 0.05) + box("l1", 0.2)
        + revolute("a1", "base", "arm", 0, (-3, 3)).replace('axis xyz="1 0 0"', 'axis xyz="0 0 1"')
        + '<joint name="palm_fix" type="fixed"><origin xyz="0 0 0.1"/><parent link="arm"/>'
        '<child link="palm"/></joint>' + revolute("l0j", "palm", "l0", 0, (-3, 3))
        + revolute("l1j", "l0", "l1", 0.05, (-3, -0.3),
                   '<mimic joint="l0j" multiplier="-1" offset="0"/>') + '</robot>')
    path = folder / "bars.yaml"
    path.write_text(yaml.safe_dump({
        "name": "bars", "urdf": str(urdf), "arm_joints": ["a1"], "palm_link": "palm",
        "hand_joints": ["l0j"], "close": {"l0j": 1}, "open": {"l0j": 0.0},
        "contact_model": "point"}))
    return load_description(path)


def test_a_joint_outside_its_limits_turns_only_once_within_them(tmp_path):
    """The net bound counts a joint as turning only between :meth:`FingerPath.limit_times`'
    start and end: the bar's joint, clipped at its limit for t < 0.3, does not turn against
    the crank then, and the bar turns with it at up to 0.2535 m/rad (finite differences
    along the closing's own clipped joint values), 5 times the net bound of both joints
    turning; a step may not pass t = 0.3 either. Counted as turning from t = 0 (the start
    ignored), the bound was 0.05 there and a closing stepped its link through a 1 mm
    slab."""
    description = _two_bar_finger(tmp_path)
    geometry = robot_link_geometry(description)
    path = paths_of(description)[0]
    assert path.net is not None
    v0 = np.zeros(2)
    starts, ends = path.limit_times(v0)
    np.testing.assert_allclose(starts, [0.0, 0.3])
    names, dt, worst = path.tree.model.actuated, 1e-7, 0.0
    for t in np.linspace(0.0, 0.6, 25):
        turning, room = path.turning(np.full(2, np.inf), t, starts, ends)
        if t < 0.3:
            assert turning.tolist() == [True, False] and room == pytest.approx(0.3 - t)
        bounds = path.speed_bounds(turning)
        poses = []
        for s in (t, t + dt):
            values = np.clip(v0 + path.rates * s, path.lower, path.upper)
            coordinates = {name: np.zeros(1) for name in names}
            coordinates.update({name: np.array([v]) for name, v in zip(path.joints, values,
                                                                      strict=True)})
            poses.append(tree_poses(path.tree, np.eye(4)[None], coordinates, path.links))
        for k, link in enumerate(path.links):
            points = geometry[link].extent_points
            a, b = (points @ p[link][0, :3, :3].T + p[link][0, :3, 3] for p in poses)
            speed = float(np.linalg.norm(b - a, axis=1).max()) / dt
            assert speed <= bounds[k] * (1 + 1e-6) + 1e-9, (t, link, speed, bounds[k])
            worst = max(worst, speed)
    assert worst > 0.25  # the bar turning with the crank was sampled
