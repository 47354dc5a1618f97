"""The MuJoCo world of the holding test: the hand on a mocap root, one free object, its table.

The MuJoCo counterpart of :class:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld`, built
from the same URDF and the same convex parts (:func:`~kinegrasp_env.physics.mujoco_model.
build_model`), with the same :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings`
(density, friction, 1 ms step). Every draw starts from MuJoCo's reset state (``mj_resetData``:
nothing of a previous draw survives, warm starts included), so a draw's result depends only
on its inputs.

Joint control: each hand joint has one actuator whose gains, and the joint's damping, are
switched. pybullet's velocity motor is a constraint of its solver (the torque needed for the
target speed, up to the limit); MuJoCo has none, and a velocity servo whose torque saturates
on these light links (2.1 N m on ~1e-4 kg m^2: 20 rad/s per 1 ms step) chatters between the
limits. So a motor is a DC motor's torque-speed line: :meth:`MujocoWorld.velocity` applies
the limit as a constant torque against a joint damping of limit / target speed, which MuJoCo
integrates implicitly: unloaded the joint runs at the target speed, blocked it presses with
the limit (pybullet's motor: the same two ends, full torque below the target speed).
:meth:`MujocoWorld.position` holds a joint with an equality constraint of MuJoCo's solver
(as stiff as the object's pin; a spring stiff enough to hold a finger against its distal
motor's 1.4 N m, ~1000 N m/rad, is unstable at 1 ms on these links). Unlike pybullet's
position motor it has no torque cap (pybullet's: ``hold_torque``, 10 N m).

Contacts are MuJoCo's hand-object contact records (``mj_contactForce`` for their normal
forces); they exist only where the surfaces touch (margin 0: pybullet reports records from
the closing's touch distance, 0.2 mm, on). A record's point on the object is
``pos + dist / 2 * n`` (MuJoCo's ``pos`` lies
midway between the two surfaces), its normal ``n`` points from the finger into the object.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.physics.mujoco_model import (
    CONTACT,
    ContactSettings,
    MujocoHand,
    build_model,
    import_mujoco,
    matrix_quat,
)
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.world.objects import GraspObject

#: MuJoCo steps per time step of the protocol (1 ms): at 1 ms MuJoCo's stiff contacts and the
#: joint holds (time constant 2 ms, the smallest MuJoCo keeps at 1 ms) made the light finger
#: links chatter (contact forces flickering between 0 and 100 N); at 0.25 ms they are steady.
SUBSTEPS = 4


def pose_of(position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(4, 4) from a position (3,) and a row-major rotation (9,) or (3, 3)."""
    out = np.eye(4)
    out[:3, :3] = np.reshape(rotation, (3, 3))
    out[:3, 3] = position
    return out


class MujocoWorld:
    """The hand, the object and its table in one MuJoCo model (module docstring).

    Args:
        obj: the catalog object (placed at ``obj.pose``).
        settings: density, friction and time step (its pybullet-only fields are unused).
        contact: MuJoCo's contact parameters.
        hand: the hand (:func:`~kinegrasp_env.physics.mujoco_robot_hold.description_hand`).

    Attributes:
        model, data: MuJoCo's.
        mass: the object's mass, kg.
        finger_geom: hand geom id -> (finger, link index) of the finger links' geoms.
    """

    def __init__(self, obj: GraspObject, hand: MujocoHand, settings: WorldSettings | None = None,
                 contact: ContactSettings = CONTACT) -> None:
        self.mujoco = import_mujoco()
        self.obj = obj
        self.settings = settings or WorldSettings()
        if not self.settings.object_free:
            raise ValueError("the MuJoCo world's object is always free (object_free=True)")
        self.hand = hand
        self.model = build_model(obj, hand, self.settings.friction,
                                 self.settings.object_density(obj),
                                 self.settings.time_step / SUBSTEPS, contact)
        self.data = self.mujoco.MjData(self.model)
        model = self.model
        self.mass = float(model.body("object").mass[0])
        self.joint_names = [model.joint(j).name for j in range(model.njnt)
                            if model.joint(j).name not in ("object_free", "hand_free")]
        self.root_qpos = int(model.joint("hand_free").qposadr[0])
        self.qpos_adr = {n: int(model.joint(n).qposadr[0]) for n in self.joint_names}
        self.dof_adr = {n: int(model.joint(n).dofadr[0]) for n in self.joint_names}
        self.actuator = {n: model.actuator(f"motor_{n}").id for n in self.joint_names}
        self.hold = {n: model.equality(f"hold_{n}").id for n in self.joint_names}
        self.object_body = model.body("object").id
        self.object_qpos = int(model.joint("object_free").qposadr[0])
        self.mocap = int(model.body_mocapid[model.body("anchor").id])
        self.pin = model.equality("pin").id
        holds = set(self.hold.values())
        #: the joint equalities of the URDF's mimic couplings (on after every reset)
        self.couplings = [e for e in range(model.neq) if e not in holds
                          and model.eq_type[e] == self.mujoco.mjtEq.mjEQ_JOINT]
        object_geoms = np.flatnonzero(model.geom_bodyid == self.object_body)
        self.object_geoms = frozenset(int(g) for g in object_geoms)
        links = {model.body(name).id: place for name, place in hand.finger_links.items()}
        self.finger_geom = {g: links[int(model.geom_bodyid[g])] for g in range(model.ngeom)
                            if int(model.geom_bodyid[g]) in links}
        hand_root = model.body(hand.root).id
        self.hand_geoms = frozenset(g for g in range(model.ngeom)
                                    if self._under(int(model.geom_bodyid[g]), hand_root))
        self.table_geom = model.geom("table").id if obj.table is not None else None
        self._table_bits = (None if self.table_geom is None else
                            (int(model.geom_contype[self.table_geom]),
                             int(model.geom_conaffinity[self.table_geom])))

    def _under(self, body: int, root: int) -> bool:
        while body > 0:
            if body == root:
                return True
            body = int(self.model.body_parentid[body])
        return False

    # ------------------------------------------------------------------ draw state
    def reset(self, root_pose: np.ndarray, joints: dict[str, float], pin: bool = True) -> None:
        """Start a draw: MuJoCo's reset state, gravity off, the table back, the hand root
        (flange frame) at ``root_pose`` (4, 4), hand joints at ``joints`` (radians or metres;
        those not named at 0), the object at its catalog pose, pinned there when ``pin``. The
        joints' controller settings (:meth:`velocity`, :meth:`position`, :meth:`couple`,
        :meth:`spring`: model fields) stay as the last draw left them: each closing sets
        those of every joint it drives before it steps."""
        mj, model, data = self.mujoco, self.model, self.data
        mj.mj_resetData(model, data)
        model.opt.gravity[:] = 0.0
        if self.table_geom is not None:
            model.geom_contype[self.table_geom], model.geom_conaffinity[self.table_geom] = \
                self._table_bits
        self.set_root(root_pose)
        data.qpos[self.root_qpos:self.root_qpos + 3] = root_pose[:3, 3]
        data.qpos[self.root_qpos + 3:self.root_qpos + 7] = matrix_quat(root_pose[:3, :3])
        for name, value in joints.items():
            data.qpos[self.qpos_adr[name]] = float(value)
        data.qpos[self.object_qpos:self.object_qpos + 3] = self.obj.pose[:3, 3]
        data.qpos[self.object_qpos + 3:self.object_qpos + 7] = matrix_quat(self.obj.pose[:3, :3])
        data.eq_active[self.pin] = 1 if pin else 0  # welded at the model's reference pose,
        mj.mj_forward(model, data)  # which is the catalog pose

    def uncouple(self) -> None:
        """Switch the mimic couplings off until the next :meth:`reset` (each coupled joint
        then moves under its own actuator, as pybullet's URDF joints do)."""
        for e in self.couplings:
            self.data.eq_active[e] = 0

    def set_root(self, root_pose: np.ndarray) -> None:
        """The anchor of the hand root (flange frame) at ``root_pose`` (4, 4)."""
        self.data.mocap_pos[self.mocap] = root_pose[:3, 3]
        self.data.mocap_quat[self.mocap] = matrix_quat(root_pose[:3, :3])

    def root_at(self, position: np.ndarray, quat_xyzw: np.ndarray) -> None:
        """The anchor at a position (3,) and a quaternion in pybullet's (x, y, z, w)."""
        self.data.mocap_pos[self.mocap] = position
        x, y, z, w = quat_xyzw
        self.data.mocap_quat[self.mocap] = (w, x, y, z)

    def release_object(self) -> None:
        """Switch the pin off."""
        self.data.eq_active[self.pin] = 0

    def remove_table(self) -> None:
        """Take the table, if any, out of collisions until the next :meth:`reset`."""
        if self.table_geom is not None:
            self.model.geom_contype[self.table_geom] = 0
            self.model.geom_conaffinity[self.table_geom] = 0

    def set_gravity(self, acceleration) -> None:
        """Gravity as a vector (3,), m/s^2, world frame."""
        self.model.opt.gravity[:] = np.asarray(acceleration, dtype=float)

    def save_state(self) -> np.ndarray:
        """The full integration state (MuJoCo's ``mjSTATE_INTEGRATION``: positions,
        velocities, controls, mocap, equality switches, warm start)."""
        kind = self.mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(self.mujoco.mj_stateSize(self.model, kind))
        self.mujoco.mj_getState(self.model, self.data, state, kind)
        return state

    def restore_state(self, state: np.ndarray) -> None:
        self.mujoco.mj_setState(self.model, self.data, state,
                                self.mujoco.mjtState.mjSTATE_INTEGRATION)
        self.mujoco.mj_forward(self.model, self.data)

    def step(self, steps: int = 1) -> None:
        """Advance ``steps`` time steps of ``settings.time_step`` (:data:`SUBSTEPS` MuJoCo
        steps each)."""
        self.mujoco.mj_step(self.model, self.data, nstep=steps * SUBSTEPS)

    # ------------------------------------------------------------------ servos
    def velocity(self, names: list[str], speeds, limits) -> None:
        """Motors towards target speeds with torque limits, per joint (module docstring): a
        constant torque ``limit`` (signed as the speed) against the joint's damping
        ``limit / |speed|`` (integrated implicitly): free, the joint runs at the target
        speed; blocked, it presses with the limit."""
        n = len(names)
        for name, speed, limit in zip(names, np.broadcast_to(speeds, n),
                                      np.broadcast_to(limits, n), strict=True):
            a = self.actuator[name]
            self.data.eq_active[self.hold[name]] = 0
            self.model.actuator_gainprm[a, 0] = 1.0
            self.model.actuator_biasprm[a, :3] = 0.0
            self.model.actuator_forcerange[a] = (-limit, limit)
            self.model.dof_damping[self.dof_adr[name]] = limit / max(abs(float(speed)), 1e-9)
            self.data.ctrl[a] = np.copysign(limit, speed)

    def position(self, names: list[str], targets) -> None:
        """Hold joints at targets (radians or metres): each joint's equality constraint on,
        its motor off (module docstring)."""
        for name, target in zip(names, np.broadcast_to(targets, len(names)), strict=True):
            a, hold = self.actuator[name], self.hold[name]
            self.model.actuator_gainprm[a, 0] = 0.0
            self.model.actuator_biasprm[a, :3] = 0.0
            self.data.ctrl[a] = 0.0
            self.model.dof_damping[self.dof_adr[name]] = 0.0
            self.model.eq_obj2id[hold] = -1
            self.model.eq_data[hold, :2] = (float(target), 0.0)
            self.data.eq_active[hold] = 1

    def couple(self, name: str, source: str, offset: float, ratio: float) -> None:
        """Hold joint ``name`` at ``offset + ratio * value of joint source`` (radians or
        metres): its equality constraint on, now between the two joints (no effort cap, as
        :meth:`position`), its motor off."""
        self.position([name], [0.0])
        hold = self.hold[name]
        self.model.eq_obj2id[hold] = self.model.joint(source).id
        self.model.eq_data[hold, :2] = (float(offset), float(ratio))

    def spring(self, names: list[str], targets, stiffness, limits) -> None:
        """Springs on joints (:class:`~kinegrasp_env.physics.grip_forces.SpringGrip`):
        torque ``stiffness (target - q)`` capped at +-``limit`` (N m/rad, radians, N m, per
        joint), the joint's hold and damping off."""
        n = len(names)
        for name, target, k, limit in zip(names, np.broadcast_to(targets, n),
                                          np.broadcast_to(stiffness, n),
                                          np.broadcast_to(limits, n), strict=True):
            a = self.actuator[name]
            self.data.eq_active[self.hold[name]] = 0
            self.model.actuator_gainprm[a, 0] = float(k)
            self.model.actuator_biasprm[a, :3] = (0.0, -float(k), 0.0)
            self.model.actuator_forcerange[a] = (-float(limit), float(limit))
            self.model.dof_damping[self.dof_adr[name]] = 0.0
            self.data.ctrl[a] = float(target)

    def joint_frames(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """(unit axes (k, 3), anchors (k, 3)) of hand joints now, world frame."""
        ids = [self.model.joint(n).id for n in names]
        return np.array(self.data.xaxis[ids]), np.array(self.data.xanchor[ids])

    # ------------------------------------------------------------------ queries
    def joint_states(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """(positions (k,), velocities (k,)) of hand joints, radians and rad/s (metres and
        m/s for a prismatic joint)."""
        return (np.array([self.data.qpos[self.qpos_adr[n]] for n in names]),
                np.array([self.data.qvel[self.dof_adr[n]] for n in names]))

    def object_pose(self) -> np.ndarray:
        """(4, 4) world pose of the object frame now."""
        b = self.object_body
        return pose_of(self.data.xpos[b], self.data.xmat[b])

    def link_pose(self, link: str) -> np.ndarray:
        """(4, 4) world pose of a hand link's URDF frame."""
        b = self.model.body(link).id
        return pose_of(self.data.xpos[b], self.data.xmat[b])

    def contact_records(self) -> list[tuple]:
        """Hand-object contacts now, each (hand geom, point on the object (3,), normal into
        the object (3,), distance m (< 0: penetrating), normal force N), world frame."""
        out, force = [], np.zeros(6)
        for i in range(self.data.ncon):
            c = self.data.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            if g1 in self.hand_geoms and g2 in self.object_geoms:
                hand, sign = g1, 1.0
            elif g2 in self.hand_geoms and g1 in self.object_geoms:
                hand, sign = g2, -1.0
            else:
                continue
            normal = sign * np.array(c.frame[:3])  # geom1 -> geom2, made finger -> object
            self.mujoco.mj_contactForce(self.model, self.data, i, force)
            point = np.array(c.pos) + 0.5 * c.dist * normal
            out.append((hand, point, normal, float(c.dist), float(force[0])))
        return out

    def penetration(self) -> float:
        """The deepest hand-object penetration now, metres (0 when nothing overlaps)."""
        return max([0.0] + [-rec[3] for rec in self.contact_records()])

    def pin_load(self) -> tuple[float, float]:
        """What the pin holds now: the norms of the net force (N) and torque about the centre
        of mass (N m) that the hand's contacts put on the object (gravity is off while it is
        pinned; the table, when there is one, does not touch the pinned object)."""
        com = self.data.xipos[self.object_body]
        force, torque, local = np.zeros(3), np.zeros(3), np.zeros(6)
        for i in range(self.data.ncon):
            c = self.data.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            if g2 in self.object_geoms and g1 in self.hand_geoms:
                sign = 1.0  # the force on geom2 is along the frame's normal (geom1 -> geom2)
            elif g1 in self.object_geoms and g2 in self.hand_geoms:
                sign = -1.0
            else:
                continue
            self.mujoco.mj_contactForce(self.model, self.data, i, local)
            f = sign * (np.reshape(c.frame, (3, 3)).T @ local[:3])
            force += f
            torque += np.cross(np.array(c.pos) - com, f)
        return float(np.linalg.norm(force)), float(np.linalg.norm(torque))

    def finger_forces(self) -> np.ndarray:
        """(fingers,) each finger's total normal force on the object now, newtons."""
        forces = np.zeros(self.hand.fingers)
        for geom, _, _, _, force in self.contact_records():
            if geom in self.finger_geom:
                forces[self.finger_geom[geom][0]] += force
        return forces
