"""The grip's joint torques: contact forces in equilibrium, mapped to the finger joints.

The holding test's grip (:mod:`~kinegrasp_env.physics.protocol`, step 2) presses the object
with contact forces whose net wrench on it is zero (internal forces only), so releasing the
pin leaves the object where it was. From the contacts the closing ended with (one per
touching finger link, world frame, normals into the object), :func:`balanced_torques` solves
a linear programme over the friction cones' edges, one per friction fraction tried
(docs/conventions.md: f_j = n + mu' (cos t1 + sin t2), normal component 1):

* the contact forces f_c = sum_j lambda_cj e_cj, lambda >= 0, with friction mu' = s mu,
  s the smallest of :data:`FRICTION_FRACTIONS` for which a solution exists (forces as far
  inside the true cones as the grasp allows: a solution on the cones' boundary slips at the
  first disturbance);
* equilibrium: sum_c f_c = 0 and sum_c (p_c - c) x f_c = 0 (c: the object's centre of mass);
* joint torques tau = J^T f: joint j of a finger gets (a_j x (p_c - o_j)) . f_c from every
  contact c on its link or a link beyond it (a_j its axis, o_j a point on it: the velocity of
  p_c per unit joint speed is a_j x (p_c - o_j), so tau_j qdot_j is the power f_c . v_c);
  every flexion joint presses towards closing, within its torque limit: 0 <= tau_j <= limit_j;
  a spread joint (it carries every contact of its finger) either way: |tau_j| <= limit_j. With
  the spread joints in the grip each finger's force is set by its joints' torques; a spread
  joint held rigid instead leaves the force's component across the finger's flexion plane to
  the simulator's solver, which on a pinned object may put it at the friction limit, and the
  release then slides the object (shipped cube grasp 6 at sigma 0 in pybullet: 15.7 mm and a
  contact lost; with the spread joints in the grip, 0.15 mm);
* objective: the largest t with every contact's normal force >= t (the firmest grip).

Pure numpy and scipy (``linprog``, HiGHS); the simulators read contacts and joint frames and
apply the torques (:mod:`~kinegrasp_env.physics.pybullet_hold`,
:mod:`~kinegrasp_env.physics.mujoco_hold`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

from kinegrasp_env.quality.wrenches import friction_cone_edges

#: Friction fractions s tried in turn (the cones' mu' = s mu), smallest first.
FRICTION_FRACTIONS: tuple[float, ...] = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
#: Smallest normal force t (newtons) a solution must give every contact.
MIN_NORMAL_FORCE = 1e-3


@dataclass(frozen=True)
class GripContact:
    """One contact of the closing, world frame.

    Attributes:
        finger: 0-2; link: 0 proximal, 1 distal.
        point: (3,) metres; normal: (3,) unit, into the object.
    """

    finger: int
    link: int
    point: np.ndarray
    normal: np.ndarray


@dataclass(frozen=True)
class GripJoints:
    """The hand joints the grip sets, world frame, now (J of them).

    Attributes:
        axes: (J, 3) unit axes (a flexion joint's closing positive); origins: (J, 3) points
            on them, metres.
        fingers: (J,) the finger each joint moves; first_links: (J,) the joint carries its
            finger's contacts on links >= this (a flexion joint: its own link, 0 proximal,
            1 distal; a spread joint: 0, every link of its finger).
        lower, upper: (J,) the torque bounds, N m (a flexion joint presses: [0, limit]; a
            spread joint may turn either way: [-limit, limit]).
        tips: (J, 3) the tip of each joint's finger, metres.
    """

    axes: np.ndarray
    origins: np.ndarray
    fingers: np.ndarray
    first_links: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    tips: np.ndarray

    def carries(self, contacts: list[GripContact]) -> np.ndarray:
        """(J, k) bool: joint j carries contact c (it is on the joint's link or beyond)."""
        finger = np.array([c.finger for c in contacts])
        link = np.array([c.link for c in contacts])
        return ((finger[None, :] == self.fingers[:, None])
                & (link[None, :] >= self.first_links[:, None]))


@dataclass(frozen=True)
class GripTorques:
    """A solution of :func:`balanced_torques`.

    Attributes:
        torques: (J,) the grip joints' torques (:class:`GripJoints` order), N m.
        forces: (k, 3) the contact forces on the object, newtons, world frame.
        fraction: the friction fraction s used.
        min_normal: the smallest contact normal force, newtons.
    """

    torques: np.ndarray
    forces: np.ndarray
    fraction: float
    min_normal: float


def torque_rows(contacts: list[GripContact], joints: GripJoints,
                forces: np.ndarray) -> np.ndarray:
    """(J, k n) the joints' torques of forces (k, n, 3) (n per contact), world frame:
    tau_j = sum over the contacts c joint j carries of (a_j x (p_c - o_j)) . f."""
    k, n = forces.shape[:2]
    rows = np.zeros((joints.axes.shape[0], k * n))
    carries = joints.carries(contacts)
    for j, c in zip(*np.nonzero(carries), strict=True):
        lever = np.cross(joints.axes[j], contacts[c].point - joints.origins[j])
        rows[j, c * n:(c + 1) * n] = forces[c] @ lever
    return rows


def balanced_torques(contacts: list[GripContact], joints: GripJoints, center: np.ndarray,
                     friction: float, num_edges: int = 8) -> GripTorques | None:
    """The grip's joint torques (module docstring), or None when no contact force
    distribution in equilibrium exists (fewer than two fingers touching, or none within the
    cones at the full friction and the torque bounds).

    Args:
        contacts: the closing's contacts, world frame.
        joints: the grip joints (:func:`hand_joints`).
        center: (3,) the object's centre of mass, world frame.
        friction: Coulomb mu; num_edges: edges per cone.
    """
    if len({c.finger for c in contacts}) < 2:
        return None
    points = np.array([c.point for c in contacts])
    normals = np.array([c.normal for c in contacts])
    k, count = len(contacts), joints.axes.shape[0]
    for fraction in FRICTION_FRACTIONS:
        edges = friction_cone_edges(normals, fraction * friction, num_edges)  # (k, m, 3)
        flat = edges.reshape(-1, 3)
        arms = np.repeat(points - center, num_edges, axis=0)
        wrench = np.vstack([flat.T, np.cross(arms, flat).T])  # (6, k m)
        torque = torque_rows(contacts, joints, edges)  # (J, k m)
        size = k * num_edges
        cost = np.zeros(size + 1)
        cost[-1] = -1.0  # maximise t
        normal = np.zeros((k, size + 1))
        for c in range(k):
            normal[c, c * num_edges:(c + 1) * num_edges] = -1.0  # -(normal force) + t <= 0
        normal[:, -1] = 1.0
        upper = np.hstack([torque, np.zeros((count, 1))])
        rows = np.vstack([upper, -upper, normal])
        bounds = np.concatenate([joints.upper, -joints.lower, np.zeros(k)])
        result = linprog(cost, A_ub=rows, b_ub=bounds,
                         A_eq=np.hstack([wrench, np.zeros((6, 1))]), b_eq=np.zeros(6),
                         bounds=[(0, None)] * (size + 1), method="highs")
        if result.status == 0 and result.x[-1] >= MIN_NORMAL_FORCE:
            weights = result.x[:size]
            forces = (weights.reshape(k, num_edges, 1) * edges).sum(axis=1)
            return GripTorques(torque @ weights, forces, fraction, float(result.x[-1]))
    return None


def levers(points: np.ndarray, origins: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(k,) the distances (metres) of points (k, 3) from the axes through origins (k, 3)
    along unit axes (k, 3) (rows broadcast)."""
    arm = np.asarray(points, dtype=float) - origins
    radial = arm - axes * np.sum(arm * axes, axis=-1, keepdims=True)
    return np.linalg.norm(radial, axis=-1)


def tip_offsets(joints: GripJoints, advance: float) -> np.ndarray:
    """(J,) the joint angles (radians) that move each joint's fingertip by ``advance``
    metres: advance / (distance from the joint's axis to the tip: :func:`levers`)."""
    return advance / np.maximum(levers(joints.tips, joints.origins, joints.axes), 1e-6)


def loaded_joints(contacts: list[GripContact], joints: GripJoints) -> np.ndarray:
    """(J,) bool: the grip joints that carry a contact."""
    return joints.carries(contacts).any(axis=1)


@dataclass(frozen=True)
class SpringGrip:
    """The grip's joint control, the same in every simulator: each loaded grip joint j
    (:func:`loaded_joints`) a spring towards ``target_j`` = its stall angle + ``offset_j``
    (:func:`tip_offsets`, signed as the balanced torque: a spread joint's may be negative)
    of stiffness ``stiffness_j`` = ``|torque_j|`` / ``offset_j``, capped at its torque limit:
    tau_j = clip(stiffness_j (target_j - q_j), -limit_j, limit_j). At the stall angle it
    presses with the balanced torque; a finger the object gives way to follows it, pressing
    less, for up to ``offset_j``; one pushed back presses more. A joint that is not loaded is
    held where it stalled (the simulator's joint hold).

    Attributes:
        stall, targets, stiffness, limits: (J,) radians, radians, N m/rad, N m.
        loaded: (J,) bool.
    """

    stall: np.ndarray
    targets: np.ndarray
    stiffness: np.ndarray
    limits: np.ndarray
    loaded: np.ndarray

    @classmethod
    def of(cls, stall: np.ndarray, solution: GripTorques, offsets: np.ndarray,
           limits: np.ndarray, loaded: np.ndarray) -> SpringGrip:
        stall = np.asarray(stall, dtype=float)
        sign = np.where(solution.torques < 0, -1.0, 1.0)
        return cls(stall, stall + sign * offsets, np.abs(solution.torques) / offsets,
                   np.asarray(limits, dtype=float), np.asarray(loaded, dtype=bool))

    def torques(self, angles: np.ndarray) -> np.ndarray:
        """(J,) the loaded joints' torques at joint angles (J,), N m (0 where not loaded)."""
        tau = np.clip(self.stiffness * (self.targets - angles), -self.limits, self.limits)
        return np.where(self.loaded, tau, 0.0)


def spring_grip(contacts: list[GripContact], joints: GripJoints, object_pose: np.ndarray,
                center_of_mass: np.ndarray, stall: np.ndarray, friction: float,
                advance: float) -> SpringGrip | None:
    """The grip of a hand just closed on the object: the balanced torques of its contacts
    (:func:`balanced_torques`) as springs (:class:`SpringGrip`); None when no contact forces
    in equilibrium exist.

    Args:
        contacts: the closing's contacts, world frame.
        joints: the grip joints now (:func:`hand_joints`).
        object_pose: (4, 4) the object's pose; center_of_mass: (3,) object frame, metres.
        stall: (J,) the grip joints' angles now, radians.
        friction: Coulomb friction; advance: the tips' advance past the stall, metres.
    """
    center = object_pose[:3, :3] @ center_of_mass + object_pose[:3, 3]
    solution = balanced_torques(contacts, joints, center, friction)
    if solution is None:
        return None
    return SpringGrip.of(stall, solution, tip_offsets(joints, advance), joints.upper,
                         loaded_joints(contacts, joints))
