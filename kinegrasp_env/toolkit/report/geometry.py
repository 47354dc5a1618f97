"""Triangle meshes for the report's 3-D views: the robot's link visuals placed by forward
kinematics, friction cones, and the arm's skeleton.

The robot's visuals are read from the shipped ``kuka_sdh.urdf`` (the arm's link meshes, the
hand's cylinders and capsules, the URDF's colours), so the picture is the model the engines
use. Lengths in metres; poses are (4, 4) homogeneous transforms.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import trimesh

from kinegrasp_env.montecarlo.evaluate import (
    DEFAULT_CHUNK,
    Noise,
    chunk_configurations,
    chunk_sizes,
)
from kinegrasp_env.quality.wrenches import friction_cone_edges
from kinegrasp_env.robot.default_robot import (
    default_description,
    kuka_sdh,
    urdf_path,
)
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.model import rpy_to_matrix
from kinegrasp_env.world.objects import GraspObject

CAPSULE_COUNT = (12, 12)
CYLINDER_SECTIONS = 16


@dataclass(frozen=True, eq=False)
class Visual:
    """One visual element of a link.

    Attributes:
        link: link name.
        vertices: (V, 3) in the link frame (metres); faces: (F, 3) vertex indices.
        color: ``rgb(r, g, b)`` from the URDF material.
        kind: ``mesh``, ``cylinder``, ``capsule``, ``box`` or ``sphere``.
    """

    link: str
    vertices: np.ndarray
    faces: np.ndarray
    color: str
    kind: str


def _rgb(rgba: str) -> str:
    r, g, b = (round(255 * float(v)) for v in rgba.split()[:3])
    return f"rgb({r}, {g}, {b})"


def _primitive(geometry: ET.Element) -> tuple[str, trimesh.Trimesh]:
    """The visual's kind and its mesh in the visual's own frame."""
    element = next(iter(geometry))
    if element.tag == "mesh":
        mesh = trimesh.load(urdf_path().parent / element.get("filename"), force="mesh")
        scale = [float(v) for v in element.get("scale", "1 1 1").split()]
        mesh.apply_scale(scale)
        return "mesh", mesh
    if element.tag == "cylinder":
        return "cylinder", trimesh.creation.cylinder(
            radius=float(element.get("radius")), height=float(element.get("length")),
            sections=CYLINDER_SECTIONS)
    if element.tag == "capsule":
        return "capsule", trimesh.creation.capsule(
            height=float(element.get("length")), radius=float(element.get("radius")),
            count=list(CAPSULE_COUNT))
    if element.tag == "box":
        return "box", trimesh.creation.box([float(v) for v in element.get("size").split()])
    if element.tag == "sphere":
        return "sphere", trimesh.creation.icosphere(2, float(element.get("radius")))
    raise ValueError(f"unsupported visual geometry {element.tag!r} in {urdf_path().name}")


@lru_cache(maxsize=1)
def robot_visuals() -> tuple[Visual, ...]:
    """Every link visual of the shipped arm+hand URDF, in its link frame."""
    root = ET.parse(urdf_path()).getroot()
    colors = {m.get("name"): _rgb(m.find("color").get("rgba"))
              for m in root.findall("material") if m.find("color") is not None}
    out = []
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            frame = np.eye(4)
            origin = visual.find("origin")
            if origin is not None:
                frame[:3, :3] = rpy_to_matrix(*map(float, origin.get("rpy", "0 0 0").split()))
                frame[:3, 3] = [float(v) for v in origin.get("xyz", "0 0 0").split()]
            kind, mesh = _primitive(visual.find("geometry"))
            material = visual.find("material")
            color = "rgb(150, 150, 150)"
            if material is not None:
                inline = material.find("color")
                color = _rgb(inline.get("rgba")) if inline is not None else \
                    colors.get(material.get("name"), color)
            vertices = np.asarray(mesh.vertices) @ frame[:3, :3].T + frame[:3, 3]
            out.append(Visual(link.get("name"), vertices, np.asarray(mesh.faces), color, kind))
    return tuple(out)


@lru_cache(maxsize=1)
def kinematics() -> Kinematics:
    return Kinematics(kuka_sdh())


def transform(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Points (..., 3) mapped by a (4, 4) pose."""
    return np.asarray(points) @ pose[:3, :3].T + pose[:3, 3]


@lru_cache(maxsize=1)
def skeleton_links() -> tuple[str, ...]:
    """Links whose frame origins make the default robot's skeleton: its chain from the base
    to the palm (its description's)."""
    description = default_description()
    chain = Kinematics(description.model).chain(description.palm_link)
    return (description.model.base_link, *(joint.child for joint in chain))


@lru_cache(maxsize=1)
def arm_links() -> frozenset[str]:
    """The default robot's arm links: its base and each arm joint's child."""
    description = default_description()
    return frozenset((description.model.base_link,
                      *(description.model.joint(j).child for j in description.arm_joints)))


def visual_poses(q: np.ndarray, frame: np.ndarray | None = None, *, arm: bool = True,
                 hand: bool = True) -> list[tuple[int, Visual, np.ndarray]]:
    """Where each link visual is at configuration q (14,).

    Args:
        q: arm+hand configuration, radians.
        frame: (4, 4) world -> target frame (default: the world frame itself).
        arm, hand: include the arm's links (:func:`arm_links`), the hand's.

    Returns:
        (index in :func:`robot_visuals`, visual, (4, 4) pose of its link frame in ``frame``).
    """
    chosen = [(i, v) for i, v in enumerate(robot_visuals())
              if (v.link in arm_links() and arm) or (v.link not in arm_links() and hand)]
    poses = kinematics().forward(np.asarray(q, dtype=float), [v.link for _, v in chosen])
    to_frame = np.eye(4) if frame is None else frame
    return [(i, v, to_frame @ poses[v.link][0]) for i, v in chosen]


def skeletons(q: np.ndarray, frame: np.ndarray | None = None) -> np.ndarray:
    """(n, L, 3) origins of :func:`skeleton_links` for configurations q (n, 14)."""
    links = skeleton_links()
    poses = kinematics().forward(np.atleast_2d(q), links)
    points = np.stack([poses[link][:, :3, 3] for link in links], axis=1)
    return points if frame is None else transform(points, frame)


def closed_configuration(q0: np.ndarray, obj: GraspObject) -> tuple[np.ndarray, bool]:
    """The grasp as the engines see it: the arm at q0 (14,), the hand closed on ``obj`` from
    q0's pre-shape by the reference auto-close (pybullet).

    Returns:
        (q (14,) with the closed hand DOF, True), or (q0, False) when the hand starts in
        collision and does not close.
    """
    from kinegrasp_env.closing.generic_reference import RobotWorld

    q0 = np.asarray(q0, dtype=float)
    description = default_description()
    world = RobotWorld(description, obj)
    try:
        result = world.auto_close(q0)
    finally:
        world.close()
    if result.start_collision:
        return q0.copy(), False
    q = q0.copy()
    for j, name in enumerate(description.hand_joints):
        if name in result.joints:
            q[description.arm_dof + j] = result.joints[name]
    return q, True


def noisy_configurations(q0: np.ndarray, noise: Noise, seed: int, samples: int,
                         count: int, chunk: int = DEFAULT_CHUNK) -> np.ndarray:
    """The first ``count`` draws' configurations (count, 14) of a run: exactly those that
    ``evaluate_grasp(..., seed, chunk=chunk)`` evaluates first (chunk 0's stream; a noise
    model's joint errors and hand offsets, not its palm, object and friction errors)."""
    first = chunk_sizes(samples, chunk)[0]
    return chunk_configurations(q0, noise, seed, [(0, first)])[:min(count, first)]


def cone_meshes(points: np.ndarray, normals: np.ndarray, friction: float, num_edges: int,
                height: float) -> tuple[np.ndarray, np.ndarray]:
    """Linearized friction cones as one triangle mesh, drawn outside the object.

    Each cone has its apex at a contact point p (k, 3) and its ``num_edges`` edges along
    -f_j (the mirror of the cone edges f_j of docs/conventions.md, so the cone stands on the
    surface instead of inside the object), scaled so its axis is ``height`` metres long.

    Returns:
        vertices (k (m + 1), 3) and faces (k m, 3).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    edges = friction_cone_edges(np.asarray(normals, dtype=float).reshape(-1, 3), friction,
                                num_edges)
    m = num_edges
    ring = points[:, None, :] - height * edges  # normal component of f_j is 1
    vertices = np.concatenate([points[:, None, :], ring], axis=1).reshape(-1, 3)
    base = (m + 1) * np.arange(len(points))[:, None]
    j = np.arange(m)
    faces = np.stack([np.zeros(m, int), 1 + j, 1 + (j + 1) % m], axis=1)
    return vertices, (base[:, None, :] + faces[None]).reshape(-1, 3)
