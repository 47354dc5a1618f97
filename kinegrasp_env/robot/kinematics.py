"""Batched forward kinematics and geometric Jacobians of a :class:`RobotModel`.

All functions are vectorized over a leading batch axis: a configuration array ``q`` of shape
(n, dof) gives poses of shape (n, 4, 4) (homogeneous transforms, world = robot base frame,
metres) and Jacobians of shape (n, 6, dof). A single configuration (dof,) is accepted and
treated as n = 1.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from kinegrasp_env.robot.fk_kernel import PRISMATIC, ROTATING, forward_pass, joint_angles
from kinegrasp_env.robot.model import RobotModel
from kinegrasp_env.robot.pose_rules import (
    add_joint_columns,
    elbow_angles,
    pose_errors,
    rotation_logs,
)


def axis_angle_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations about a fixed unit ``axis`` (3,) by ``angle`` (n,) radians -> (n, 3, 3)."""
    angle = np.asarray(angle, dtype=float)
    x, y, z = axis
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    out = np.empty((*angle.shape, 3, 3))
    out[..., 0, 0] = c + x * x * t
    out[..., 0, 1] = x * y * t - z * s
    out[..., 0, 2] = x * z * t + y * s
    out[..., 1, 0] = y * x * t + z * s
    out[..., 1, 1] = c + y * y * t
    out[..., 1, 2] = y * z * t - x * s
    out[..., 2, 0] = z * x * t - y * s
    out[..., 2, 1] = z * y * t + x * s
    out[..., 2, 2] = c + z * z * t
    return out


def rotation_log(rot: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) (axis * angle, radians) of rotations (..., 3, 3)
    (:func:`kinegrasp_env.robot.pose_rules.rotation_log_into` on each)."""
    rot = np.asarray(rot, dtype=float)
    out = np.empty((*rot.shape[:-2], 3))
    rotation_logs(np.ascontiguousarray(rot.reshape(-1, 3, 3)), out.reshape(-1, 3))
    return out


def rigid_inverse(transform: np.ndarray) -> np.ndarray:
    """Inverses (..., 4, 4) of rigid transforms (..., 4, 4): [R^T, -R^T t]."""
    rot_t = np.swapaxes(transform[..., :3, :3], -1, -2)
    out = np.zeros_like(transform)
    out[..., :3, :3] = rot_t
    out[..., :3, 3] = -(rot_t @ transform[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def pose_error(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Twist-like error (..., 6) of poses current against target (..., 4, 4), broadcast:
    target position - current, then rotation vector of R_target R_current^T (world frame;
    :func:`kinegrasp_env.robot.pose_rules.pose_error_into` on each)."""
    current, target = np.broadcast_arrays(np.asarray(current, dtype=float),
                                          np.asarray(target, dtype=float))
    out = np.empty((*current.shape[:-2], 6))
    pose_errors(np.ascontiguousarray(current.reshape(-1, 4, 4)),
                np.ascontiguousarray(target.reshape(-1, 4, 4)), out.reshape(-1, 6))
    return out


def _as_batch(q: np.ndarray, dof: int) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        q = q[None]
    if q.ndim != 2 or q.shape[1] != dof:
        raise ValueError(f"configuration must have shape (n, {dof}) or ({dof},), got {q.shape}")
    return q


def _axis_frame(axis: np.ndarray) -> np.ndarray:
    """A rotation Q (3, 3) with Q e_z = axis (exactly a signed permutation for x/y/z axes)."""
    axis = np.asarray(axis, dtype=float)
    for k, perm in ((2, np.eye(3)), (0, np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0]])),
                    (1, np.array([[0.0, 1, 0], [0, 0, 1], [1, 0, 0]]))):
        unit = np.zeros(3)
        unit[k] = 1.0
        if np.allclose(axis, unit, atol=0, rtol=0):
            return perm
        if np.allclose(axis, -unit, atol=0, rtol=0):
            return perm @ np.diag([1.0, -1.0, -1.0])
    helper = np.eye(3)[np.argmin(np.abs(axis))]
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(axis, x), axis], axis=1)


SNAP_TOL = 1e-10


def snap_rotation(rot: np.ndarray) -> np.ndarray:
    """Round entries within SNAP_TOL of 0 or +-1 to exactly that value.

    URDF files write right angles to ~11 digits (1.57079632679), leaving 1e-11-sized
    entries that would otherwise cost full multiplications; the change is below 1e-10 rad.
    """
    out = rot.copy()
    for target in (0.0, 1.0, -1.0):
        out[np.abs(out - target) < SNAP_TOL] = target
    return out


class Kinematics:
    """Batched FK / Jacobians for one :class:`RobotModel`.

    Forward kinematics run as one compiled pass (:mod:`kinegrasp_env.robot.fk_kernel`);
    constant rotations are snapped (:func:`snap_rotation`) so that permutation-like ones cost
    nothing. Poses are returned as C-contiguous (n, 4, 4) views of one (L, n, 4, 4) buffer.

    Args:
        model: the robot.
    """

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self._drivers = model.drivers()
        self._parent_joint = {j.child: j for j in model.joints}
        self._links = model.links
        self._needed: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray]] = {}
        self._slot = {model.base_link: 0} | {j.child: i + 1 for i, j in enumerate(model.joints)}
        count = len(model.joints)
        kind = np.zeros(count, dtype=np.int64)
        const = np.zeros((count, 3, 3))
        back = np.tile(np.eye(3), (count, 1, 1))
        has_back = np.zeros(count, dtype=bool)
        slide = np.zeros((count, 3))
        for i, joint in enumerate(model.joints):
            # per joint: the constant rotation R_origin (snapped) @ Q, where Q e_z = the axis,
            # then Q^T after the rotation about z (unless Q is the identity)
            rot = snap_rotation(joint.origin[:3, :3])
            if joint.kind == "prismatic":
                kind[i] = PRISMATIC
                slide[i] = rot @ joint.axis
            elif joint.movable:
                kind[i] = ROTATING
                q_frame = _axis_frame(joint.axis)
                if not np.array_equal(q_frame, np.eye(3)):
                    back[i], has_back[i] = q_frame.T, True
                rot = rot @ q_frame
            const[i] = rot
        self._driven = self._driver_table()
        self._pass = (np.array([self._slot[j.parent] for j in model.joints], dtype=np.int64),
                      kind, const, np.array([j.origin[:3, 3] for j in model.joints], dtype=float)
                      .reshape(count, 3), back, has_back, slide)

    def _driver_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per joint (J,): the actuated index that drives it, its multiplier and offset
        (0, 1, 0 for a fixed joint): :func:`~kinegrasp_env.robot.fk_kernel.joint_angles`'
        table."""
        index = np.zeros(len(self.model.joints), dtype=np.int64)
        mult, offset = np.ones(len(self.model.joints)), np.zeros(len(self.model.joints))
        for i, joint in enumerate(self.model.joints):
            if joint.movable:
                index[i], mult[i], offset[i] = self._drivers[joint.name]
        return index, mult, offset

    def _chains(self, wanted: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
        """((J,) bool mask of the joints whose child frames lead to the ``wanted`` links,
        (W,) int64 the wanted links' slots) (KeyError for unknown links)."""
        needed = self._needed.get(wanted)
        if needed is None:
            unknown = set(wanted) - set(self._links)
            if unknown:
                raise KeyError(f"unknown links {sorted(unknown)}")
            found: set[str] = set()
            for link in wanted:  # only compute the chains leading to the requested links
                while link in self._parent_joint and link not in found:
                    found.add(link)
                    link = self._parent_joint[link].parent
            needed = self._needed[wanted] = (
                np.array([j.child in found for j in self.model.joints], dtype=bool),
                np.array([self._slot[link] for link in wanted], dtype=np.int64))
        return needed

    def _angles(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per joint and draw (J, n): cos and sin of the rotating joints' angles, values of
        the prismatic ones (zeros elsewhere), from configurations q (n, dof)
        (:func:`~kinegrasp_env.robot.fk_kernel.joint_angles`)."""
        count, n = len(self.model.joints), q.shape[0]
        cos, sin, shift = np.zeros((count, n)), np.zeros((count, n)), np.zeros((count, n))
        joint_angles(np.ascontiguousarray(q), self._pass[1], *self._driven, cos, sin, shift)
        return cos, sin, shift

    def forward(self, q: np.ndarray, links: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        """Poses of links in the world (base) frame (one compiled pass over draws and joints:
        :func:`kinegrasp_env.robot.fk_kernel.forward_pass`).

        Args:
            q: (n, dof) or (dof,) actuated configurations (radians / metres).
            links: link names to return (default: all links).

        Returns:
            dict link name -> (n, 4, 4) transforms (C-contiguous views of one buffer).
        """
        q = _as_batch(q, self.model.dof)
        wanted = tuple(dict.fromkeys(self._links if links is None else links))
        mask, wanted_slots = self._chains(wanted)
        slots = len(self.model.joints) + 1
        out = np.empty((len(wanted), q.shape[0], 4, 4))
        forward_pass(*self._pass, mask, *self._angles(q), wanted_slots,
                     np.empty((slots, 3, 3)), np.empty((slots, 3)), np.empty((slots, 3, 3)), out)
        return {link: out[i] for i, link in enumerate(wanted)}

    def pose(self, q: np.ndarray, link: str) -> np.ndarray:
        """(n, 4, 4) pose of one link."""
        return self.forward(q, [link])[link]

    def chain(self, link: str) -> list:
        """The joints from the base to ``link``, base first."""
        chain = []
        current = link
        while current in self._parent_joint:
            joint = self._parent_joint[current]
            chain.append(joint)
            current = joint.parent
        chain.reverse()
        return chain

    def joint_frames(self, q: np.ndarray, link: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Movable joints on the chain to ``link``: (name, origin (n, 3), world axis (n, 3))."""
        chain = self.chain(link)
        return self._joint_frames(self.forward(q, [j.child for j in chain]), chain)

    def _joint_frames(self, poses: dict[str, np.ndarray], chain: list
                      ) -> list[tuple[str, np.ndarray, np.ndarray]]:
        out = []
        for joint in chain:
            if joint.movable:
                frame = poses[joint.child]  # child frame = joint frame (URDF convention)
                out.append((joint.name, frame[:, :3, 3], frame[:, :3, :3] @ joint.axis))
        return out

    def jacobian_links(self, link: str) -> list[str]:
        """The links whose poses :meth:`jacobian_at` needs for ``link``'s Jacobian."""
        return list(dict.fromkeys([link] + [j.child for j in self.chain(link)]))

    def jacobian(self, q: np.ndarray, link: str, point: np.ndarray | None = None) -> np.ndarray:
        """Geometric (spatial) Jacobian of a link frame, world frame.

        Args:
            q: (n, dof) or (dof,) configurations.
            link: link whose origin (or ``point``) is tracked.
            point: optional (3,) point in the link frame (metres); default its origin.

        Returns:
            (n, 6, dof): rows 0-2 map joint rates to the linear velocity of the point,
            rows 3-5 to the angular velocity of the link.
        """
        q = _as_batch(q, self.model.dof)
        return self.jacobian_at(self.forward(q, self.jacobian_links(link)), link, point)

    def jacobian_at(self, poses: dict[str, np.ndarray], link: str,
                    point: np.ndarray | None = None) -> np.ndarray:
        """:meth:`jacobian` from link poses (n, 4, 4) already computed by :meth:`forward`
        (at least those of :meth:`jacobian_links`); the same numbers."""
        pose = poses[link]
        target = pose[:, :3, 3] if point is None else pose[:, :3, :3] @ point + pose[:, :3, 3]
        jac = np.zeros((pose.shape[0], 6, self.model.dof))
        for name, origin, axis in self._joint_frames(poses, self.chain(link)):
            index, mult, _ = self._drivers[name]
            add_joint_columns(jac, index, float(mult), self.model.joint(name).kind != "prismatic",
                              origin, axis, target)
        return jac

    def arm_angle(self, q: np.ndarray, links: tuple[str, str, str]) -> np.ndarray:
        """Elbow (arm) angle psi (n,) radians of an S-R-S arm whose shoulder, elbow and wrist
        links are ``links`` (a description's ``arm_angle_links``).

        psi is the angle of the elbow about the shoulder-wrist line, measured from the
        plane through that line and the world z axis (the plane the elbow lies in when
        joint 3 is zero), positive by the right-hand rule about shoulder -> wrist.
        Undefined (returned as 0) when the elbow lies on the shoulder-wrist line.
        """
        poses = self.forward(q, links)
        return elbow_angle(*(poses[name][:, :3, 3] for name in links))


def elbow_angle(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray) -> np.ndarray:
    """Arm angle (...,) from shoulder, elbow and wrist centres (..., 3), broadcast; see
    ``arm_angle`` (:func:`kinegrasp_env.robot.pose_rules.elbow_angle_of` on each row)."""
    shoulder, elbow, wrist = np.broadcast_arrays(*(np.asarray(a, dtype=float)
                                                   for a in (shoulder, elbow, wrist)))
    out = np.empty(shoulder.shape[:-1])
    elbow_angles(shoulder.reshape(-1, 3), elbow.reshape(-1, 3), wrist.reshape(-1, 3),
                 out.reshape(-1))
    return out
