"""Grasp planning for any description robot's hand, GraspIt-style: sampled approaches, IK,
auto-close (the sampler for hands that are not parallel jaws; two-finger hands also have the
antipodal one, :mod:`~kinegrasp_env.toolkit.grasp_planner`).

1. **Approach**: a direction d from the robot's side or from above (azimuth and elevation
   drawn in :class:`ApproachSettings`' ranges), an aim point drawn in the middle half of the
   object's bounding box, and where the ray along d through the aim enters the object
   (exact: :meth:`~kinegrasp_env.world.objects.GraspObject.ray_entry`).
2. **Palm pose and pre-shape**: the hand's approach axis (:func:`~kinegrasp_env.robot.
   hand_frame.hand_frame`: palm origin to fingertip centre at the open pre-shape) along d,
   rolled about it by a drawn angle, the fingertip centre ``depth`` beyond the entry point
   along d (drawn: the fingertips reach past the surface and close on it); the hand's
   pre-shape drawn from the description's ``preshapes`` (:mod:`~kinegrasp_env.robot.
   preshapes`; the ``open`` one without them).
3. **IK, clearance, closing**: as the antipodal planner: damped least squares from random
   restarts (:func:`~kinegrasp_env.robot.palm_ik.solve_palm_ik`), every link but the fingers
   :attr:`~kinegrasp_env.toolkit.plan_checks.PlannerSettings.min_clearance` from the
   object, the hand closed from its pre-shape by the reference engine; kept when in
   force closure with the robot's contact model.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
from kinegrasp_env.montecarlo.nominal import grasp_from_draw
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.hand_frame import hand_frame
from kinegrasp_env.robot.kinematics import Kinematics, axis_angle_matrix
from kinegrasp_env.robot.palm_ik import solve_palm_ik
from kinegrasp_env.toolkit.plan_checks import (
    PlannerSettings,
    PlanTally,
    arm_meta,
    planned_closing,
    self_motion,
)
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import GraspObject


@dataclass(frozen=True)
class ApproachSettings:
    """The approach sampler's ranges (radians, metres)."""

    azimuth: tuple[float, float] = (-1.2, 1.2)  # about +z from +x (the robot faces +x)
    elevation: tuple[float, float] = (-0.2, 1.45)  # the approach below the horizontal
    depth: tuple[float, float] = (0.0, 0.03)  # fingertip centre beyond the surface


def aligned(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) a rotation taking unit vector a (3,) to unit vector b (3,)."""
    axis = np.cross(a, b)
    sin, cos = np.linalg.norm(axis), float(a @ b)
    if sin < 1e-12:  # parallel or opposite
        if cos > 0:
            return np.eye(3)
        other = np.eye(3)[np.argmin(np.abs(a))]
        axis = np.cross(a, other)
        return axis_angle_matrix(axis / np.linalg.norm(axis), np.pi)
    return axis_angle_matrix(axis / sin, float(np.arctan2(sin, cos)))


def approach_poses(obj: GraspObject, centre: np.ndarray, approach: np.ndarray,
                   settings: ApproachSettings, rng: np.random.Generator, count: int
                   ) -> tuple[np.ndarray, list[dict]]:
    """Up to ``count`` palm poses (k, 4, 4) in the world frame (step 1-2 of the module; a
    ray that misses the object gives none) and each one's draws (direction, roll, depth).

    Args:
        obj: the object at its pose; centre, approach: the hand's fingertip centre (3,) and
            unit approach axis (3,) in the palm frame.
    """
    poses, meta = [], []
    lo, hi = obj.mesh.bounds
    rot = obj.pose[:3, :3]
    reach = 2.0 * obj.r_max + 0.1
    for _ in range(count):
        azimuth, elevation = rng.uniform(*settings.azimuth), rng.uniform(*settings.elevation)
        d = np.array([np.cos(elevation) * np.cos(azimuth),
                      np.cos(elevation) * np.sin(azimuth), -np.sin(elevation)])
        aim = lo + rng.uniform(0.25, 0.75, size=3) * (hi - lo)  # object frame
        roll, depth = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(*settings.depth)
        entry = obj.ray_entry(aim - (rot.T @ d) * reach, rot.T @ d)
        if entry is None:
            continue
        surface = obj.to_world(aim - (rot.T @ d) * (reach - entry))
        pose = np.eye(4)
        pose[:3, :3] = axis_angle_matrix(d, roll) @ aligned(approach, d)
        pose[:3, 3] = surface + depth * d - pose[:3, :3] @ centre
        poses.append(pose)
        meta.append({"direction": d.tolist(), "roll": float(roll), "depth": float(depth)})
    return np.array(poses).reshape(-1, 4, 4), meta


def plan_approach_grasps(description: RobotDescription, object_name: str, *, count: int,
                         rng: np.random.Generator, settings: PlannerSettings,
                         friction: float = 0.5, time_budget: float | None = None,
                         approach: ApproachSettings | None = None,
                         tally: PlanTally | None = None) -> list[Grasp]:
    """Up to ``count`` grasps of any hand of ``description`` on the object (the module's
    steps; ``settings.attempts`` approaches drawn), each in force closure at its nominal
    closing; ``time_budget`` (seconds): no candidate is closed once it is spent; ``tally``:
    filled with what became of the palm poses."""
    deadline = None if time_budget is None else time.monotonic() + float(time_budget)
    approach = approach or ApproachSettings()
    frame = hand_frame(description)
    found: list[Grasp] = []
    with RobotReferenceEngine(description, object_name, friction=friction) as engine:
        kin = Kinematics(description.model)
        motion = self_motion(description, kin)
        targets, drawn = approach_poses(engine.obj, frame.centre, frame.approach, approach,
                                        rng, settings.attempts)
        hands = description.drawn_configurations(rng, len(targets))
        arms, reached = solve_palm_ik(kin, description, targets, rng,
                                      restarts=settings.ik_restarts,
                                      iterations=settings.ik_iterations)
        if tally is not None:
            tally.drawn += len(targets)
            tally.dropped["out of reach"] += int((~reached).sum())
        for c in np.flatnonzero(reached):
            if len(found) >= count or (deadline is not None and time.monotonic() > deadline):
                break
            q0 = hands[c].copy()
            q0[:description.arm_dof] = arms[c]
            draws = planned_closing(engine, q0, settings, tally)
            if draws is None:
                continue
            found.append(grasp_from_draw(
                draws, object_name, q0, kin.pose(q0, description.palm_link)[0],
                grasp_id=str(len(found)), robot=description.name,
                meta={"planner": "approach", **drawn[c], **arm_meta(motion, q0),
                      "contact_model": description.contact_model,
                      "settings": {**asdict(settings), **asdict(approach)}}))
    return found
