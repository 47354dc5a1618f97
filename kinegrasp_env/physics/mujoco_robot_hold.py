"""The holding test (:mod:`~kinegrasp_env.physics.protocol`) of any description robot, in
MuJoCo: the second opinion on :class:`~kinegrasp_env.physics.robot_hold.RobotHold`, with the
same draw interface, protocol and motors; where MuJoCo differs, the steps below say so.

The world is :class:`~kinegrasp_env.physics.mujoco_world.MujocoWorld` with the robot's hand
(:func:`description_hand`): the URDF subtree below the description's ``palm_link``, cut as
pybullet's holding test cuts it (:func:`~kinegrasp_env.physics.robot_world.hand_urdf`: the
same links, meshes, joints and limits), its root held at the palm pose that the draw's arm
joints give (forward kinematics of the URDF). MuJoCo collides a mesh as its convex hull, as
pybullet and the kinematic engines do; two flat faces pressed together touch at several
points (MuJoCo's multi-point convex collision, on by default), but a pad whose hull is
slightly curved touches at one corner: the Panda's finger, whose pad is two faces 2 degrees
apart, touches a cube face at one hull vertex, 11 mm from the kinematic closing's patch
centre (pybullet's polyhedral contact features give the overlap's corners).

One draw (:meth:`MujocoRobotHold.run_draw`):

1. **closing**, gravity off, the object pinned: a hand link penetrating the object by more
   than :data:`~kinegrasp_env.closing.close_rules.START_TOL` at the pre-shape is a start
   collision. Otherwise each finger's first closing joint (radians or metres) closes under a
   motor of its own
   (:meth:`~kinegrasp_env.physics.mujoco_world.MujocoWorld.velocity`: the URDF's velocity
   limit, its effort limit, :func:`~kinegrasp_env.physics.hand_motors.motor_efforts`), the
   finger's other closing joints and the mimic joints follow it by the rule of
   :func:`~kinegrasp_env.physics.hand_motors.closing_followers` (here an equality of
   MuJoCo's solver between the two joints, without pybullet's effort cap on the follower);
   the URDF's own mimic couplings are off, so the fingers close on their own, as in
   pybullet; an independently actuated phalanx closes by the touch rule
   (:class:`~kinegrasp_env.physics.hand_motors.TouchRule`) and a spread is held
   (:func:`~kinegrasp_env.physics.hand_motors.preshape_holds`), as in pybullet; a joint's
   limits are as stiff as MuJoCo keeps stable (:data:`LIMIT_STEPS`).
   The closing ends by the same stall rule
   (:class:`~kinegrasp_env.physics.robot_hold.RobotMotorSettings`); then one contact per
   touching finger link (MuJoCo's records merged by pybullet's rule and averaged without
   force weights, as :func:`~kinegrasp_env.physics.robot_hold.world_contacts` averages a
   pad's: :func:`~kinegrasp_env.physics.mujoco_hold.world_contacts`), in the object frame,
   and every closing joint's value. Closing with the object free (``pin=False``), the
   object has no support damping, where pybullet's has.
2. **grip**: the rule for jaws of :mod:`~kinegrasp_env.physics.robot_hold`: every closing
   motor keeps pushing with its full effort; fewer than two touching fingers: ``no_grip``.
3. the release and the phases: :func:`~kinegrasp_env.physics.hold_runner.hold_test`, the
   same sequence and rules, from MuJoCo's saved integration state, the hand moved by its
   mocap anchor.
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.closing.close_rules import CONTACT_TOL, START_TOL
from kinegrasp_env.physics import hold_runner
from kinegrasp_env.physics.balanced_grip import GripLayout
from kinegrasp_env.physics.hand_motors import (
    JointMotor,
    TouchRule,
    closing_followers,
    finger_leaders,
    preshape_holds,
)
from kinegrasp_env.physics.hold_runner import close_until_stall
from kinegrasp_env.physics.mujoco_hold import MujocoWorldSteps, touching, world_contacts
from kinegrasp_env.physics.mujoco_model import MujocoHand, with_compiler
from kinegrasp_env.physics.mujoco_world import MujocoWorld
from kinegrasp_env.physics.protocol import START_COLLISION, HoldProtocol, HoldResult
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.physics.robot_hold import (
    DescriptionHold,
    RobotMotorSettings,
    closing_result,
)
from kinegrasp_env.physics.robot_world import ROOT_LINK, hand_urdf
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.objects import GraspObject, as_object

#: The mesh files MuJoCo reads (file suffixes, lower case).
MUJOCO_MESHES = (".stl", ".obj")
#: The time constant of the hand joints' limits, in MuJoCo steps (the smallest MuJoCo keeps
#: stable is two). pybullet's limits are hard; with MuJoCo's default limit softness (20 ms)
#: the xArm's drive joint, closing in free space with its URDF effort (50 N m on light
#: links), ran 2.1 rad past its upper limit (0.85 rad); at 10 steps 0.05 rad; at two, 0.004.
LIMIT_STEPS = 2


def description_hand(description: RobotDescription) -> MujocoHand:
    """The robot's hand for MuJoCo (module docstring): its URDF text, root, palm and finger
    links.

    Raises:
        ValueError: a collision mesh MuJoCo cannot read (one line, naming the file; visual
            meshes are dropped, whatever their format).
    """
    with tempfile.TemporaryDirectory(prefix="kinegrasp_hand_") as folder:
        path = Path(folder) / "hand.urdf"
        hand_urdf(description, path)
        text = path.read_text()
    for mesh in ET.fromstring(text).iterfind("link/collision/geometry/mesh"):
        name = mesh.get("filename", "")
        if Path(name).suffix.lower() not in MUJOCO_MESHES:
            raise ValueError(f"robot {description.name!r}: MuJoCo reads STL and OBJ meshes, "
                             f"not {Path(name).name}; convert it (trimesh) and name the "
                             f"new file in {description.urdf.name}")
    links: dict[str, tuple[int, int]] = {}
    for f, finger in enumerate(description.fingers):
        for k, link in enumerate(finger.links):
            links.setdefault(link, (f, k))
    return MujocoHand(with_compiler(text, description.urdf.name), ROOT_LINK,
                      description.palm_link, links, len(description.fingers))


class JawServos:
    """The closing motors (module docstring, steps 1 and 2) of a :class:`MujocoWorld`, the
    hand at its pre-shape.

    Args:
        world: the world.
        description: the robot.
        motors: :func:`~kinegrasp_env.physics.hand_motors.motor_efforts`.
        holds: :func:`~kinegrasp_env.physics.hand_motors.hold_efforts` (MuJoCo holds a
            joint by an equality, without an effort cap).
        touch_distance: a contact record within this distance (metres) is a touch.
        free: the object is free (not pinned): a finger driven on its own presses as a
            last motor does (:func:`~kinegrasp_env.physics.hand_motors.independent_jaws`),
            as in pybullet.

    A pressing motor presses with its full effort when blocked, as pybullet's; MuJoCo's
    velocity servo (:meth:`~kinegrasp_env.physics.mujoco_world.MujocoWorld.velocity`: a
    constant effort against a damping of effort over speed) also resists being pushed back,
    the more the slower its target, where pybullet's gives way beyond its effort.
    """

    def __init__(self, world: MujocoWorld, description: RobotDescription,
                 motors: list[JointMotor], holds: dict[str, float],
                 touch_distance: float = CONTACT_TOL, free: bool = False) -> None:
        self.world, self.touch_distance = world, touch_distance
        leaders = finger_leaders(description)
        self.motors = [m for m in motors if m.joint in leaders]
        self.names = [m.joint for m in self.motors]
        self.speeds = np.array([m.speed for m in self.motors])
        start = dict(zip(world.joint_names, world.joint_states(world.joint_names)[0],
                         strict=True))
        world.uncouple()
        for f in closing_followers(description, motors, start, holds=holds):
            world.couple(f.joint, f.source, f.target_start - f.ratio * f.source_start,
                         f.ratio)
        fixed = preshape_holds(description, holds, start)
        if fixed:
            world.position([h.joint for h in fixed], [h.value for h in fixed])
        self.touch = TouchRule(description, self.motors, holds, world.settings.time_step,
                               free=free)
        world.velocity(self.names, [m.direction * m.speed for m in self.motors],
                       [m.effort for m in self.motors])

    def step(self) -> None:
        """One time step, then the touch rule
        (:class:`~kinegrasp_env.physics.hand_motors.TouchRule`) on the links touching now:
        a held joint by its equality constraint (no effort cap, as every MuJoCo hold here),
        a pressing one by its motor at the creep speed with its effort."""
        self.world.step()
        if not self.touch.active:
            return
        held, pressing = self.touch.update(touching(self.world, self.touch_distance))
        if held:
            self.world.position(held, self.world.joint_states(held)[0])
        for name, _ in pressing:
            motor = self.motors[self.names.index(name)]
            self.world.velocity([name], [self.touch.velocity(motor)], [motor.effort])

    def travel(self) -> np.ndarray:
        """(m,) the motors' joint positions in seconds of travel (value / closing speed; a
        pressing motor's 0: :meth:`~kinegrasp_env.physics.hand_motors.TouchRule.travel`)."""
        return self.touch.travel(self.names, self.world.joint_states(self.names)[0]
                                 / self.speeds)


class MujocoRobotSteps(MujocoWorldSteps):
    """The holding test's primitives (:class:`~kinegrasp_env.physics.mujoco_hold.
    MujocoWorldSteps`) of a description robot's hand: the grip is the closing motors left
    on (jaws), or with ``layout`` the balanced grip
    (:mod:`~kinegrasp_env.physics.balanced_grip`: the loaded joints MuJoCo springs, the
    others held)."""

    def __init__(self, world: MujocoWorld, protocol: HoldProtocol,
                 layout: GripLayout | None = None) -> None:
        super().__init__(world, protocol)
        self.layout = layout

    def grip(self) -> bool:
        world, layout = self.world, self.layout
        contacts = world_contacts(world, CONTACT_TOL)
        if len({c.finger for c in contacts}) < 2:
            return False
        if layout is None:
            return True
        spring = layout.world_spring(world, contacts, self.protocol.grip_advance)
        if spring is None:
            return False
        names = np.array(layout.names)
        loaded, held = names[spring.loaded], names[~spring.loaded]
        world.uncouple()  # each joint on its own, as in pybullet
        if held.size:
            world.position(list(held), spring.stall[~spring.loaded])
        if loaded.size:
            world.spring(list(loaded), spring.targets[spring.loaded],
                         spring.stiffness[spring.loaded], spring.limits[spring.loaded])
        return True


class MujocoRobotHold(DescriptionHold):
    """The holding test of a description robot in MuJoCo, one draw at a time (arguments and
    attributes: :class:`~kinegrasp_env.physics.robot_hold.RobotHold`'s)."""

    name = "mujoco"

    def __init__(self, description: RobotDescription | str, obj: GraspObject | str,
                 friction: float, protocol: HoldProtocol, world: WorldSettings | None = None,
                 settings: RobotMotorSettings | None = None) -> None:
        world_settings = replace(world or WorldSettings(), friction=friction)
        super().__init__(description, protocol, settings)
        self.world = world = MujocoWorld(as_object(obj), description_hand(self.description),
                                         world_settings)
        model = world.model
        for name in world.joint_names:
            joint = model.joint(name).id
            model.jnt_solref[joint] = (LIMIT_STEPS * model.opt.timestep, 1.0)
            # MuJoCo's URDF reader caps a joint's actuator force at its <limit effort>; the
            # motors' efforts (the description's, times the protocol's scale) rule instead
            model.jnt_actfrclimited[joint] = 0

    def close_hand(self, q: np.ndarray, pin: bool = True
                   ) -> tuple[RobotCloseResult, JawServos | None]:
        """The closing of configuration q (dof,) on the object, pinned or (``pin=False``)
        free without gravity: its contacts in the object frame where the object ended, and
        the motors (None: start collision)."""
        world, fingers = self.world, self.description.fingers
        world.reset(self.palm_poses(q)[0], self.hand_values(q, world.qpos_adr), pin=pin)
        if world.penetration() > START_TOL:
            return RobotCloseResult(True, missed=(False,) * len(fingers)), None
        servos = JawServos(world, self.description, self.motors, self.holds,
                           self.settings.touch_distance, free=not pin)
        close_until_stall(servos.step, servos.travel, self.settings, world.settings.time_step)
        names = [m.joint for m in self.motors]  # every closing joint, as pybullet reports
        positions = world.joint_states(names)[0]
        return closing_result(world_contacts(world, self.settings.touch_distance),
                              world.object_pose(),
                              len(fingers), dict(zip(names, map(float, positions),
                                                     strict=True))), servos

    def run_draw(self, q: np.ndarray) -> tuple[RobotCloseResult, HoldResult]:
        """One draw at configuration q (dof,): the closing on the pinned object and the
        holding test."""
        closing, servos = self.close_hand(q)
        if servos is None:
            return closing, HoldResult(START_COLLISION)
        return closing, hold_runner.hold_test(
            MujocoRobotSteps(self.world, self.protocol, self.layout), self.protocol)

    def close(self) -> None:
        """Nothing to disconnect (MuJoCo's model and data are freed with this object)."""
