"""The pybullet *dynamics* world of the physics closing: a free-floating hand held by a
constraint, and one catalog object as a rigid body.

The kinematic closing (:mod:`kinegrasp_env.closing.generic_reference`) never steps the
simulation; here the hand's finger motors close under dynamics, the object may be pushed (or
pinned where it is, :meth:`PhysicsWorld.pin_object`), and in the holding test
(:mod:`kinegrasp_env.physics.pybullet_hold`) gravity turns and the hand moves. Therefore:

* the hand (cut from the robot's URDF: :class:`~kinegrasp_env.physics.robot_world.
  RobotPhysicsWorld`) is loaded with a *dynamic* base, and a fixed constraint (the "arm")
  holds its root at the palm pose reached by the draw's arm joints. The arm itself is not
  simulated: its joints would only set where the palm is, which is all the constraint
  needs, and moving the constraint's target is how the holding test moves the hand
  (no IK, no arm-object collisions, no joint-limit failures of the arm during the shake);
* the object is one rigid body whose collision shape is a compound of its exact convex parts
  (written to a temporary ``.obj`` with one ``o`` group per part, which pybullet loads as one
  convex hull per group, collision margin zero), mass = density x the mesh's volume,
  inertia of the uniform-density mesh about its centre of mass; or, with
  ``object_free=False``, the same shape as a static body;
* friction: Bullet combines two bodies' friction coefficients as their product, so the hand's
  links get 1.0 and the object ``friction`` (the quality measure's mu); no rolling or spinning
  friction (point contacts with Coulomb friction, the quality measure's contact model).

Every draw starts from the same saved simulator state (``restoreState``, then one collision
pass with the hand parked away from the object, which drops the previous draw's hand-object
pair and the contact caches of the object's parts: ``restoreState`` leaves those, and mug
draws closed differently after different predecessors), so a draw's result depends only on
its own inputs, not on the draws before (tests).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet
from scipy.spatial import ConvexHull

from kinegrasp_env.physics.protocol import check_simulated_friction
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sim import BulletWorld, matrix_to_pose
from kinegrasp_env.world.table_body import table_body

#: Gravity, m/s^2 (world -z).
GRAVITY = 9.81
#: Largest force the constraint that holds the hand may apply, newtons (the arm is stiff);
#: also the largest force of the constraint that pins the object.
ANCHOR_FORCE = 1.0e4
#: Where a support table is put while the holding test runs (world frame, metres): out of
#: reach of the hand and the object.
TABLE_AWAY = (0.0, 0.0, -100.0)
#: Mass (kg) and principal moments of inertia (kg m^2) given to the hand's root link: it stands
#: in for the arm behind the flange. With the URDF's 0.01 kg root, the anchor constraint let
#: the hand wander by up to 1 mm under the grip forces and pybullet's solver stopped short of
#: convergence (finger motors starved of torque); 100 kg behaves as a fixed base does.
ROOT_MASS = 100.0
ROOT_INERTIA = 1.0
#: How the hand is loaded: with Bullet's polyhedral contact features (SAT: a pad on a face
#: touches at the corners of their overlap).
HAND_FLAGS = pybullet.URDF_INITIALIZE_SAT_FEATURES
#: The object's collision shape gets the same features (``createCollisionShape`` reads the
#: same bit). It is made by ``createCollisionShape``, not loaded from a URDF: the URDF
#: importer gives every convex part a 1 mm collision margin that ``changeDynamics`` does not
#: reach (measured: the object 1 mm larger, a capsule fingertip's contacts 1 mm off the
#: surface), and recomputes its inertia from the shape's bounding box unless asked not to.
OBJECT_SHAPE_FLAGS = pybullet.URDF_INITIALIZE_SAT_FEATURES


@dataclass(frozen=True)
class WorldSettings:
    """Physical settings of the world.

    Attributes:
        density: of the object, kg/m^3; None (the default): the catalog object's own
            (:attr:`~kinegrasp_env.world.objects.GraspObject.density`).
        friction: Coulomb friction mu between a finger and the object (the quality's mu).
        object_free: the object is a dynamic body (it can be pushed); False: static.
        support_damping: while the hand closes (gravity off) a free object's linear and
            angular velocities are damped at this rate, 1/s (pybullet's damping: a push of
            v m/s carries the object about v / support_damping metres): it stands in for the
            support the object rests on, so the object moves while pushed and stops soon
            after instead of floating away. 0: floating. Off during the holding test.
        time_step: simulation step, seconds (1 ms: at pybullet's default 1/240 s the light
            finger links sank up to 2.5 mm into the object under the grip and five-contact
            cube grasps with Q = 0.23 dropped it at once; at 1 ms they hold it within 2 mm).
        solver_iterations: pybullet's constraint-solver iterations per step.
    """

    density: float | None = None
    friction: float = 0.5
    object_free: bool = True
    support_damping: float = 20.0
    time_step: float = 1.0 / 1000.0
    solver_iterations: int = 50

    def __post_init__(self) -> None:
        check_simulated_friction(self.friction)
        for name in ("density", "time_step"):
            value = getattr(self, name)
            if name == "density" and value is None:
                continue
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not (np.isfinite(self.support_damping) and self.support_damping >= 0):
            raise ValueError(f"support_damping must be >= 0, got {self.support_damping!r}")
        if self.solver_iterations < 1:
            raise ValueError(f"solver_iterations must be >= 1, got {self.solver_iterations!r}")

    def object_density(self, obj: GraspObject) -> float:
        """kg/m^3: :attr:`density`, or the object's own where it is None."""
        return obj.density if self.density is None else float(self.density)


def quaternion_matrix(orientation) -> np.ndarray:
    """(3, 3) rotation of a quaternion (x, y, z, w), by Bullet's own formula
    (``btMatrix3x3::setRotation``: the same bits as ``getMatrixFromQuaternion``, tested),
    without a call on pybullet's global client."""
    x, y, z, w = (float(v) for v in orientation)
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    return np.array([[1.0 - (yy + zz), xy - wz, xz + wy],
                     [xy + wz, 1.0 - (xx + zz), yz - wx],
                     [xz - wy, yz + wx, 1.0 - (xx + yy)]])


def pose_matrix(position, orientation) -> np.ndarray:
    """(4, 4) transform from a pybullet (position, quaternion xyzw)."""
    out = np.eye(4)
    out[:3, :3] = quaternion_matrix(orientation)
    out[:3, 3] = position
    return out


def mass_properties(obj: GraspObject, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass (kg), principal moments of inertia (3,) (kg m^2) and the (4, 4) inertial frame
    (centre of mass, principal axes; object frame) of the uniform-density object mesh."""
    mesh = obj.mesh
    mass = float(density * mesh.volume)
    # trimesh: about the centre of mass, for the mesh's own density
    inertia = density / mesh.density * np.asarray(mesh.moment_inertia, dtype=float)
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    frame = np.eye(4)
    frame[:3, :3] = axes
    frame[:3, 3] = obj.center_of_mass
    return mass, moments, frame


def write_parts_obj(parts: tuple[np.ndarray, ...], path: Path) -> None:
    """Write convex parts (each (n_i, 3), metres) as one ``.obj``: a group per part, its hull's
    triangles oriented outwards."""
    lines, offset = [], 1
    for i, part in enumerate(parts):
        hull = ConvexHull(part)
        lines.append(f"o part_{i}")
        lines += [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in part]
        centre = part.mean(axis=0)
        for tri in hull.simplices:
            a, b, c = part[tri]
            if np.dot(np.cross(b - a, c - a), a - centre) < 0:
                tri = tri[[0, 2, 1]]
            lines.append("f " + " ".join(str(offset + int(k)) for k in tri))
        offset += len(part)
    path.write_text("\n".join(lines) + "\n")


class PhysicsWorld(BulletWorld):
    """The free hand, its anchor constraint and one object, in a world of their own (the
    hand: :meth:`_load_hand`, a subclass's).

    Args:
        obj: the catalog object (placed at ``obj.pose``).
        settings: :class:`WorldSettings`.

    Attributes:
        mass: the object's mass, kg (also for a static object: what it would weigh).
        joint_index, link_index: hand joint / link name -> pybullet index.
    """

    def __init__(self, obj: GraspObject, settings: WorldSettings | None = None) -> None:
        if type(self)._load_hand is PhysicsWorld._load_hand:
            raise TypeError("PhysicsWorld is the base of a hand's world: build "
                            "RobotPhysicsWorld(description, obj), which loads the hand")
        super().__init__(gui=False)
        self.obj = obj
        self.settings = settings or WorldSettings()
        bullet = self.bullet
        bullet.setTimeStep(self.settings.time_step)
        bullet.setPhysicsEngineParameter(numSolverIterations=self.settings.solver_iterations,
                                         deterministicOverlappingPairs=1)
        self.bodies["hand"] = self._load_hand()
        self.mass, moments, self.inertial = mass_properties(obj, self.settings.object_density(obj))
        self.inertial_inverse = np.linalg.inv(self.inertial)
        self.bodies["object"] = self._object_body(moments)
        if obj.table is not None:  # the object rests on it; fingers stall on it
            self.bodies["table"] = table_body(bullet, obj, self.settings.friction)
            self.table_pose = bullet.getBasePositionAndOrientation(self.bodies["table"])
        #: the constraint that pins the object (:meth:`pin_object`), None when free
        self.pin: int | None = None
        self.anchor = bullet.createConstraint(self.hand, -1, -1, -1, pybullet.JOINT_FIXED,
                                              [0, 0, 0], [0, 0, 0], [0, 0, 0])
        bullet.setGravity(0, 0, 0)
        #: the state every draw starts from (hand parked at the world origin, clear of the
        #: object; nothing touching)
        self.initial_state = bullet.saveState()

    def _object_body(self, moments: np.ndarray) -> int:
        """The object: its convex parts, mass, inertia and friction (module docstring), with
        Bullet's polyhedral features (SAT) as the hand has them: a flat pad pressed on a
        face then touches it at the corners of the overlap (a patch, up to four points), not
        at one arbitrary corner."""
        bullet, obj = self.bullet, self.obj
        with tempfile.TemporaryDirectory(prefix="kinegrasp_parts_") as folder:
            path = Path(folder) / f"{obj.name}_parts.obj"
            write_parts_obj(obj.parts, path)
            shape = bullet.createCollisionShape(pybullet.GEOM_MESH, fileName=str(path),
                                                flags=OBJECT_SHAPE_FLAGS)
        position, orientation = matrix_to_pose(obj.pose)
        inertial_position, inertial_orientation = matrix_to_pose(self.inertial)
        free = self.settings.object_free
        body = bullet.createMultiBody(
            baseMass=self.mass if free else 0.0, baseCollisionShapeIndex=shape,
            basePosition=position, baseOrientation=orientation,
            baseInertialFramePosition=inertial_position,
            baseInertialFrameOrientation=inertial_orientation)
        bullet.changeDynamics(body, -1, collisionMargin=0.0, lateralFriction=self.settings.friction,
                              rollingFriction=0.0, spinningFriction=0.0, restitution=0.0,
                              linearDamping=0.0, angularDamping=0.0)
        if free:
            bullet.changeDynamics(body, -1, localInertiaDiagonal=[float(m) for m in moments])
        return body

    def _load_hand(self) -> int:  # pragma: no cover - each world loads its own hand
        """Load the hand with a dynamic base; set :attr:`joint_index` and
        :attr:`link_index`; return its body."""
        raise NotImplementedError

    @property
    def hand(self) -> int:
        return self.bodies["hand"]

    @property
    def object_body(self) -> int:
        return self.bodies["object"]

    def reset(self, root_pose: np.ndarray, joints: dict[str, float]) -> None:
        """Start a draw: the saved state, gravity off, support damping on, the hand root
        (flange frame) at ``root_pose`` (4, 4) with the anchor holding it there, hand joints
        at ``joints`` (radians; every hand joint not named keeps its saved value)."""
        bullet = self.bullet
        self.release_object()
        bullet.restoreState(self.initial_state)
        if "table" in self.bodies:
            bullet.resetBasePositionAndOrientation(self.bodies["table"], *self.table_pose)
        # the hand is parked again: a collision pass drops the previous draw's hand-object
        # pair and its per-part contact caches (restoreState leaves them; see the module doc)
        bullet.performCollisionDetection()
        self.gravity(False)
        self.damp_object(True)
        position, orientation = matrix_to_pose(root_pose)
        bullet.resetBasePositionAndOrientation(self.hand, position, orientation)
        bullet.resetBaseVelocity(self.hand, [0, 0, 0], [0, 0, 0])
        self.move_anchor(root_pose)
        for name, value in joints.items():
            bullet.resetJointState(self.hand, self.joint_index[name], float(value), 0.0)

    def move_anchor(self, root_pose: np.ndarray) -> None:
        """Where the constraint holds the hand root: (4, 4) world pose of the flange frame."""
        self.anchor_at(*matrix_to_pose(root_pose))

    def anchor_at(self, position: list[float], orientation: list[float]) -> None:
        """:meth:`move_anchor` from a position (3,) and a quaternion (x, y, z, w)."""
        self.bullet.changeConstraint(self.anchor, jointChildPivot=position,
                                     jointChildFrameOrientation=orientation,
                                     maxForce=ANCHOR_FORCE)

    def gravity(self, on: bool) -> None:
        """Gravity along world -z (:data:`GRAVITY`), or none."""
        self.bullet.setGravity(0, 0, -GRAVITY if on else 0.0)

    def set_gravity(self, acceleration) -> None:
        """Gravity as a vector (3,), m/s^2, world frame."""
        self.bullet.setGravity(*(float(a) for a in acceleration))

    def pin_object(self) -> None:
        """Pin the (free) object where it is now: a fixed constraint to the world, at most
        :data:`ANCHOR_FORCE` newtons (a free object: it stays a dynamic body, so the contact
        forces on it are computed as for a free one), and no contact with the support table,
        if any, while it is pinned (as in MuJoCo: the table's zero-force contacts with the
        pinned object changed the solver's answer, a cube grasp's verdict among them)."""
        if not self.settings.object_free:
            raise ValueError("only a free object (object_free=True) can be pinned")
        self.release_object()
        bullet = self.bullet
        position, orientation = bullet.getBasePositionAndOrientation(self.object_body)
        bullet.resetBaseVelocity(self.object_body, [0, 0, 0], [0, 0, 0])
        self.pin = bullet.createConstraint(self.object_body, -1, -1, -1, pybullet.JOINT_FIXED,
                                           [0, 0, 0], [0, 0, 0], position,
                                           childFrameOrientation=orientation)
        bullet.changeConstraint(self.pin, jointChildPivot=position,
                                jointChildFrameOrientation=orientation, maxForce=ANCHOR_FORCE)
        self._touch_table(False)

    def _touch_table(self, on: bool) -> None:
        """Let the object and the support table (if any) collide, or not."""
        if "table" in self.bodies:
            self.bullet.setCollisionFilterPair(self.object_body, self.bodies["table"], -1, -1,
                                               int(on))

    def restore_without_contacts(self, state: int) -> None:
        """``restoreState(state)`` with no contact cached: the object is first moved out of
        reach and a collision pass drops its contact pairs (``restoreState`` keeps them, with
        their solver warm-start impulses), then the state is restored."""
        bullet = self.bullet
        bullet.restoreState(state)
        bullet.resetBasePositionAndOrientation(self.object_body, TABLE_AWAY, [0, 0, 0, 1])
        bullet.performCollisionDetection()
        bullet.restoreState(state)

    def pin_load(self) -> tuple[float, float]:
        """What the pin holds now (the net wrench the rest of the world puts on the pinned
        object, from pybullet's constraint state): (force, newtons; torque, N m), norms."""
        state = self.bullet.getConstraintState(self.pin)
        return float(np.linalg.norm(state[:3])), float(np.linalg.norm(state[3:6]))

    def release_object(self) -> None:
        """Remove the object's pin, if any (the object and the table collide again)."""
        if self.pin is not None:
            self.bullet.removeConstraint(self.pin)
            self.pin = None
            self._touch_table(True)

    def remove_table(self) -> None:
        """Put the support table, if any, out of reach (:data:`TABLE_AWAY`) until the next
        :meth:`reset`."""
        if "table" in self.bodies:
            self.bullet.resetBasePositionAndOrientation(self.bodies["table"], TABLE_AWAY,
                                                        self.table_pose[1])

    def damp_object(self, on: bool) -> None:
        """Switch the free object's support damping (see :class:`WorldSettings`) on or off."""
        if self.settings.object_free:
            rate = self.settings.support_damping if on else 0.0
            self.bullet.changeDynamics(self.object_body, -1, linearDamping=rate,
                                       angularDamping=rate)

    def step(self, steps: int = 1) -> None:
        """Advance ``steps`` time steps."""
        for _ in range(steps):
            self.bullet.stepSimulation()

    def object_pose(self) -> np.ndarray:
        """(4, 4) world pose of the object frame now (pybullet reports the inertial frame)."""
        com = pose_matrix(*self.bullet.getBasePositionAndOrientation(self.object_body))
        return com @ self.inertial_inverse

    def link_pose(self, link: str) -> np.ndarray:
        """(4, 4) world pose of a hand link's URDF frame (the root: the flange frame)."""
        bullet = self.bullet
        index = self.link_index[link]
        if index < 0:
            return pose_matrix(*bullet.getBasePositionAndOrientation(self.hand))
        state = bullet.getLinkState(self.hand, index, computeForwardKinematics=True)
        return pose_matrix(state[4], state[5])

    def joint_frames(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """(unit axes (k, 3), points on them (k, 3)) of hand joints now, world frame: each
        joint's child link's frame (a URDF joint's frame is its child link's) and its axis
        there."""
        axes, points = [], []
        for joint in names:
            info = self.bullet.getJointInfo(self.hand, self.joint_index[joint])
            pose = self.link_pose(info[12].decode())
            axes.append(pose[:3, :3] @ np.asarray(info[13]))
            points.append(pose[:3, 3])
        return np.array(axes).reshape(-1, 3), np.array(points).reshape(-1, 3)

    def joint_states(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """(positions (k,), velocities (k,)) of hand joints, radians and rad/s."""
        states = self.bullet.getJointStates(self.hand, [self.joint_index[n] for n in names])
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def contact_points(self) -> list[tuple]:
        """pybullet's contact records between the hand (A) and the object (B), from the last
        step (``getContactPoints``)."""
        return self.bullet.getContactPoints(self.hand, self.object_body)

    def penetration(self) -> float:
        """The deepest hand-object penetration now, metres (0 when nothing overlaps)."""
        records = self.bullet.getClosestPoints(self.hand, self.object_body, 0.0)
        return max([0.0] + [-rec[8] for rec in records])
