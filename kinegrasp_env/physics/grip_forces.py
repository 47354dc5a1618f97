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
class GripTorques:
    """A solution of :func:`balanced_torques`.

    Attributes:
        torques: (6,) flexion joint torques (finger-major, proximal before distal), N m.
        forces: (k, 3) the contact forces on the object, newtons, world frame.
        fraction: the friction fraction s used.
        min_normal: the smallest contact normal force, newtons.
    """

    torques: np.ndarray
    forces: np.ndarray
    fraction: float
    min_normal: float


def torque_rows(contacts: list[GripContact], axes: np.ndarray, origins: np.ndarray,
                forces: np.ndarray) -> np.ndarray:
    """(6, n) the flexion torques of forces (k, n, 3) (n per contact), for joint axes (6, 3)
    (unit) through origins (6, 3), world frame: tau_j = sum (a_j x (p_c - o_j)) . f."""
    rows = np.zeros((6, forces.shape[0] * forces.shape[1]))
    n = forces.shape[1]
    for c, contact in enumerate(contacts):
        for link in range(contact.link + 1):
            j = 2 * contact.finger + link
            lever = np.cross(axes[j], contact.point - origins[j])
            rows[j, c * n:(c + 1) * n] = forces[c] @ lever
    return rows


def balanced_torques(contacts: list[GripContact], axes: np.ndarray, origins: np.ndarray,
                     center: np.ndarray, limits: np.ndarray, friction: float,
                     num_edges: int = 8) -> GripTorques | None:
    """The grip's joint torques (module docstring), or None when no contact force
    distribution in equilibrium exists (fewer than two contacts, or none within the cones
    at the full friction and the torque limits).

    Args:
        contacts: the closing's contacts, world frame.
        axes, origins: (6, 3) the flexion joints' unit axes (closing positive) and points on
            them, world frame, finger-major.
        center: (3,) the object's centre of mass, world frame.
        limits: (6,) the joints' torque limits, N m (> 0).
        friction: Coulomb mu; num_edges: edges per cone.
    """
    if len({c.finger for c in contacts}) < 2:
        return None
    points = np.array([c.point for c in contacts])
    normals = np.array([c.normal for c in contacts])
    k = len(contacts)
    for fraction in FRICTION_FRACTIONS:
        edges = friction_cone_edges(normals, fraction * friction, num_edges)  # (k, m, 3)
        flat = edges.reshape(-1, 3)
        arms = np.repeat(points - center, num_edges, axis=0)
        wrench = np.vstack([flat.T, np.cross(arms, flat).T])  # (6, k m)
        torque = torque_rows(contacts, axes, origins, edges)  # (6, k m)
        size = k * num_edges
        cost = np.zeros(size + 1)
        cost[-1] = -1.0  # maximise t
        normal = np.zeros((k, size + 1))
        for c in range(k):
            normal[c, c * num_edges:(c + 1) * num_edges] = -1.0  # -(normal force) + t <= 0
        normal[:, -1] = 1.0
        upper = np.hstack([torque, np.zeros((6, 1))])
        rows = np.vstack([upper, -upper, normal])
        bounds = np.concatenate([limits, np.zeros(6), np.zeros(k)])
        result = linprog(cost, A_ub=rows, b_ub=bounds,
                         A_eq=np.hstack([wrench, np.zeros((6, 1))]), b_eq=np.zeros(6),
                         bounds=[(0, None)] * (size + 1), method="highs")
        if result.status == 0 and result.x[-1] >= MIN_NORMAL_FORCE:
            weights = result.x[:size]
            forces = (weights.reshape(k, num_edges, 1) * edges).sum(axis=1)
            return GripTorques(torque @ weights, forces, fraction, float(result.x[-1]))
    return None


def tip_offsets(axes: np.ndarray, origins: np.ndarray, tips: np.ndarray,
                advance: float) -> np.ndarray:
    """(6,) the joint angles (radians) that move each finger's tip by ``advance`` metres:
    advance / (distance from the joint's axis to its finger's tip); tips (3, 3) world."""
    out = np.empty(6)
    for j in range(6):
        arm = tips[j // 2] - origins[j]
        radial = arm - axes[j] * (arm @ axes[j])
        out[j] = advance / max(float(np.linalg.norm(radial)), 1e-6)
    return out


def loaded_joints(contacts: list[GripContact]) -> np.ndarray:
    """(6,) bool: the flexion joints with a contact on their link or a link beyond."""
    out = np.zeros(6, dtype=bool)
    for c in contacts:
        out[2 * c.finger:2 * c.finger + c.link + 1] = True
    return out


@dataclass(frozen=True)
class SpringGrip:
    """The grip's joint control, the same in every simulator: each loaded flexion joint j
    (:func:`loaded_joints`) a spring towards ``target_j`` = its stall angle + ``offset_j``
    (:func:`tip_offsets`) of stiffness ``stiffness_j`` = ``torque_j`` / ``offset_j``, capped
    at its torque limit: tau_j = clip(stiffness_j (target_j - q_j), -limit_j, limit_j). At
    the stall angle it presses with the balanced torque; a finger the object gives way to
    follows it, pressing less, for up to ``offset_j``; one pushed back presses more. A joint
    that is not loaded is held where it stalled (the simulator's joint hold).

    Attributes:
        stall, targets, stiffness, limits: (6,) radians, radians, N m/rad, N m.
        loaded: (6,) bool.
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
        return cls(stall, stall + offsets, solution.torques / offsets,
                   np.asarray(limits, dtype=float), np.asarray(loaded, dtype=bool))

    def torques(self, angles: np.ndarray) -> np.ndarray:
        """(6,) the loaded joints' torques at joint angles (6,), N m (0 where not loaded)."""
        tau = np.clip(self.stiffness * (self.targets - angles), -self.limits, self.limits)
        return np.where(self.loaded, tau, 0.0)


def spring_grip(contacts: list[GripContact], axes: np.ndarray, origins: np.ndarray,
                tips: np.ndarray, object_pose: np.ndarray, center_of_mass: np.ndarray,
                stall: np.ndarray, torque_limits: tuple[float, float], friction: float,
                advance: float) -> SpringGrip | None:
    """The grip of a hand just closed on the object: the balanced torques of its contacts
    (:func:`balanced_torques`) as springs (:class:`SpringGrip`); None when no contact forces
    in equilibrium exist.

    Args:
        contacts: the closing's contacts, world frame.
        axes, origins: (6, 3) the flexion joints' unit axes (closing positive) and points on
            them, world frame; tips: (3, 3) the fingertips, world frame.
        object_pose: (4, 4) the object's pose; center_of_mass: (3,) object frame, metres.
        stall: (6,) the flexion joints' angles now, radians.
        torque_limits: (proximal, distal) the flexion joints' torque limits, N m.
        friction: Coulomb friction; advance: the tips' advance past the stall, metres.
    """
    center = object_pose[:3, :3] @ center_of_mass + object_pose[:3, 3]
    limits = np.array(list(torque_limits) * 3)
    solution = balanced_torques(contacts, axes, origins, center, limits, friction)
    if solution is None:
        return None
    offsets = tip_offsets(axes, origins, tips, advance)
    return SpringGrip.of(stall, solution, offsets, limits, loaded_joints(contacts))
