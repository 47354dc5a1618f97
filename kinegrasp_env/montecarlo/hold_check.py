"""The static hold check of a description robot's closings (:mod:`~kinegrasp_env.quality.
static_hold`): can the closed hand carry the object's weight in each of the holding test's six
gravity directions, the lift's acceleration added to the downward one, with contact forces in
the contact model's cones and joint efforts within the limits the holding test gives its
motors?

* **Loads**: the object's mass (:attr:`~kinegrasp_env.world.objects.GraspObject.mass`) times
  the protocol's gravity along +-x, +-y, +-z of the world; the -z one adds the peak
  acceleration of the protocol's lift (:func:`~kinegrasp_env.physics.motion.
  peak_lift_acceleration`).
* **Limits** (:func:`~kinegrasp_env.physics.hand_motors.motor_efforts`: the URDF's efforts
  unless the description overrides them): each finger's first closing joint is the holding
  test's closing motor, which presses towards closing with at most its effort (0 <= tau <=
  effort, tau in the closing direction); the finger's other closing joints are position
  motors there and hold either way (|tau| <= effort).
* **Joint efforts of a contact force**: joint j of the finger, in the object frame at the
  draw's final joint values, with axis a and a point o on it: a prismatic joint takes a . f,
  a revolute one a . (tau_c + (c - o) x f) for a primitive wrench (f, tau_c) about the centre
  of mass c (its moment about the axis), times the joint's closing direction.

Draws that end ``start_collision`` or ``missed`` do not hold.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.finger_paths import link_poses
from kinegrasp_env.physics.hand_motors import motor_efforts
from kinegrasp_env.physics.motion import peak_lift_acceleration
from kinegrasp_env.physics.protocol import GRAVITY_PHASES, HoldProtocol
from kinegrasp_env.quality.soft_contacts import (
    TORSION_PRIMITIVES,
    contact_wrenches,
    soft_torsions,
)
from kinegrasp_env.quality.static_hold import gravity_loads, static_hold
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.world.objects import GraspObject

__all__ = ["StaticHoldCheck", "load_accelerations"]


def load_accelerations(protocol: HoldProtocol) -> np.ndarray:
    """(6, 3) the accelerations of gravity the check loads the object with, world frame,
    m/s^2: the protocol's gravity phases in their order, the lift's peak acceleration added
    to the downward one (the lift runs under gravity along world -z)."""
    accelerations = protocol.gravity * np.array(list(GRAVITY_PHASES.values()))
    accelerations[list(GRAVITY_PHASES).index("gravity_-z"), 2] -= peak_lift_acceleration(
        protocol)
    return accelerations


class StaticHoldCheck:
    """The static hold check (module docstring) of one robot and object.

    Args:
        description: the robot; obj: the catalog object (its pose and mass).
        friction, num_edges: the friction cones; finger_radius: soft contacts' patch radius
            (metres).
        protocol: the holding test whose loads it checks (gravity, lift).
    """

    def __init__(self, description: RobotDescription, obj: GraspObject, *, friction: float,
                 num_edges: int, finger_radius: float,
                 protocol: HoldProtocol | None = None) -> None:
        protocol = protocol or HoldProtocol()
        self.description, self.obj = description, obj
        self.friction, self.num_edges, self.finger_radius = friction, num_edges, finger_radius
        self.kinematics = Kinematics(description.model)
        efforts = {m.joint: m.effort for m in motor_efforts(description)}
        self.joint_names = tuple(efforts)
        index = {name: i for i, name in enumerate(self.joint_names)}
        leaders = {finger.joints[0] for finger in description.fingers if finger.joints}
        self.upper = np.array([efforts[name] for name in self.joint_names])
        self.lower = np.array([0.0 if name in leaders else -efforts[name]
                               for name in self.joint_names])
        palm = len(self.kinematics.chain(description.palm_link))
        #: (finger, link) -> (chain from the palm, [(chain position, joint index, sign)])
        self.carriers: dict[tuple[int, int], tuple[list, list[tuple[int, int, float]]]] = {}
        for f, finger in enumerate(description.fingers):
            signs = dict(zip(finger.joints, finger.directions, strict=True))
            for k, link in enumerate(finger.links):
                chain = self.kinematics.chain(link)[palm:]
                carried = [(position, index[joint.name], float(signs[joint.name]))
                           for position, joint in enumerate(chain) if joint.name in signs]
                self.carriers[(f, k)] = (chain, carried)
        self.mass = obj.mass
        self.loads = gravity_loads(self.mass, load_accelerations(protocol), obj.pose[:3, :3])
        self.contact_model = description.quality_model
        self.per_contact = num_edges + (TORSION_PRIMITIVES
                                        if self.contact_model == "soft" else 0)

    def primitives(self, points: np.ndarray, normals: np.ndarray, present: np.ndarray,
                   soft: np.ndarray | None = None) -> np.ndarray:
        """(B, k P, 6) the contact model's primitive wrenches (newtons, newton metres about
        the centre of mass) of contacts (B, k, 3), zero rows where ``present`` (B, k) is
        False; ``soft`` (B, k): the patch model's soft contacts (the others point
        contacts, no torsion)."""
        filled = np.where(present[..., None], points, self.obj.center_of_mass)
        unit = np.where(present[..., None], normals, np.array([0.0, 0.0, 1.0]))
        torsion = (None if soft is None
                   else soft_torsions(soft, self.friction, self.finger_radius))
        w = contact_wrenches(filled, unit, contact_model=self.contact_model,
                             friction=self.friction, num_edges=self.num_edges,
                             torque_scale=1.0, center=tuple(map(float,
                                                                self.obj.center_of_mass)),
                             finger_radius=self.finger_radius, torsion=torsion)
        return w * np.repeat(present, self.per_contact, axis=1)[..., None]

    def torque_rows(self, palm: np.ndarray, values: dict[str, np.ndarray], finger: np.ndarray,
                    link: np.ndarray, primitives: np.ndarray) -> np.ndarray:
        """(B, J, k P) joint efforts per unit weight of each primitive (module docstring).

        Args:
            palm: (B, 4, 4) palm poses, object frame; values: joint name -> (B,) final values.
            finger, link: (B, k) each contact's finger and link index (-1: absent).
            primitives: (B, k P, 6) of :meth:`primitives`.
        """
        batch, slots = finger.shape
        per = self.per_contact
        rows = np.zeros((batch, len(self.joint_names), slots * per))
        center = self.obj.center_of_mass
        for (f, k), (chain, carried) in self.carriers.items():
            on = (finger == f) & (link == k)
            draws = np.flatnonzero(on.any(axis=1))
            if draws.size == 0 or not carried:
                continue
            sub = {name: v[draws] for name, v in values.items()}
            for position, joint_index, sign in carried:
                joint = chain[position]
                frame = link_poses(palm[draws], sub, chain[:position]) @ joint.origin
                axis = frame[:, :3, :3] @ joint.axis  # (m, 3) object frame
                lever = (np.zeros_like(axis) if joint.kind == "prismatic"
                         else np.cross(axis, center - frame[:, :3, 3]))
                for slot in range(slots):
                    hit = np.flatnonzero(on[draws, slot])
                    if hit.size == 0:
                        continue
                    w = primitives[draws[hit], slot * per:(slot + 1) * per]  # (h, P, 6)
                    if joint.kind == "prismatic":
                        effort = np.einsum("hpd,hd->hp", w[..., :3], axis[hit])
                    else:
                        effort = (np.einsum("hpd,hd->hp", w[..., 3:], axis[hit])
                                  + np.einsum("hpd,hd->hp", w[..., :3], lever[hit]))
                    rows[draws[hit], joint_index, slot * per:(slot + 1) * per] = sign * effort
        return rows

    def contact_terms(self, q: np.ndarray, values: dict[str, np.ndarray], points: np.ndarray,
                      normals: np.ndarray, finger: np.ndarray, link: np.ndarray,
                      soft: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(primitives (B, k P, 6), torque rows (B, J, k P)) of B closings.

        Args:
            q: (B, dof) the draws' configurations (the palm pose); values: joint name ->
                (B,) the closing's final joint values (others: from q).
            points, normals: (B, k, 3) the contacts (object frame; NaN where absent);
            finger, link: (B, k) their finger and link index (-1 where absent).
            soft: (B, k) the patch model's soft contacts (:meth:`~kinegrasp_env.
                montecarlo.patch_contacts.PatchContacts.expand`), or None.
        """
        palm = self.obj.pose_inverse @ self.kinematics.pose(q, self.description.palm_link)
        full = self.description.model.expand(q)
        full.update({name: np.asarray(v, dtype=float) for name, v in values.items()})
        w = self.primitives(points, normals, finger >= 0, soft)
        return w, self.torque_rows(palm, full, finger, link, w)

    def held(self, q: np.ndarray, values: dict[str, np.ndarray], points: np.ndarray,
             normals: np.ndarray, finger: np.ndarray, link: np.ndarray,
             scale: np.ndarray | float = 1.0, soft: np.ndarray | None = None) -> np.ndarray:
        """(B, 6) which of the six loads, times ``scale`` (a number or (B,)), each closing
        holds (arguments: :meth:`contact_terms`)."""
        if q.shape[0] == 0:
            return np.zeros((0, self.loads.shape[0]), dtype=bool)
        w, rows = self.contact_terms(q, values, points, normals, finger, link, soft)
        return self._verdicts(w, rows, np.broadcast_to(scale, q.shape[:1]))

    def _verdicts(self, w: np.ndarray, rows: np.ndarray, scale: np.ndarray) -> np.ndarray:
        # the programme is homogeneous: loads times s hold iff the loads hold with the
        # limits divided by s
        size = 1.0 / np.asarray(scale, dtype=float)[:, None]
        return static_hold(w, rows, self.lower * size, self.upper * size, self.loads)

    def capacity(self, q: np.ndarray, values: dict[str, np.ndarray], points: np.ndarray,
                 normals: np.ndarray, finger: np.ndarray, link: np.ndarray, *,
                 top: float = 64.0, steps: int = 12,
                 soft: np.ndarray | None = None) -> np.ndarray:
        """(B,) the largest multiple of the object's weight (and lift) each closing holds in
        all six directions, in [0, ``top``], by bisection on a log scale to a factor
        ``top ** (2 ** -steps)`` (arguments: :meth:`contact_terms`); 0 where even
        ``1 / top`` of it is not held."""
        batch = q.shape[0]
        if batch == 0:
            return np.zeros(0)
        w, rows = self.contact_terms(q, values, points, normals, finger, link, soft)
        low, high = np.full(batch, -np.log(top)), np.full(batch, np.log(top))
        at_top = self._verdicts(w, rows, np.exp(high)).all(axis=1)
        above = self._verdicts(w, rows, np.exp(low)).all(axis=1)
        for _ in range(steps):
            middle = 0.5 * (low + high)
            ok = self._verdicts(w, rows, np.exp(middle)).all(axis=1)
            low, high = np.where(ok, middle, low), np.where(ok, high, middle)
        return np.where(at_top, top, np.where(above, np.exp(low), 0.0))
