"""Grasp planning for any catalog robot: a parallel-jaw hand's antipodal pairs, palm poses,
IK (below); any other hand's sampled approaches (:mod:`~kinegrasp_env.toolkit.
approach_planner`).

1. **Antipodal pairs** (Dex-Net's antipodal sampler): points and outward normals sampled on
   the object's surface (``trimesh.sample.sample_surface``, seeded); a pair (p1, p2) is kept
   when its normals are nearly opposite (n1 . n2 <= -cos ``max_normal_angle``), the line
   p1 -> p2 lies within ``max_normal_angle`` of each inward normal (so within the friction
   cones for mu >= tan of it) and its width |p2 - p1| fits the jaws' opening less
   ``2 * width_margin``.
2. **Palm pose**: the jaw frame of the hand (:func:`jaw_frame`: in the palm frame at the open
   pre-shape, the closing axis from one fingertip link to the other, the approach axis from
   the palm to the jaws, and the jaws' centre) is aligned with the pair: closing axis along
   n2 - n1 (the pads parallel to the faces), the pair's midpoint ``depth`` beyond the jaws'
   centre along the approach (sampled in [0, ``max_depth``]: towards the fingertips),
   approach axis at a sampled angle about the closing axis, kept where it points downward
   (approach . -z >= ``min_downward``);
   the first ``attempts`` pairs are tried.
3. **IK**: damped least squares on the arm joints for that palm pose
   (:func:`~kinegrasp_env.robot.palm_ik.solve_palm_ik`: :class:`~kinegrasp_env.robot.
   kinematics.Kinematics`' pose and Jacobian, random restarts within the joint limits,
   joints within their limits); the hand's pre-shape drawn from the description's
   ``preshapes`` (:mod:`~kinegrasp_env.robot.preshapes`; the ``open`` one without them).
4. **Checks**: at q0 every robot link but the fingers clears the object by
   ``min_clearance`` (pybullet's distance: the palm is not grazing the object); the nominal
   closing (:class:`~kinegrasp_env.montecarlo.evaluate.
   RobotReferenceEngine`, sigma 0) must start clear of the object and end in force closure
   with the robot's contact model; the grasps kept record their robot.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from kinegrasp_env.counts import check_count
from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
from kinegrasp_env.robot.catalog import as_description
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.hand_frame import hand_frame
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.palm_ik import solve_palm_ik
from kinegrasp_env.sampling.noise import SeedLike, as_generator, check_seed
from kinegrasp_env.toolkit.approach_planner import plan_approach_grasps
from kinegrasp_env.toolkit.plan_checks import (
    PlannerSettings,
    PlanTally,
    arm_meta,
    attempts_for,
    planned_closing,
    self_motion,
)
from kinegrasp_env.world.grasps import Grasp


@dataclass(frozen=True)
class JawFrame:
    """The jaws of a two-finger hand in its palm frame at the open pre-shape.

    Attributes:
        center: (3,) midpoint of the fingertip links' centres (:func:`~kinegrasp_env.robot.
            hand_frame.hand_frame`'s: the centres of their bounding boxes in the palm frame).
        closing: (3,) unit axis from the first fingertip link to the second.
        approach: (3,) unit axis from the palm origin towards ``center``, normal to closing.
        opening: the fingers' clearance at the open pre-shape (pybullet's distance between
            the two fingers' touching links: :func:`jaw_links`).
    """

    center: np.ndarray
    closing: np.ndarray
    approach: np.ndarray
    opening: float


def jaw_frame(engine: RobotReferenceEngine) -> JawFrame:
    """The hand's :class:`JawFrame` (measured in the engine's pybullet world).

    Raises:
        ValueError: the hand does not have exactly two fingers.
    """
    description = engine.description
    if len(description.fingers) != 2:
        raise ValueError(f"robot {description.name!r} has {len(description.fingers)} fingers; "
                         "the antipodal planner plans for two (parallel jaws)")
    world = engine.world
    q = description.open_configuration()
    q[:description.arm_dof] = np.clip(0.0, description.model.lower[:description.arm_dof],
                                      description.model.upper[:description.arm_dof])
    world.set_configuration(q)
    robot = world.bodies["robot"]
    jaws = [world.link_index[link] for link in jaw_links(description)]
    centres = hand_frame(description).tip_centres
    closing = centres[1] - centres[0]
    closing /= np.linalg.norm(closing)
    center = 0.5 * (centres[0] + centres[1])
    approach = center - closing * (center @ closing)
    approach /= np.linalg.norm(approach)
    rows = world.bullet.getClosestPoints(robot, robot, 1.0, linkIndexA=jaws[0],
                                         linkIndexB=jaws[1])
    opening = min(r[8] for r in rows)
    return JawFrame(center, closing, approach, float(opening))


def jaw_links(description: RobotDescription) -> list[str]:
    """Each finger's link nearest its tip that has collision geometry (the tip itself where
    it has some; a pad fixed below a moving link has its shapes on that link in a catalog
    robot: :mod:`~kinegrasp_env.robot.fixed_collisions`)."""
    from kinegrasp_env.robot.urdf_meshes import collision_links

    touching = collision_links(description.urdf)
    return [[link for link in (*finger.links, finger.tip) if link in touching][-1]
            for finger in description.fingers]


def antipodal_pairs(mesh, settings: PlannerSettings, max_width: float,
                    rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Antipodal pairs of a trimesh ``mesh``: points (P, 2, 3) and their outward unit normals
    (P, 2, 3), object frame. First the pairs among the surface samples, shuffled; then, in
    sample order, each sample with the point where a ray from it into the object leaves it
    again (Dex-Net's partner search: the only way to find the two faces of a thin wall,
    whose opposite samples almost never line up)."""
    import trimesh

    points, faces = trimesh.sample.sample_surface(mesh, settings.surface_samples,
                                                  seed=int(rng.integers(2**31)))
    normals = mesh.face_normals[faces]  # outward
    cos = np.cos(settings.max_normal_angle)
    d = points[None, :, :] - points[:, None, :]  # d[i, j] = p_j - p_i
    width = np.linalg.norm(d, axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = d / width[..., None]
    keep = ((normals @ normals.T <= -cos) & (width > 1e-6) & (width <= max_width)
            & (np.einsum("ijk,ik->ij", u, -normals) >= cos)
            & (np.einsum("ijk,jk->ij", u, normals) >= cos))
    i, j = np.nonzero(np.triu(keep, 1))
    order = rng.permutation(len(i))
    i, j = i[order], j[order]
    rays = ray_partners(mesh, points, normals, cos, max_width)
    return (np.concatenate([np.stack([points[i], points[j]], axis=1), rays[0]]),
            np.concatenate([np.stack([normals[i], normals[j]], axis=1), rays[1]]))


#: How far inside the surface a partner ray starts (metres): past the sample's own face.
RAY_OFFSET = 1e-6


def ray_partners(mesh, points: np.ndarray, normals: np.ndarray, cos: float,
                 max_width: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (P, 2, 3) and outward normals (P, 2, 3) of each sample (points, normals (S, 3))
    with the first face a ray from it along its inward normal meets, kept where that face's
    normal is within the cone angle (arccos ``cos``) of the opposite one and the pair is at
    most ``max_width`` apart; in sample order."""
    located, ray, triangle = mesh.ray.intersects_location(
        points - RAY_OFFSET * normals, -normals, multiple_hits=False)
    partner_normals = mesh.face_normals[triangle]
    width = np.linalg.norm(located - points[ray], axis=1)
    keep = ((np.einsum("ij,ij->i", partner_normals, normals[ray]) <= -cos)
            & (width > 1e-6) & (width <= max_width))
    order = np.argsort(ray[keep], kind="stable")
    first, second = points[ray][keep][order], located[keep][order]
    return (np.stack([first, second], axis=1),
            np.stack([normals[ray][keep][order], partner_normals[keep][order]], axis=1))


def palm_pose_for(pair_world: np.ndarray, normals_world: np.ndarray, jaw: JawFrame,
                  angle: float, depth: float) -> np.ndarray:
    """(4, 4) palm pose putting the jaws on a pair (2, 3) with outward normals (2, 3) (world
    frame): closing axis along n2 - n1 (the pads parallel to the two faces), approach at
    ``angle`` about it, the pair's midpoint ``depth`` beyond the jaws' centre along the
    approach."""
    a = normals_world[1] - normals_world[0]
    a /= np.linalg.norm(a)
    helper = np.eye(3)[np.argmin(np.abs(a))]
    b1 = np.cross(a, helper)
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(a, b1)
    approach = np.cos(angle) * b1 + np.sin(angle) * b2
    world_axes = np.stack([a, approach, np.cross(a, approach)], axis=1)
    palm_axes = np.stack([jaw.closing, jaw.approach, np.cross(jaw.closing, jaw.approach)],
                         axis=1)
    pose = np.eye(4)
    pose[:3, :3] = world_axes @ palm_axes.T
    target = pair_world.mean(axis=0) - depth * approach
    pose[:3, 3] = target - pose[:3, :3] @ jaw.center
    return pose


def plan_grasps(robot: str | RobotDescription, object_name: str, *, count: int = 4,
                seed: SeedLike = 0, settings: PlannerSettings | None = None,
                friction: float = 0.5, time_budget: float | None = None,
                tally: PlanTally | None = None) -> list[Grasp]:
    """Up to ``count`` grasps of a robot on an object, each in force closure at its nominal
    closing: a two-finger hand's by the module's antipodal steps, any other hand's by
    sampled approaches (:func:`~kinegrasp_env.toolkit.approach_planner.
    plan_approach_grasps`); ``time_budget`` (seconds): no candidate is closed once it is
    spent (the grasps found so far are returned); ``tally``: filled with what became of the
    palm poses (:class:`~kinegrasp_env.toolkit.plan_checks.PlanTally`); ``settings``
    default: those of :class:`~kinegrasp_env.toolkit.plan_checks.PlannerSettings`, trying
    :func:`~kinegrasp_env.toolkit.plan_checks.attempts_for` ``count`` palm poses.

    Raises:
        ValueError: bad count or seed.
    """
    import time

    deadline = None if time_budget is None else time.monotonic() + float(time_budget)
    check_count(count, "count")
    settings = settings or PlannerSettings(attempts=attempts_for(count))
    check_seed(seed)
    rng = as_generator(seed)
    description = as_description(robot)
    if len(description.fingers) != 2:
        return plan_approach_grasps(description, object_name, count=count, rng=rng,
                                    settings=settings, friction=friction,
                                    time_budget=time_budget, tally=tally)
    found: list[Grasp] = []
    with RobotReferenceEngine(description, object_name, friction=friction) as engine:
        jaw = jaw_frame(engine)
        kin = Kinematics(description.model)
        motion = self_motion(description, kin)
        obj = engine.obj
        pairs, normals = antipodal_pairs(obj.mesh, settings,
                                         jaw.opening - 2 * settings.width_margin, rng)
        pairs, normals = pairs[:settings.attempts], normals[:settings.attempts]
        rot = obj.pose[:3, :3]
        angles = rng.uniform(0.0, 2.0 * np.pi, len(pairs))
        depths = rng.uniform(0.0, settings.max_depth, len(pairs))
        targets = np.array([palm_pose_for(obj.to_world(pair), n @ rot.T, jaw, angle, depth)
                            for pair, n, angle, depth in zip(pairs, normals, angles, depths,
                                                             strict=True)])
        targets = targets.reshape(-1, 4, 4)
        hands = description.drawn_configurations(rng, len(targets))
        downward = -(targets[:, :3, :3] @ jaw.approach)[:, 2] >= settings.min_downward
        arms, reached = solve_palm_ik(kin, description, targets[downward], rng,
                                      restarts=settings.ik_restarts,
                                      iterations=settings.ik_iterations)
        if tally is not None:
            tally.drawn += len(targets)
            tally.dropped["facing up"] += int((~downward).sum())
            tally.dropped["out of reach"] += int((~reached).sum())
        for c, arm in zip(np.flatnonzero(downward)[reached], arms[reached], strict=True):
            if len(found) >= count or (deadline is not None and time.monotonic() > deadline):
                break
            pair, angle, depth = pairs[c], float(angles[c]), float(depths[c])
            q0 = hands[c].copy()
            q0[:description.arm_dof] = arm
            draws = planned_closing(engine, q0, settings, tally)
            if draws is None:
                continue
            k = int(draws.n_contacts[0])
            found.append(Grasp(
                object_name, q0, kin.pose(q0, description.palm_link)[0],
                draws.points[0, :k].copy(), draws.normals[0, :k].copy(),
                draws.finger[0, :k].astype(int), draws.link[0, :k].astype(int),
                float(draws.quality[0]), str(len(found)),
                {"planner": "antipodal", "pair": pair.tolist(), "approach_angle": angle,
                 "depth": depth, **arm_meta(motion, q0),
                 "contact_model": description.contact_model,
                 "settings": asdict(settings)},
                description.name))
    return found
