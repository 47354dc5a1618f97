"""The holding test's primitives in MuJoCo (:class:`MujocoWorldSteps`) and a hand's contacts
read from MuJoCo's contact records, for :class:`~kinegrasp_env.physics.mujoco_robot_hold.
MujocoRobotHold`: the same protocol, phases, thresholds and hand motion
(:mod:`~kinegrasp_env.physics.motion`) as pybullet's (:mod:`~kinegrasp_env.physics.
pybullet_hold`), in a :class:`~kinegrasp_env.physics.mujoco_world.MujocoWorld`; a saved state
is MuJoCo's integration state (``mj_getState`` / ``mj_setState``).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.physics.grip_forces import GripContact
from kinegrasp_env.physics.hold_runner import WorldSteps
from kinegrasp_env.physics.mujoco_world import MujocoWorld
from kinegrasp_env.physics.protocol import HoldProtocol
from kinegrasp_env.physics.pybullet_contacts import merge_records


def touching(world: MujocoWorld, distance: float) -> set[tuple[int, int]]:
    """(finger, link) of the finger links with a contact within ``distance`` (m)."""
    return {world.finger_geom[rec[0]] for rec in world.contact_records()
            if rec[0] in world.finger_geom and rec[3] <= distance}


def world_contacts(world: MujocoWorld, distance: float) -> list[GripContact]:
    """One contact per touching finger link, world frame (pybullet's merge rule on records
    laid out as pybullet's: [6] point on the object, [7] normal object -> finger, [8]
    distance, [9] normal force), the records averaged without their forces, as
    :func:`~kinegrasp_env.physics.robot_hold.world_contacts` averages a pad's."""
    records: dict[tuple[int, int], list[tuple]] = {}
    for geom, point, normal, dist, _force in world.contact_records():
        if geom in world.finger_geom and dist <= distance:
            rec = (None,) * 6 + (point, -normal, dist, 0.0)
            records.setdefault(world.finger_geom[geom], []).append(rec)
    return [GripContact(finger, link, *merge_records(records[(finger, link)]))
            for finger, link in sorted(records)]


class MujocoWorldSteps(WorldSteps):
    """The holding test's primitives (:class:`~kinegrasp_env.physics.hold_runner.HoldSteps`)
    that any hand in a :class:`MujocoWorld` shares: time steps, the fingers' forces, the
    object in the palm frame (the hand's ``palm``), a saved state MuJoCo's integration state
    (``mj_getState`` / ``mj_setState``), the hand's root moved by its mocap anchor. A hand's
    steps add its grip.

    Args:
        world: the world right after the closing.
        protocol: the holding test's settings.
    """

    def __init__(self, world: MujocoWorld, protocol: HoldProtocol) -> None:
        super().__init__(world, protocol, world.hand.palm)
        self.state = self.start = None

    def advance(self, steps: int = 1) -> None:
        self.world.step(steps)

    def finger_forces(self) -> np.ndarray:
        return self.world.finger_forces()

    def save(self) -> None:
        world = self.world
        self.state = world.save_state()
        self.start = world.link_pose(world.hand.root), world.link_pose(self.palm_link)[:3, 3]

    def start_phase(self, gravity: np.ndarray) -> None:
        self.world.restore_state(self.state)
        self.world.set_gravity(gravity)

    def hand_start(self) -> tuple[np.ndarray, np.ndarray]:
        return self.start

    def move_hand(self, position: np.ndarray, orientation: np.ndarray) -> None:
        self.world.root_at(position, orientation)

    def discard(self) -> None:
        self.state = self.start = None
