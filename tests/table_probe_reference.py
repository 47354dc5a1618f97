"""The tests' reference for the table test: whether the default robot is in the support
table, for a batch of configurations, from pybullet's own closest points.

A :class:`TableProbe` holds a pybullet world of its own (one ``BulletClient``) with the arm
(the composed arm+hand URDF, of which only the arm's links are asked about), the hand (the
SDH URDF on its own, placed at the hand root as the engines place it, so that a palm-mount
error moves it) and the table box (:class:`~kinegrasp_env.world.support.SupportTable`). A
configuration is *in the table* when pybullet reports a closest-point pair at distance <= 0
between the box and any arm link (base included) or hand link, every collision margin set to
zero, so the test is the exact intersection of the collision shapes (GJK on the links'
convex meshes, capsules and cylinders). Draws whose every link is farther from the box than
the ball holding its collision geometry (:func:`link_radii`, placed by forward kinematics)
are answered without pybullet (cheap: forward kinematics and a distance per link; most
draws of a grasp well above the table).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh

from kinegrasp_env.assets import asset_path
from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.robot.default_robot import ARM_JOINTS, default_hand_mount, kuka_sdh, urdf_path
from kinegrasp_env.robot.kinematics import Kinematics, rigid_inverse
from kinegrasp_env.robot.model import rpy_to_matrix
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sim import BulletWorld, load_hand, matrix_to_pose
from kinegrasp_env.world.table_body import table_body


@lru_cache(maxsize=2)
def link_radii(urdf: Path) -> dict[str, float]:
    """Per link of ``urdf``, the radius (metres) of a ball about the link frame's origin that
    holds all its collision geometry: the farthest mesh vertex, or for a capsule / cylinder /
    sphere / box the distance of its centre plus its own circumradius."""
    radii: dict[str, float] = {}
    for link in ET.parse(urdf).getroot().iter("link"):
        for col in link.iter("collision"):
            origin = col.find("origin")
            rot, offset = np.eye(3), np.zeros(3)
            if origin is not None:
                rot = rpy_to_matrix(*map(float, origin.get("rpy", "0 0 0").split()))
                offset = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
            shape = col.find("geometry")[0]
            radii[link.get("name")] = max(radii.get(link.get("name"), 0.0),
                                          shape_radius(shape, rot, offset, Path(urdf).parent))
    return radii


def shape_radius(shape, rot: np.ndarray, offset: np.ndarray, folder: Path) -> float:
    """The farthest point of one URDF collision geometry from its link frame's origin (an
    upper bound for primitives), metres."""
    if shape.tag == "mesh":
        vertices = trimesh.load(folder / shape.get("filename"), force="mesh").vertices
        return float(np.linalg.norm(vertices @ rot.T + offset, axis=1).max())
    centre = float(np.linalg.norm(offset))
    if shape.tag in ("capsule", "cylinder"):
        r, half = float(shape.get("radius")), 0.5 * float(shape.get("length"))
        return centre + (half + r if shape.tag == "capsule" else float(np.hypot(half, r)))
    if shape.tag == "sphere":
        return centre + float(shape.get("radius"))
    return centre + 0.5 * float(np.linalg.norm([float(v) for v in shape.get("size").split()]))


class TableProbe(BulletWorld):
    """The arm, the hand and the table of ``obj`` (which must have a table).

    Args:
        obj: the object; its ``table`` and ``pose`` place the box.

    Raises:
        ValueError: the object has no table.
    """

    def __init__(self, obj: GraspObject) -> None:
        if obj.table is None:
            raise ValueError(f"object {obj.name!r} has no support table")
        super().__init__()
        bullet = self.bullet
        self.model = kuka_sdh()
        self.kin = Kinematics(self.model)
        with quiet_c_output():
            arm = bullet.loadURDF(str(urdf_path()), useFixedBase=True)
        self.bodies["arm"] = arm
        self.arm_joints = {bullet.getJointInfo(arm, j)[1].decode(): j
                           for j in range(bullet.getNumJoints(arm))}
        self.arm_links = [-1, *(self.arm_joints[name] for name in ARM_JOINTS)]
        for link in range(-1, bullet.getNumJoints(arm)):
            bullet.changeDynamics(arm, link, collisionMargin=0.0)
        self.bodies["hand"], self.hand_joints, _ = load_hand(bullet)
        self.bodies["table"] = table_body(bullet, obj)
        self._arm_moved = False
        box_pose, self.half = obj.table.box(obj.pose)
        self.box_inverse = np.linalg.inv(box_pose)
        # the links screened by forward kinematics before pybullet is asked (names as in the
        # composed robot, whose hand links the hand body shares) and their balls' radii
        arm_radii = link_radii(urdf_path())
        hand_radii = link_radii(asset_path("robots", "sdh_hand.urdf"))
        self.arm_names = [name for name in (self.model.base_link, *(
            bullet.getJointInfo(arm, j)[12].decode() for j in self.arm_links[1:]))
            if name in arm_radii]
        self.hand_names = list(hand_radii)
        self.radii = np.array([arm_radii[name] for name in self.arm_names]
                              + [hand_radii[name] for name in self.hand_names])

    def hits(self, q: np.ndarray, roots: np.ndarray | None = None,
             shifts: np.ndarray | None = None) -> np.ndarray:
        """(n,) bool: configuration i (q (n, 14), radians) puts an arm or hand link in the
        table.

        Args:
            q: arm joints and hand DOF (the hand's joints are set from q[:, 7:]).
            roots: (n, 4, 4) world poses of the hand root (default: the flange pose of q).
            shifts: (n, 4, 4) rigid moves of the whole robot (default none; see
                :func:`arm_shift`); ``roots`` are taken
                as already moved.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if roots is None:
            roots = self.kin.pose(q, default_hand_mount())
            if shifts is not None:
                roots = shifts @ roots
        values = self.model.expand(q)
        hand_names = [name for name in self.hand_joints if name in values]
        out = np.zeros(q.shape[0], dtype=bool)
        for i in np.flatnonzero(self.maybe_hits(q, roots, shifts)):
            self.place(i, values, hand_names, roots[i], None if shifts is None else shifts[i])
            out[i] = self.touching()
        return out

    def maybe_hits(self, q: np.ndarray, roots: np.ndarray, shifts: np.ndarray | None
                   ) -> np.ndarray:
        """(n,) bool, False only where no link can reach the table: every link's bounding
        ball (:func:`link_radii`, about the link frame's origin from forward kinematics) is
        clear of the box; pybullet is asked about the others only."""
        poses = self.kin.forward(q, [default_hand_mount(), *self.arm_names, *self.hand_names])
        arm = np.stack([poses[name][:, :3, 3] for name in self.arm_names], axis=1)
        if shifts is not None:
            arm = arm @ np.swapaxes(shifts[:, :3, :3], 1, 2) + shifts[:, None, :3, 3]
        # the hand body's links where the engine puts it: root . flange^-1 . link
        to_root = roots @ np.linalg.inv(poses[default_hand_mount()])
        hand = np.stack([(to_root @ poses[name])[:, :3, 3] for name in self.hand_names], axis=1)
        points = np.concatenate([arm, hand], axis=1)  # (n, L, 3) link origins, world
        local = points @ self.box_inverse[:3, :3].T + self.box_inverse[:3, 3]
        outside = np.linalg.norm(np.maximum(np.abs(local) - self.half, 0.0), axis=2)
        return np.any(outside <= self.radii + 1e-6, axis=1)

    def place(self, i: int, values: dict[str, np.ndarray], hand_names: list[str],
              root: np.ndarray, shift: np.ndarray | None) -> None:
        """Put draw ``i`` in the probe's world: the arm (shifted by ``shift``, (4, 4), if
        given), its joints from ``values`` (name -> (N,) radians), the hand at ``root`` (4, 4)."""
        bullet = self.bullet
        arm, hand = self.bodies["arm"], self.bodies["hand"]
        if shift is not None or self._arm_moved:
            base = np.eye(4) if shift is None else shift
            bullet.resetBasePositionAndOrientation(arm, *matrix_to_pose(base))
            self._arm_moved = shift is not None
        for name in ARM_JOINTS:
            bullet.resetJointState(arm, self.arm_joints[name], float(values[name][i]))
        bullet.resetBasePositionAndOrientation(hand, *matrix_to_pose(root))
        for name in hand_names:
            bullet.resetJointState(hand, self.hand_joints[name], float(values[name][i]))

    def touching(self) -> bool:
        """Whether the placed robot touches the table (pybullet's closest points at 0 m)."""
        bullet = self.bullet
        table = self.bodies["table"]
        if bullet.getClosestPoints(self.bodies["hand"], table, 0.0):
            return True
        arm = self.bodies["arm"]
        return any(bullet.getClosestPoints(arm, table, 0.0, linkIndexA=link)
                   for link in self.arm_links)


def arm_shift(object_pose: np.ndarray, object_offset: np.ndarray) -> np.ndarray:
    """(n, 4, 4) M = W_O D^-1 W_O^-1: the rigid move of the whole robot that, the object left
    at its believed pose W_O (4, 4), puts the robot where it truly is relative to the object
    (object errors D (n, 4, 4): :mod:`kinegrasp_env.closing.hand_errors`)."""
    return object_pose @ rigid_inverse(object_offset) @ rigid_inverse(object_pose)
