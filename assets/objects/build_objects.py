"""Generate the object catalog: watertight meshes and their exact convex decompositions.

Run: ``python assets/objects/build_objects.py`` (needs trimesh and manifold3d, both in the
``dev`` extra). Every object is built as a union of convex parts (boxes, tessellated
cylinders and frusta, annular sectors); the parts *are* the convex decomposition used for
collision queries, and the mesh is their boolean union, so the two describe the same
surface (no approximation). Object frame: origin at the centre of the base, +z up, metres.

Writes ``<name>.obj`` (the watertight mesh) and ``<name>_parts.json`` (the parts' vertices).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
SECTIONS = 48  # tessellation of every round part


def box(size, center, yaw: float = 0.0, pitch: float = 0.0) -> np.ndarray:
    """8 vertices of a box of ``size`` (x, y, z) centred at ``center``, rotated."""
    half = np.asarray(size, dtype=float) / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    rot = trimesh.transformations.euler_matrix(0.0, pitch, yaw)[:3, :3]
    return corners * half @ rot.T + np.asarray(center)


def frustum(r0: float, r1: float, z0: float, z1: float, axis: str = "z",
            center=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Vertices of a tessellated frustum (cylinder when r0 = r1) along ``axis``."""
    a = 2 * np.pi * (np.arange(SECTIONS) + 0.5) / SECTIONS
    ring = np.stack([np.cos(a), np.sin(a)], axis=1)
    lower = np.column_stack([r0 * ring, np.full(SECTIONS, z0)])
    upper = np.column_stack([r1 * ring, np.full(SECTIONS, z1)])
    pts = np.vstack([lower, upper])
    if axis == "x":
        pts = pts[:, [2, 0, 1]]
    elif axis == "y":
        pts = pts[:, [1, 2, 0]]
    return pts + np.asarray(center)


def annular_sector(r_in: float, r_out: float, a0: float, a1: float, z0: float,
                   z1: float) -> np.ndarray:
    """8 vertices of one sector of a thick-walled tube."""
    pts = []
    for r in (r_in, r_out):
        for a in (a0, a1):
            for z in (z0, z1):
                pts.append([r * math.cos(a), r * math.sin(a), z])
    return np.array(pts)


def cube() -> list[np.ndarray]:
    return [box((0.06, 0.06, 0.06), (0, 0, 0.03))]


def spray_flask() -> list[np.ndarray]:
    """A spray bottle: body, shoulder, neck, trigger head, nozzle, trigger (27 cm tall)."""
    return [
        frustum(0.038, 0.038, 0.0, 0.16),                  # body
        frustum(0.038, 0.018, 0.16, 0.19),                 # shoulder
        frustum(0.016, 0.016, 0.19, 0.215),                # neck
        box((0.075, 0.034, 0.045), (0.012, 0, 0.2375)),     # trigger head
        box((0.022, 0.016, 0.016), (0.058, 0, 0.245)),      # nozzle
        box((0.012, 0.022, 0.055), (0.038, 0, 0.19)),       # trigger
    ]


def drill() -> list[np.ndarray]:
    """A cordless power drill standing on its battery, chuck towards +x (24 cm tall)."""
    return [
        box((0.085, 0.07, 0.05), (0.0, 0, 0.025)),                      # battery
        box((0.045, 0.042, 0.13), (0.005, 0, 0.115), pitch=-0.2),        # handle
        box((0.19, 0.062, 0.075), (0.035, 0, 0.205)),                   # motor body
        frustum(0.024, 0.020, 0.13, 0.175, axis="x", center=(0, 0, 0.205)),  # chuck
        frustum(0.004, 0.004, 0.175, 0.225, axis="x", center=(0, 0, 0.205)),  # bit
    ]


def mug() -> list[np.ndarray]:
    """A mug: 8.2 cm diameter, 9.5 cm tall, 5 mm wall, with a handle on the +x side."""
    r_out, r_in, height, floor = 0.041, 0.036, 0.095, 0.008
    edges = 2 * np.pi * (np.arange(SECTIONS + 1) + 0.5) / SECTIONS  # as in ``frustum``
    parts = [frustum(r_out, r_out, 0.0, floor)]
    parts += [annular_sector(r_in, r_out, edges[i], edges[i + 1], floor, height)
              for i in range(SECTIONS)]
    # handle: a C of three boxes, 12 mm thick, reaching 3.2 cm out from the wall
    parts += [
        box((0.034, 0.012, 0.010), (0.054, 0, 0.078)),
        box((0.010, 0.012, 0.056), (0.068, 0, 0.050)),
        box((0.034, 0.012, 0.010), (0.054, 0, 0.022)),
    ]
    return parts


def mug_mesh(parts: list[np.ndarray]) -> trimesh.Trimesh:
    """The mug's surface: a solid cylinder minus its cavity, plus the handle (the wall
    sectors would meet face to face, which a boolean union leaves non-manifold)."""
    hull = trimesh.convex.convex_hull
    outer = hull(frustum(0.041, 0.041, 0.0, 0.095))
    cavity = hull(frustum(0.036, 0.036, 0.008, 0.2))
    cup = trimesh.boolean.difference([outer, cavity], engine="manifold")
    return trimesh.boolean.union([cup, *[hull(p) for p in parts[-3:]]], engine="manifold")


OBJECTS = {"cube": cube, "spray_flask": spray_flask, "drill": drill, "mug": mug}


def union_mesh(name: str, parts: list[np.ndarray]) -> trimesh.Trimesh:
    if name == "mug":
        mesh = mug_mesh(parts)
    else:
        hulls = [trimesh.convex.convex_hull(p) for p in parts]
        mesh = trimesh.boolean.union(hulls, engine="manifold") if len(hulls) > 1 else hulls[0]
    check = trimesh.Trimesh(mesh.vertices, mesh.faces)  # merged, as a loader sees it
    if not (check.is_watertight and check.is_winding_consistent and check.volume > 0):
        raise RuntimeError(f"{name}: mesh is not a watertight solid")
    return check


def build(out_dir: Path = HERE) -> list[Path]:
    written = []
    for name, make in OBJECTS.items():
        parts = make()
        mesh = union_mesh(name, parts)
        mesh_path = out_dir / f"{name}.obj"
        mesh.export(mesh_path, digits=9)
        parts_path = out_dir / f"{name}_parts.json"
        parts_path.write_text(json.dumps(
            {"object": name, "units": "metres", "frame": "origin at base centre, +z up",
             "parts": [np.round(p, 9).tolist() for p in parts]}, indent=None))
        written += [mesh_path, parts_path]
    return written


if __name__ == "__main__":
    for path in build():
        print(path)
