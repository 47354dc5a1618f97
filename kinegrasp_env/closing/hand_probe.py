"""The hand of one reference auto-close (:mod:`kinegrasp_env.closing.reference`): its
pybullet joints, and its finger capsules' axes and exact gaps.

Within ``EXACT_BAND`` of contact a finger capsule's gap is computed exactly, from its axis
and the object's convex parts. The capsule axes come from the hand URDF's kinematics in
double precision (:func:`zero_flexion_frames` once per pre-shape, then :func:`finger_axes` per
evaluation), not from pybullet's link states: ``getLinkState``'s link frame (its entries 4
and 5) carries single-precision rounding (up to ~5e-7 per entry measured; pybullet's inertial
frame, which its collision shapes hang from, agrees with these axes to ~1e-15), which kept
the secant polish from reaching ``POLISH_TOL`` and cost two pybullet calls per evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from kinegrasp_env.assets import asset_path
from kinegrasp_env.closing.finger_axes import finger_axes
from kinegrasp_env.closing.hand_geometry import Shape, hand_shapes
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.robot.default_robot import FINGERS, HAND_JOINTS, SPREAD_JOINTS, kuka_sdh
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.model import load_urdf
from kinegrasp_env.world.sim import GraspWorld


def hand_joint_values(preshape: np.ndarray) -> dict[str, float]:
    """Every hand joint's value (coupled spread expanded) from the 7 hand DOF."""
    model = kuka_sdh()
    q = np.zeros(model.dof)
    q[model.index(HAND_JOINTS)] = preshape
    values = model.expand(q)
    return {name: float(values[name]) for name in values if not name.startswith("lbr_")}


@dataclass(frozen=True)
class FingerChain:
    """What places one finger's capsule axes, from the hand URDF (the file pybullet loads).

    Attributes:
        axis_p, axis_d: (3,) unit axes of the proximal and distal joints.
        distal_origin: (4, 4) the distal joint's origin in the proximal link frame.
        ends_p, ends_d: (2, 3) capsule axis end points in the proximal and distal link frames,
            metres.
        radii: (2,) capsule radii (proximal, distal), metres.
    """

    axis_p: np.ndarray
    axis_d: np.ndarray
    distal_origin: np.ndarray
    ends_p: np.ndarray
    ends_d: np.ndarray
    radii: np.ndarray


@lru_cache(maxsize=1)
def hand_kinematics() -> Kinematics:
    """Forward kinematics of the hand alone (``sdh_hand.urdf``, root = the flange frame)."""
    return Kinematics(load_urdf(asset_path("robots", "sdh_hand.urdf"), actuated=HAND_JOINTS))


@lru_cache(maxsize=1)
def finger_chains() -> tuple[FingerChain, ...]:
    """The :class:`FingerChain` of fingers 1, 2, 3."""
    model = hand_kinematics().model
    chains = []
    for (prox, dist, _, _), (shape_p, shape_d) in zip(FINGERS, finger_capsules(), strict=True):
        chains.append(FingerChain(
            model.joint(prox).axis, model.joint(dist).axis, model.joint(dist).origin,
            np.array(shape_p.axis_points()), np.array(shape_d.axis_points()),
            np.array([shape_p.radius, shape_d.radius])))
    return tuple(chains)


@lru_cache(maxsize=64)
def zero_flexion_frames(spread: float) -> np.ndarray:
    """(3, 4, 4) frames of the fingers' proximal links at zero flexion, in the hand root
    frame, for a spread (radians); cached: a Monte Carlo run repeats one pre-shape."""
    q = np.zeros(len(HAND_JOINTS))
    q[HAND_JOINTS.index(SPREAD_JOINTS[0])] = spread
    frames = hand_kinematics().forward(q, [f[2] for f in FINGERS])
    out = np.stack([frames[f[2]][0] for f in FINGERS])
    out.setflags(write=False)  # shared by the cache
    return out


class HandProbe:
    """The hand of one auto-close: its pybullet joints and its finger capsules' exact gaps.

    pybullet's joints are reset only where the value changed (resetting one to its current
    value leaves the state as it was). A finger capsule's exact closest pair with the object
    comes from its axis, placed by the proximal joint frame of the draw (hand root and spread,
    object frame) and the finger's two flexions (:func:`finger_axes`), not from pybullet.
    """

    def __init__(self, world: GraspWorld) -> None:
        self.world, self.obj = world, world.obj
        self.hand = world.bodies["hand"]
        self.body = world.bodies["object"]
        self.reset_joints = world.bullet.resetJointStatesMultiDof  # bound once per close
        self.closest_points = world.bullet.getClosestPoints
        self.joint_index = world.joint_index
        self.joints: dict[int, float] = {}
        self.chains = finger_chains()
        #: pybullet link index -> (finger, link 0 proximal / 1 distal)
        self.capsules = {world.link_index[f[2 + link]]: (i, link)
                         for i, f in enumerate(FINGERS) for link in (0, 1)}
        self.frames = np.empty((3, 4, 4))

    def set_hand(self, root_pose: np.ndarray, preshape: np.ndarray) -> None:
        """Place the hand root ((4, 4) world) and set every hand joint from the pre-shape."""
        joints = hand_joint_values(preshape)
        self.world.set_hand(root_pose, joints)
        self.joints = {self.joint_index[name]: float(v) for name, v in joints.items()}
        self.frames = self.obj.pose_inverse @ root_pose @ zero_flexion_frames(float(preshape[0]))

    def set_joints(self, values: dict[str, float]) -> None:
        """Set hand joints by name (radians) in pybullet, those that changed in one call."""
        joints, targets = [], []
        for name, value in values.items():
            joint, value = self.joint_index[name], float(value)
            if self.joints.get(joint) != value:
                joints.append(joint)
                targets.append([value])
                self.joints[joint] = value
        if joints:
            self.reset_joints(self.hand, joints, targets)

    def axes(self, finger: int, prox: float, dist: float, links) -> np.ndarray:
        """Capsule axes (m, 2, 3) [a, b] of a finger's links (0 proximal, 1 distal) at
        flexions prox, dist (radians), object frame."""
        chain = self.chains[finger]
        ends = finger_axes(self.frames[finger:finger + 1], chain.axis_p, np.array([prox]),
                           chain.distal_origin, chain.axis_d, np.array([dist]),
                           chain.ends_p, chain.ends_d)[0].reshape(2, 2, 3)
        return ends[list(links)]

    def pairs(self, axes: np.ndarray) -> tuple[np.ndarray, ...]:
        """Exact closest pairs of capsule axes (m, 2, 3) and the object: (on the object
        (m, 3), on the axis (m, 3), axis distance (m,), part (m,))."""
        return closest_to_segments(self.obj, axes[:, 0], axes[:, 1])

    def radii(self, finger: int, links) -> np.ndarray:
        """Capsule radii (m,) of a finger's links (0 proximal, 1 distal), metres."""
        return self.chains[finger].radii[list(links)]


@lru_cache(maxsize=1)
def finger_capsules() -> tuple[tuple[Shape, Shape], ...]:
    """(proximal, distal) capsule of each finger."""
    shapes = {s.link: s for s in hand_shapes()}
    return tuple((shapes[f[2]], shapes[f[3]]) for f in FINGERS)
