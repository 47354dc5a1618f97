"""Reading an object to import: a mesh file (OBJ, STL, PLY, OFF, GLB/GLTF) or a URDF.

A mesh file is read with trimesh (a scene's meshes are joined, each in its place). A URDF
gives the collision geometry of its first link that has some: each ``<collision>`` element's
mesh (with its ``scale``) or primitive (box, cylinder, sphere), moved by its ``<origin>``;
the link frame is the object's source frame. Every problem is one :class:`MeshError` line
naming the file.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from kinegrasp_env.robot.model import rpy_to_matrix

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")
URDF_SUFFIXES = (".urdf",)


class MeshError(ValueError):
    """An input file that cannot be imported (one line, names the file and the problem)."""


@dataclass(frozen=True)
class SourceMesh:
    """Triangles read from the user's files, in the source frame and units.

    Attributes:
        vertices: (V, 3) float64.
        faces: (F, 3) int64 vertex indices.
        files: every file read (the mesh, or the URDF and the meshes it names).
        description: where the triangles came from, for the catalog listing.
    """

    vertices: np.ndarray
    faces: np.ndarray
    files: tuple[Path, ...]
    description: str


def load_source(path: str | Path) -> SourceMesh:
    """Read a mesh file or a URDF (by suffix); :class:`MeshError` if it cannot be."""
    path = Path(path)
    if path.is_dir():
        raise MeshError(f"{path} is a folder; give a mesh file or a URDF")
    if not path.is_file():
        raise MeshError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix in URDF_SUFFIXES:
        return read_urdf(path)
    if suffix not in MESH_SUFFIXES:
        raise MeshError(f"{path}: unsupported file type {suffix or '(none)'!r}; supported: "
                        f"{', '.join(MESH_SUFFIXES + URDF_SUFFIXES)}")
    mesh = read_mesh(path)
    return SourceMesh(mesh.vertices, mesh.faces, (path,), path.name)


def read_mesh(path: Path) -> trimesh.Trimesh:
    """One triangle mesh from a mesh file (no processing); :class:`MeshError` when the file
    is empty, unreadable or holds no triangles."""
    if path.stat().st_size == 0:
        raise MeshError(f"{path}: the file is empty")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for malformed files
        raise MeshError(f"{path}: not a readable {path.suffix.lstrip('.').upper()} mesh "
                        f"({' '.join(str(exc).split())[:120]})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"{path}: no triangles found; not a valid "
                        f"{path.suffix.lstrip('.').upper()} mesh")
    return trimesh.Trimesh(np.asarray(mesh.vertices, dtype=np.float64),
                           np.asarray(mesh.faces, dtype=np.int64), process=False)


def read_urdf(path: Path) -> SourceMesh:
    """The collision geometry of the URDF's first link that has any (link frame)."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, UnicodeDecodeError) as exc:
        raise MeshError(f"{path}: not valid URDF XML ({exc})") from None
    if root.tag != "robot":
        raise MeshError(f"{path}: not a URDF (root element <{root.tag}>, expected <robot>)")
    for link in root.iter("link"):
        collisions = link.findall("collision")
        if collisions:
            break
    else:
        raise MeshError(f"{path}: no link has collision geometry")
    meshes, files = [], [path]
    for element in collisions:
        mesh, used = collision_mesh(element, path)
        meshes.append(mesh)
        files.extend(used)
    joined = trimesh.util.concatenate(meshes)
    names = ", ".join(f.name for f in files[1:]) or "primitives"
    return SourceMesh(np.asarray(joined.vertices, dtype=np.float64),
                      np.asarray(joined.faces, dtype=np.int64), tuple(files),
                      f"{path.name} link {link.get('name')!r} ({names})")


def collision_mesh(element: ET.Element, urdf: Path) -> tuple[trimesh.Trimesh, list[Path]]:
    """One ``<collision>``: its geometry (scaled) moved by its origin; the files it read."""
    geometry = element.find("geometry")
    shape = None if geometry is None else next(iter(geometry), None)
    if shape is None:
        raise MeshError(f"{urdf}: a <collision> element has no geometry")
    used: list[Path] = []
    if shape.tag == "mesh":
        file = resolve_mesh_file(shape.get("filename", ""), urdf)
        mesh = read_mesh(file)
        scale = numbers(shape.get("scale"), 3, 1.0, urdf, "scale")
        mesh.vertices = mesh.vertices * scale
        used.append(file)
    elif shape.tag == "box":
        mesh = trimesh.creation.box(extents=numbers(shape.get("size"), 3, None, urdf, "size"))
    elif shape.tag == "cylinder":
        mesh = trimesh.creation.cylinder(radius=float(shape.get("radius", 0)),
                                         height=float(shape.get("length", 0)), sections=48)
    elif shape.tag == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=float(shape.get("radius", 0)))
    else:
        raise MeshError(f"{urdf}: unsupported collision geometry <{shape.tag}>")
    origin = element.find("origin")
    transform = np.eye(4)
    if origin is not None:
        transform[:3, :3] = rpy_to_matrix(*numbers(origin.get("rpy"), 3, 0.0, urdf, "rpy"))
        transform[:3, 3] = numbers(origin.get("xyz"), 3, 0.0, urdf, "xyz")
    mesh.apply_transform(transform)
    return mesh, used


def resolve_mesh_file(name: str, urdf: Path) -> Path:
    """A URDF mesh ``filename``: relative to the URDF's folder; ``package://pkg/rest`` and
    ``file://`` are looked up there too (by ``rest``, then by the bare file name)."""
    if not name:
        raise MeshError(f"{urdf}: a <mesh> has no filename")
    plain = name.removeprefix("file://")
    candidates = [Path(plain)] if Path(plain).is_absolute() else [urdf.parent / plain]
    if name.startswith("package://"):
        rest = name[len("package://"):].split("/", 1)[-1]
        candidates = [urdf.parent / rest, urdf.parent / Path(rest).name]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise MeshError(f"{urdf}: mesh file {name!r} not found (looked for "
                    f"{', '.join(str(c) for c in candidates)})")


def numbers(text: str | None, count: int, default: float | None, urdf: Path,
            what: str) -> np.ndarray:
    """``count`` numbers from a URDF attribute (one number is repeated: a uniform scale)."""
    if text is None:
        if default is None:
            raise MeshError(f"{urdf}: missing {what}")
        return np.full(count, default)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        raise MeshError(f"{urdf}: {what}={text!r} is not a list of numbers") from None
    if values.size == 1:
        values = np.full(count, values[0])
    if values.size != count or not np.all(np.isfinite(values)):
        raise MeshError(f"{urdf}: {what}={text!r} must be {count} finite numbers")
    return values
