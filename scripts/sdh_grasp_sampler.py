"""The sampler that planned the default robot's committed grasp sets: the shipped ones
(``assets/grasps/kuka_sdh/``, :mod:`make_grasp_sets`) and the agents' open-world sets
(``agents/prepare.py``), kept here so that those sets stay reproducible from their seeds.
``kinegrasp plan`` and the library plan every robot, the default one included, with the
shared planner (:func:`kinegrasp_env.toolkit.grasp_planner.plan_grasps`).

A candidate palm pose: an approach direction d (from the robot's side or from above), an aim
point inside the object's bounding box, a stand-off along -d from where the open hand (alone,
at a drawn pre-shape) first touches the object, and a roll about d. The arm reaches it by the
arm's analytic IK (collision-free, within limits), the hand auto-closes from the pre-shape
with the reference engine, and the candidate is kept when its contacts are in force closure
(at most three contacts, none with the hand closed in the object's support table).
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.nominal import grasp_from_draw
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.robot.default_robot import ARM_JOINTS, PALM_LINK, hand_joint_values, kuka_sdh
from kinegrasp_env.toolkit.elbow import ArmWalk
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import GraspObject, load_object
from kinegrasp_env.world.sim import ObjectWorld, load_hand, matrix_to_pose

log = logging.getLogger(__name__)

#: Palm stand-off that keeps the open fingers clear of the object, metres.
FINGER_REACH = 0.25


@dataclass(frozen=True)
class PlannerSettings:
    """Sampling ranges (metres, radians)."""

    standoff: tuple[float, float] = (0.01, 0.06)  # back-off after the approach touches
    elevation: tuple[float, float] = (-0.2, 1.45)   # approach direction below horizontal
    azimuth: tuple[float, float] = (-1.2, 1.2)      # about +x (the robot faces +x)
    proximal: tuple[float, float] = (-0.9, -0.2)
    distal: tuple[float, float] = (-0.2, 0.3)
    spreads: tuple[float, ...] = (0.0, np.pi / 3, np.pi / 6)
    max_contacts: int = 3


def palm_frame(direction: np.ndarray, roll: float) -> np.ndarray:
    """(3, 3) palm rotation: z along ``direction``, x rolled by ``roll`` about it."""
    z = direction / np.linalg.norm(direction)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x0 = np.cross(helper, z)
    x0 /= np.linalg.norm(x0)
    y0 = np.cross(z, x0)
    x = np.cos(roll) * x0 + np.sin(roll) * y0
    return np.column_stack([x, np.cross(z, x), z])


class HandWorld(ObjectWorld):
    """The default robot's hand alone (its root free to place) beside one catalog object:
    the sampler's probe of how far an open hand can approach."""

    def __init__(self, obj: GraspObject) -> None:
        super().__init__(obj)
        self.bodies["hand"], self.joint_index, self.link_index = load_hand(self.bullet)

    def set_hand(self, root_pose: np.ndarray, joints: dict[str, float]) -> None:
        """Place the hand root (flange frame, (4, 4) world) and set hand joint values."""
        bullet = self.bullet
        hand = self.bodies["hand"]
        bullet.resetBasePositionAndOrientation(hand, *matrix_to_pose(root_pose))
        for name, value in joints.items():
            bullet.resetJointState(hand, self.joint_index[name], float(value))

    def closest(self, max_distance: float) -> list[tuple]:
        """pybullet closest points between the hand and the object."""
        return self.bullet.getClosestPoints(self.bodies["hand"], self.bodies["object"],
                                            max_distance)


class GraspPlanner:
    """Sample force-closure grasps of the default robot on one object (module docstring).

    Args:
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure.
        settings: sampling ranges.
    """

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8,
                 settings: PlannerSettings | None = None) -> None:
        self.obj = load_object(object_name)
        self.engine = make_engine("pybullet", DEFAULT_ROBOT, object_name, friction=friction,
                                  num_edges=num_edges)
        self.model = kuka_sdh()
        #: the arm's analytic IK and its links' clearance from the object
        #: (:class:`~kinegrasp_env.toolkit.elbow.ArmWalk`)
        self.walk = ArmWalk(object_name)
        self.ik = self.walk.ik
        #: the batched kinematics of the arm and hand (14 joints)
        self.kin = self.ik.kin
        #: (7,) where the IK starts: the arm's ``home`` in the robot's description, radians
        self.ik_start = load_robot(DEFAULT_ROBOT).home_arm()
        #: the open hand alone beside the object (the approach probe)
        self.world = HandWorld(self.obj)
        self.settings = settings or PlannerSettings()

    def close(self) -> None:
        self.engine.close()
        self.walk.close()
        self.world.close()

    # ------------------------------------------------------------------ geometry checks
    def closed_in_table(self, q0: np.ndarray, hand: np.ndarray) -> bool:
        """Whether the hand closed to ``hand`` (7,) on the arm joints of q0 (14,) ends in the
        object's support table (never, without one): such a grasp goes through the table."""
        if self.obj.table is None:
            return False
        closed = self.engine.check(np.concatenate([q0[:7], hand])[None])
        return bool(self.engine.in_table(closed)[0])

    def surface_distance(self, aim: np.ndarray, direction: np.ndarray) -> float | None:
        """Distance from ``aim`` (world) back along -direction to the object's surface."""
        reach = 2.0 * self.obj.r_max + 0.1
        rot = self.obj.pose[:3, :3]
        start = self.obj.to_object(aim - direction * reach)
        entry = self.obj.ray_entry(start, rot.T @ direction)
        return None if entry is None else reach - entry

    # ------------------------------------------------------------------ sampling
    def sample_pose(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray] | None:
        """(palm pose (4, 4), pre-shape (7,)) or None if the ray misses the object."""
        s = self.settings
        azimuth = rng.uniform(*s.azimuth)
        elevation = rng.uniform(*s.elevation)
        direction = np.array([np.cos(elevation) * np.cos(azimuth),
                              np.cos(elevation) * np.sin(azimuth), -np.sin(elevation)])
        lo, hi = self.obj.mesh.bounds
        aim_local = lo + rng.uniform(0.25, 0.75, size=3) * (hi - lo)
        aim = self.obj.to_world(aim_local)
        depth = self.surface_distance(aim, direction)
        if depth is None:
            return None
        spread = s.spreads[rng.integers(len(s.spreads))]
        prox = rng.uniform(*s.proximal)
        dist = rng.uniform(*s.distal)
        preshape = np.array([spread, prox, dist, prox, dist, prox, dist])
        rot = palm_frame(direction, rng.uniform(0, 2 * np.pi))
        far = depth + FINGER_REACH  # palm this far back from the aim: fingers clear
        advance = self.approach(aim - direction * far, rot, direction, far, preshape)
        if advance is None:
            return None
        pose = np.eye(4)
        pose[:3, :3] = rot
        pose[:3, 3] = aim - direction * (far - advance + rng.uniform(*s.standoff))
        return pose, preshape

    def approach(self, start: np.ndarray, rot: np.ndarray, direction: np.ndarray,
                 limit: float, preshape: np.ndarray) -> float | None:
        """Largest advance (metres, <= limit) of the open hand from ``start`` along
        ``direction`` before it touches the object (bisection to 1 mm); None if it starts
        in collision."""
        world = self.world
        joints = hand_joint_values(preshape)
        mount = next(j for j in self.model.joints if j.child == PALM_LINK)  # flange to palm
        palm_offset = np.linalg.inv(mount.origin)

        def collides(advance: float) -> bool:
            pose = np.eye(4)
            pose[:3, :3] = rot
            pose[:3, 3] = start + direction * advance
            world.set_hand(pose @ palm_offset, joints)
            return bool(world.closest(0.0))

        if collides(0.0):
            return None
        lo, hi = 0.0, limit
        if not collides(hi):
            return hi
        while hi - lo > 1e-3:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if collides(mid) else (mid, hi)
        return lo

    def try_candidate(self, pose: np.ndarray, preshape: np.ndarray,
                      rng: np.random.Generator) -> Grasp | None:
        """IK, clearance, auto-close and quality for one palm pose; None if rejected."""
        seed = np.zeros(self.model.dof)
        seed[self.model.index(ARM_JOINTS)] = self.ik_start
        seed[7:] = preshape
        result = self.ik.solve(pose, seed, rng=rng, restarts=4)
        if not result.success[0]:
            return None
        q0 = result.q[0]
        if not self.walk.arm_clear(q0):
            return None
        draw = self.engine.run(q0[None])  # with a table: start_collision if in it
        if draw.outcome[0] != FORCE_CLOSURE or self.closed_in_table(q0, draw.hand[0]):
            return None
        k = int(draw.n_contacts[0])
        if k > self.settings.max_contacts:
            return None
        palm = self.kin.pose(q0, PALM_LINK)[0]
        return grasp_from_draw(draw, self.obj.name, q0, palm,
                               meta={"elbow_angle": float(self.ik.elbow_angle(q0[None])[0])})

    def plan(self, count: int, seed: int = 0, *, max_attempts: int | None = None,
             time_budget: float | None = None, progress: bool = False) -> list[Grasp]:
        """Up to ``count`` force-closure grasps (fewer if the budget runs out).

        Args:
            count: grasps wanted.
            seed: random seed.
            max_attempts: palm poses to try at most (default 400 per grasp wanted).
            time_budget: seconds at most.
            progress: tqdm bar on stderr.
        """
        rng = np.random.default_rng(seed)
        max_attempts = max_attempts or 400 * count
        start = time.perf_counter()
        found: list[Grasp] = []
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=count, desc=f"planning {self.obj.name}", unit="grasp",
                       file=sys.stderr, disable=None)
        attempts = 0
        while len(found) < count and attempts < max_attempts:
            if time_budget is not None and time.perf_counter() - start > time_budget:
                break
            attempts += 1
            sample = self.sample_pose(rng)
            if sample is None:
                continue
            grasp = self.try_candidate(*sample, rng)
            if grasp is not None:
                found.append(Grasp(**{**grasp.__dict__, "id": str(len(found))}))
                if bar is not None:
                    bar.update(1)
        if bar is not None:
            bar.close()
        log.info("%s: %d grasps from %d palm poses", self.obj.name, len(found), attempts)
        return found
