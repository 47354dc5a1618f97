"""A robot's picture and its geometry, both read by pybullet from the URDF in one way.

:func:`loaded_robot` loads the URDF (mesh paths resolved: :func:`resolved_urdf_text`) into a
DIRECT client of its own with the joints set. :func:`draw_robot` renders it with pybullet's
software renderer (the robot at its open configuration, seen from the front-left, the camera
aimed at the centre of its bounding box); :func:`robot_geometry` reads the same loaded robot's
triangles and link frames for the HTML reports' 3-D scenes:

- a link whose visuals are primitives (box, sphere, cylinder, capsule) is drawn from its
  visual geometry (pybullet's visual shape data: kind, dimensions, visual frame);
- a link with a mesh visual is drawn from its collision geometry (pybullet gives a visual
  mesh's file name only, not its triangles): each collision mesh as the convex hull of the
  vertices pybullet holds for it (``getMeshData``: what the closing touches), each collision
  primitive from its dimensions.

Lengths in metres; a pose is a (4, 4) homogeneous transform; link frames are the URDF's.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.robot.description import RobotDescription

#: pybullet geometry kinds (``GEOM_*``) -> names.
GEOMETRY_KINDS = {2: "sphere", 3: "box", 4: "cylinder", 5: "mesh", 6: "plane", 7: "capsule"}
CYLINDER_SECTIONS = 16
CAPSULE_COUNT = (12, 12)


def resolved_urdf_text(description: RobotDescription) -> str:
    """The URDF's text with every mesh path replaced by its resolved absolute path, so that
    any URDF reader finds the meshes wherever the file is written."""
    text = description.urdf.read_text()
    for mesh in {m.filename: m for m in description.meshes}.values():
        text = text.replace(f'"{mesh.filename}"', f'"{mesh.path.as_posix()}"')
    return text


@contextmanager
def loaded_robot(description: RobotDescription,
                 values: Mapping[str, float] | None = None) -> Iterator[tuple]:
    """The robot in a DIRECT pybullet client of its own, fixed at the origin.

    Args:
        description: the robot.
        values: movable joint name -> value (radians / metres); default: the open
            configuration (arm joints at 0, hand at the ``open`` pre-shape, mimics following).

    Yields:
        (client, body id, link name -> pybullet link index (-1: the base link)).
    """
    if values is None:
        values = description.model.expand(description.open_configuration())
    with quiet_c_output():  # pybullet's banner, "argv[0]=" on connect
        import pybullet
        from pybullet_utils.bullet_client import BulletClient

        bullet = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        with tempfile.TemporaryDirectory() as folder, quiet_c_output():  # mesh-loader notes
            urdf = Path(folder) / description.urdf.name
            urdf.write_text(resolved_urdf_text(description))
            body = bullet.loadURDF(str(urdf), useFixedBase=True)
        links = {description.model.base_link: -1}
        joints = {}
        for i in range(bullet.getNumJoints(body)):
            info = bullet.getJointInfo(body, i)
            joints[info[1].decode()] = i
            links[info[12].decode()] = i
        for joint, value in values.items():
            bullet.resetJointState(body, joints[joint], float(value))
        yield bullet, body, links
    finally:
        bullet.disconnect()


def _render(bullet, centre, distance: float, yaw: float, pitch: float, width: int,
            height: int, eye=None, up=None) -> tuple[np.ndarray, np.ndarray]:
    """((height, width, 3) uint8 image, (4, 4) world -> clip matrix) of a camera looking at
    ``centre`` (3,) from ``distance`` metres (pybullet's yaw and pitch, degrees), or from the
    point ``eye`` (3,) with the image's up direction ``up`` (3,)."""
    if eye is None:
        view = bullet.computeViewMatrixFromYawPitchRoll(list(map(float, centre)), distance,
                                                        yaw, pitch, 0.0, 2)
    else:
        view = bullet.computeViewMatrix(list(map(float, eye)), list(map(float, centre)),
                                        list(map(float, up)))
    projection = bullet.computeProjectionMatrixFOV(50.0, width / height, 0.05 * distance,
                                                   5.0 * distance)
    image = bullet.getCameraImage(width, height, view, projection,
                                  renderer=bullet.ER_TINY_RENDERER)[2]
    rgb = np.asarray(image, dtype=np.uint8).reshape(height, width, 4)[:, :, :3]
    # pybullet's matrices are column-major 4x4 lists
    clip = np.reshape(projection, (4, 4)).T @ np.reshape(view, (4, 4)).T
    return rgb, clip


def _pixels(clip: np.ndarray, points: np.ndarray, width: int, height: int) -> np.ndarray:
    """(n, 2) pixel coordinates of world points (n, 3) through ``clip`` (4, 4)."""
    h = np.c_[points, np.ones(len(points))] @ clip.T
    ndc = h[:, :2] / h[:, 3:4]
    return np.c_[(ndc[:, 0] + 1) * width / 2, (1 - ndc[:, 1]) * height / 2]


def _in_hand(description: RobotDescription, link: str) -> bool:
    """The link hangs below the palm link (the hand's own links)."""
    model = description.model
    parents = {j.child: j.parent for j in model.joints}
    while link in parents:
        link = parents[link]
        if link == description.palm_link:
            return True
    return False


#: The size of a panel's caption in :func:`draw_robot`'s picture (pixels).
CAPTION_SIZE = 14


def draw_robot(description: RobotDescription, out: str | Path, *, width: int = 640,
               height: int = 480, yaw: float = 50.0, pitch: float = -20.0,
               frame=None) -> Path:
    """Render the robot at its open configuration into the PNG ``out``.

    Args:
        description: the robot.
        out: the PNG file to write.
        width, height: image size, pixels (per panel).
        yaw, pitch: camera direction, degrees (pybullet's convention).
        frame: a :class:`~kinegrasp_env.robot.hand_frame.HandFrame` of the robot: a second
            panel, the hand close up, draws it (the approach axis blue from the palm frame's
            origin to the fingertip centre, each finger's closing direction red).

    Returns:
        The path written.
    """
    from PIL import Image, ImageDraw, ImageFont

    out = Path(out)
    # pybullet's first import (it prints a banner), the connection and the loading happen in
    # loaded_robot, C-level output silenced: importing pybullet here would print the banner
    with loaded_robot(description) as (bullet, body, links):
        boxes = [bullet.getAABB(body, i) for i in links.values()]
        low = np.min([b[0] for b in boxes], axis=0)
        high = np.max([b[1] for b in boxes], axis=0)
        centre, size = (low + high) / 2, float(np.linalg.norm(high - low))
        rgb, _ = _render(bullet, centre, 1.25 * size, yaw, pitch, width, height)
        panels = [Image.fromarray(rgb)]
        if frame is not None:
            palm = _link_frame(bullet, body, links[description.palm_link])
            world = (palm @ np.append(frame.centre, 1.0))[:3]
            # the hand alone: every link outside the hand drawn transparent
            hand_links = set(description.finger_links) | {description.palm_link}
            for name, index in links.items():
                if name not in hand_links and not _in_hand(description, name):
                    bullet.changeVisualShape(body, index, rgbaColor=[1, 1, 1, 0])
            # from the side: across the plane of the approach axis and the first finger's
            # closing direction (the jaws move in the image), the arm up
            side = np.cross(frame.approach, frame.closing[0])
            if np.linalg.norm(side) < 1e-6:
                side = np.cross(frame.approach, [1.0, 0.0, 0.0])
            side = palm[:3, :3] @ (side / np.linalg.norm(side))
            distance = 3.0 * max(frame.depth, 0.05)
            close, clip = _render(bullet, world, distance, yaw, pitch, width, height,
                                  eye=world + distance * side,
                                  up=-(palm[:3, :3] @ frame.approach))
            hand = Image.fromarray(close)
            pen = ImageDraw.Draw(hand)
            arrow = 0.6 * max(frame.depth, 0.05)
            origin, tip_end = palm[:3, 3], world
            ends = _pixels(clip, np.array([origin, tip_end]), width, height)
            pen.line([tuple(ends[0]), tuple(ends[1])], fill=(30, 80, 220), width=3)
            pen.ellipse([*(ends[1] - 4), *(ends[1] + 4)], fill=(30, 80, 220))
            for centre_tip, direction in zip(frame.tip_centres, frame.closing, strict=True):
                at = (palm @ np.append(centre_tip, 1.0))[:3]
                end = at + palm[:3, :3] @ direction * 0.5 * arrow
                a, b = _pixels(clip, np.array([at, end]), width, height)
                pen.line([tuple(a), tuple(b)], fill=(220, 40, 40), width=3)
            panels.append(hand)
    captions = [f"{description.name} at its open pre-shape"]
    if frame is not None:
        captions.append(f"the hand: approach axis (blue) to the fingertip centre, "
                        f"{frame.depth:.3f} m ahead; closing directions (red)")
    canvas = Image.new("RGB", (width * len(panels), height), (255, 255, 255))
    pen = ImageDraw.Draw(canvas)
    try:
        font = ImageFont.load_default(size=CAPTION_SIZE)
    except TypeError:  # Pillow before 10.1: its one bitmap font
        font = ImageFont.load_default()
    for i, (panel, caption) in enumerate(zip(panels, captions, strict=True)):
        canvas.paste(panel, (i * width, 0))
        pen.text((i * width + 10, 8), caption, fill=(40, 40, 40), font=font)
    out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(out, format="PNG")
    return out


@dataclass(frozen=True, eq=False)
class LinkShape:
    """One piece of a link's drawn geometry.

    Attributes:
        link: the link's name.
        vertices: (V, 3) in the link's URDF frame, metres; faces: (F, 3) vertex indices.
        color: ``rgb(r, g, b)`` (the link's visual colour).
        source: ``visual`` or ``collision`` (see the module docstring).
        kind: ``mesh``, ``box``, ``sphere``, ``cylinder`` or ``capsule``.
    """

    link: str
    vertices: np.ndarray
    faces: np.ndarray
    color: str
    source: str
    kind: str


@dataclass(frozen=True, eq=False)
class RobotGeometry:
    """A robot's drawn geometry and its link frames at some configurations.

    Attributes:
        shapes: every piece, links in the URDF's order.
        frames: per configuration asked for, link name -> (4, 4) world pose of its URDF
            frame (pybullet's kinematics).
    """

    shapes: tuple[LinkShape, ...]
    frames: tuple[dict[str, np.ndarray], ...]

    def links_from(self, source: str) -> tuple[str, ...]:
        """The links drawn from ``visual`` or ``collision`` geometry."""
        return tuple(dict.fromkeys(s.link for s in self.shapes if s.source == source))


def _pose(position: Sequence[float], quaternion: Sequence[float]) -> np.ndarray:
    """(4, 4) pose of a pybullet position and (x, y, z, w) quaternion."""
    from scipy.spatial.transform import Rotation

    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
    pose[:3, 3] = position
    return pose


def _primitive(kind: str, dimensions: Sequence[float]):
    """A trimesh of a pybullet primitive (dimensions as pybullet gives them), in its frame."""
    import trimesh

    if kind == "box":
        return trimesh.creation.box([float(v) for v in dimensions[:3]])  # full extents
    if kind == "sphere":
        return trimesh.creation.icosphere(2, float(dimensions[0]))
    if kind == "cylinder":
        return trimesh.creation.cylinder(radius=float(dimensions[1]),
                                         height=float(dimensions[0]),
                                         sections=CYLINDER_SECTIONS)
    if kind == "capsule":
        return trimesh.creation.capsule(height=float(dimensions[0]),
                                        radius=float(dimensions[1]), count=list(CAPSULE_COUNT))
    raise ValueError(f"cannot draw a {kind} geometry")


#: A link colour with every channel above this (0..1) is near white, and would vanish on the
#: pictures' near-white backgrounds (the Panda's links are white): it is drawn in
#: :data:`LIGHT_LINK_COLOUR` instead.
LIGHT_CHANNEL = 0.85
#: The colour of near-white links (0..1 channels): a blue-grey set apart from the objects'
#: grey.
LIGHT_LINK_COLOUR = (0.45, 0.55, 0.72)


def _rgb(rgba: Sequence[float]) -> str:
    """``rgb(r, g, b)`` of a visual colour (0..1 channels; near white: see
    :data:`LIGHT_CHANNEL`)."""
    channels = [float(v) for v in rgba[:3]]
    if min(channels) > LIGHT_CHANNEL:
        channels = list(LIGHT_LINK_COLOUR)
    r, g, b = (round(255 * v) for v in channels)
    return f"rgb({r}, {g}, {b})"


def _link_frame(bullet, body: int, index: int) -> np.ndarray:
    """World pose of link ``index``'s URDF frame (the base's: its inertial frame times the
    inverse of its local inertial pose, which is how pybullet places the base)."""
    if index >= 0:
        state = bullet.getLinkState(body, index, computeForwardKinematics=True)
        return _pose(state[4], state[5])
    position, quaternion = bullet.getBasePositionAndOrientation(body)
    local = bullet.getDynamicsInfo(body, -1)
    return _pose(position, quaternion) @ np.linalg.inv(_pose(local[3], local[4]))


def _collision_shapes(bullet, body: int, index: int, link: str,
                      color: str) -> list[LinkShape]:
    """Link ``index``'s collision geometry in its URDF frame (pybullet's collision frames
    and mesh vertices are in the link's inertial frame)."""
    from scipy.spatial import ConvexHull

    local = bullet.getDynamicsInfo(body, index)
    inertial = _pose(local[3], local[4])
    out = []
    for k, row in enumerate(bullet.getCollisionShapeData(body, index)):
        kind = GEOMETRY_KINDS.get(row[2], "unknown")
        if kind == "mesh":
            count, points = bullet.getMeshData(body, index, collisionShapeIndex=k)
            points = np.asarray(points, dtype=float).reshape(-1, 3)
            if count < 4:
                continue
            faces = ConvexHull(points).simplices
            vertices = points @ inertial[:3, :3].T + inertial[:3, 3]
        else:
            mesh = _primitive(kind, row[3])
            frame = inertial @ _pose(row[5], row[6])
            vertices = np.asarray(mesh.vertices) @ frame[:3, :3].T + frame[:3, 3]
            faces = np.asarray(mesh.faces)
        out.append(LinkShape(link, vertices, np.asarray(faces), color, "collision", kind))
    return out


def _shapes(bullet, body: int, links: Mapping[str, int]) -> tuple[LinkShape, ...]:
    """Every link's drawn geometry (see the module docstring), links in the URDF's order."""
    visuals: dict[int, list] = {}
    for row in bullet.getVisualShapeData(body):
        visuals.setdefault(row[1], []).append(row)
    out: list[LinkShape] = []
    for link, index in links.items():
        rows = visuals.get(index, [])
        if not rows:
            continue
        color = _rgb(rows[0][7])
        if any(GEOMETRY_KINDS.get(r[2]) == "mesh" for r in rows):
            out += _collision_shapes(bullet, body, index, link, color)
            continue
        for row in rows:
            kind = GEOMETRY_KINDS.get(row[2], "unknown")
            mesh = _primitive(kind, row[3])
            frame = _pose(row[5], row[6])  # the visual frame, in the link's URDF frame
            out.append(LinkShape(link, np.asarray(mesh.vertices) @ frame[:3, :3].T
                                 + frame[:3, 3], np.asarray(mesh.faces), _rgb(row[7]),
                                 "visual", kind))
    return tuple(out)


def robot_geometry(description: RobotDescription,
                   configurations: Sequence[Mapping[str, float]]) -> RobotGeometry:
    """The robot's drawn geometry and its link frames at each of ``configurations``.

    Args:
        description: the robot.
        configurations: each a mapping movable joint name -> value (radians / metres),
            e.g. ``description.model.expand(q)`` or a closing's final joint values (joints
            left out keep the open configuration's values).

    Returns:
        :class:`RobotGeometry` (its ``frames[i]`` for ``configurations[i]``).
    """
    open_values = description.model.expand(description.open_configuration())
    frames = []
    with loaded_robot(description) as (bullet, body, links):
        shapes = _shapes(bullet, body, links)
        joints = {bullet.getJointInfo(body, i)[1].decode(): i for i in links.values() if i >= 0}
        for values in configurations:
            for joint, value in {**open_values, **values}.items():
                bullet.resetJointState(body, joints[joint], float(value))
            frames.append({link: _link_frame(bullet, body, index)
                           for link, index in links.items()})
    return RobotGeometry(shapes, tuple(frames))
