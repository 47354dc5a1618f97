"""What a catalog object is made of besides its parts: where its triangle mesh comes from
(read on first use), and a built-in object's derived geometry (centre of mass, r_max, face
planes, true edges) computed once from its mesh and parts and kept on disk, so that loading
it needs neither trimesh nor qhull."""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from kinegrasp_env.assets import asset_path
from kinegrasp_env.paths import cache_root
from kinegrasp_env.world.polytope import ConvexPart, face_planes

if TYPE_CHECKING:
    import trimesh


def mesh_file(path: Path, process: bool) -> trimesh.Trimesh:
    """The triangle mesh of an OBJ file (trimesh's ``process`` merges duplicate vertices),
    read afresh (an object keeps the one it read: :attr:`GraspObject.mesh`)."""
    import trimesh

    return trimesh.load(path, force="mesh", process=process)


@dataclass(frozen=True)
class MeshFile:
    """A mesh source that reads an OBJ file (:func:`mesh_file`) when called."""

    path: Path
    process: bool

    def __call__(self) -> trimesh.Trimesh:
        return mesh_file(self.path, self.process)


@dataclass(frozen=True)
class GivenMesh:
    """A mesh source that is a mesh already (an object built in memory)."""

    mesh: trimesh.Trimesh

    def __call__(self) -> trimesh.Trimesh:
        return self.mesh


#: The sources of a built-in object's derived geometry (a change of any gives a new key).
GEOMETRY_SOURCES = ("object_geometry.py", "polytope.py")


def builtin_geometry(name: str) -> dict[str, np.ndarray]:
    """A built-in object's centre of mass (3,), r_max (), its parts' face planes (every
    part's (F_i, 4) rows stacked, with (n_parts + 1,) offsets) and true edges (stacked
    (E, 2, 3), with offsets), computed from its mesh and parts once and kept on disk
    (``cache_root()/objects``, keyed by the asset files, the code and trimesh's version), so
    that loading it needs neither trimesh nor qhull."""
    from importlib.metadata import version

    obj_file, parts_file = (asset_path("objects", f"{name}.obj"),
                            asset_path("objects", f"{name}_parts.json"))
    digest = hashlib.sha256(obj_file.read_bytes() + b"\0" + parts_file.read_bytes())
    for source in GEOMETRY_SOURCES:
        digest.update(b"\0" + (Path(__file__).parent / source).read_bytes())
    digest.update(b"\0" + version("trimesh").encode())
    path = cache_root() / "objects" / f"{name}-{digest.hexdigest()[:16]}.npz"
    try:
        with np.load(path) as data:
            return {key: data[key] for key in data.files}
    except (OSError, ValueError):
        pass
    mesh = mesh_file(obj_file, True)
    com = np.asarray(mesh.center_mass, dtype=float)
    parts = json.loads(parts_file.read_text())["parts"]
    polytopes = [ConvexPart(v, face_planes(v)) for v in (np.asarray(p, dtype=float)
                                                          for p in parts)]
    geometry = {"center_of_mass": com,
                "r_max": np.array(np.linalg.norm(mesh.vertices - com, axis=1).max()),
                "planes": np.vstack([p.planes for p in polytopes]),
                "offsets": np.cumsum([0] + [len(p.planes) for p in polytopes]),
                "edges": np.concatenate([p.edges.reshape(-1, 2, 3) for p in polytopes]),
                "edge_offsets": np.cumsum([0] + [len(p.edges) for p in polytopes])}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, **geometry)
        os.replace(tmp, path)
    except OSError:
        pass  # read-only cache: computed again next time
    return geometry


def split_rows(rows: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, ...]:
    """The blocks ``rows[offsets[k]:offsets[k + 1]]`` of stacked per-part rows."""
    return tuple(rows[offsets[k]:offsets[k + 1]] for k in range(len(offsets) - 1))
