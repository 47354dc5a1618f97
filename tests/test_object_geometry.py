"""A built-in object's derived geometry (centre of mass, r_max, face planes, true edges) kept
on disk, and its mesh loaded on first use: what a cached load gives is what the mesh and
qhull give, and a load from the cache needs neither trimesh nor scipy.spatial."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from kinegrasp_env.assets import asset_path
from kinegrasp_env.world import object_geometry as geometry
from kinegrasp_env.world.names import OBJECT_NAMES
from kinegrasp_env.world.polytope import face_planes


@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_cached_geometry_is_the_meshs_and_qhulls(name, tmp_path, monkeypatch):
    """Against trimesh and scipy directly: the centre of mass is trimesh's of the asset mesh,
    r_max the largest vertex distance from it, each part's planes and edges those of a
    ConvexPart built afresh from its vertices (qhull); the second load (from the disk copy)
    gives the same arrays to the bit."""
    import trimesh

    from kinegrasp_env.world.polytope import ConvexPart

    monkeypatch.setenv("KINEGRASP_CACHE", str(tmp_path))
    first = geometry.builtin_geometry(name)
    assert list((tmp_path / "objects").glob(f"{name}-*.npz"))
    second = geometry.builtin_geometry(name)
    for key, value in first.items():
        assert np.array_equal(value, second[key]), key
    mesh = trimesh.load(asset_path("objects", f"{name}.obj"), force="mesh", process=True)
    assert np.array_equal(first["center_of_mass"], mesh.center_mass)
    assert float(first["r_max"]) == np.linalg.norm(mesh.vertices - mesh.center_mass,
                                                   axis=1).max()
    parts = json.loads(asset_path("objects", f"{name}_parts.json").read_text())["parts"]
    planes = geometry.split_rows(first["planes"], first["offsets"])
    edges = geometry.split_rows(first["edges"], first["edge_offsets"])
    for k, vertices in enumerate(parts):
        fresh = ConvexPart(np.asarray(vertices, dtype=float),
                           face_planes(np.asarray(vertices, dtype=float)))
        assert np.array_equal(planes[k], fresh.planes)
        assert np.array_equal(edges[k], fresh.edges)


def test_a_cached_builtin_object_loads_without_trimesh_or_qhull(tmp_path):
    """In a fresh interpreter whose cache holds the drill's geometry, loading it, its
    convex parts' edges and its distance grid imports neither trimesh nor scipy.spatial;
    its mesh, asked for, is trimesh's of the asset file."""
    env = dict(os.environ, KINEGRASP_CACHE=str(tmp_path))
    warm = "from kinegrasp_env.world.sdf import object_grid; object_grid('drill')"
    subprocess.run([sys.executable, "-c", warm], env=env, check=True)
    check = (
        "import sys\n"
        "from kinegrasp_env.world.objects import load_object\n"
        "from kinegrasp_env.world.sdf import object_grid\n"
        "obj = load_object('drill'); [p.edges for p in obj.convex_parts]; object_grid('drill')\n"
        "print(sorted({'trimesh', 'scipy.spatial'} & set(sys.modules)))\n"
        "print(len(obj.mesh.faces))\n")
    out = subprocess.run([sys.executable, "-c", check], env=env, check=True,
                         capture_output=True, text=True).stdout.split("\n")
    assert out[0] == "[]", out[0]
    import trimesh

    mesh = trimesh.load(asset_path("objects", "drill.obj"), force="mesh", process=True)
    assert int(out[1]) == len(mesh.faces)
