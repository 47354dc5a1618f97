"""Importing objects (``kinegrasp objects add``): geometry against closed forms and independent
computations, bad input, atomicity, and one real mesh end to end.

Every test runs with a temporary ``$KINEGRASP_HOME`` (the catalog) and ``$KINEGRASP_CACHE``.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pybullet
import pybullet_data
import pytest
import trimesh
from env_helpers import check_reward_is_the_evaluation

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli.main import main
from kinegrasp_env.world import importer
from kinegrasp_env.world.decompose import mass_properties
from kinegrasp_env.world.deviation import deviation, surface_distance, winding_number
from kinegrasp_env.world.import_settings import ImportSettings
from kinegrasp_env.world.importer import import_object
from kinegrasp_env.world.meshfile import MeshError
from kinegrasp_env.world.meshprep import HAND_SPAN, check_size, clean_mesh
from kinegrasp_env.world.objects import (
    OBJECT_NAMES,
    face_planes,
    is_object,
    load_object,
    object_names,
)
from kinegrasp_env.world.polytope import ConvexPart
from kinegrasp_env.world.store import CatalogError, catalog_dir, imported_names

PYBULLET_DATA = Path(pybullet_data.getDataPath())


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> Path:
    cache = tmp_path_factory.mktemp("cache")
    # jit.py fixes a kernel's cache folder when its module is imported (before this fixture)
    # but looks for stale folders next to the current one when it compiles: let it find one
    (cache / "numba").mkdir()
    return cache


@pytest.fixture()
def home(tmp_path, monkeypatch, cache_dir) -> Path:
    """A fresh catalog folder (and a module-wide temporary cache)."""
    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    monkeypatch.setenv("KINEGRASP_CACHE", str(cache_dir))
    importer.forget()
    yield tmp_path / "home"
    importer.forget()


def box_file(path: Path, extents=(0.05, 0.05, 0.05), offset=(0.0, 0.0, 0.0)) -> Path:
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(offset)
    box.export(path)
    return path


def l_shape() -> trimesh.Trimesh:
    """An L: [0, .06] x [0, .02] x [0, .02] united with [0, .02] x [0, .02] x [0, .06] (m)."""
    pytest.importorskip("manifold3d")
    a = trimesh.creation.box(extents=(0.06, 0.02, 0.02))
    a.apply_translation((0.03, 0.01, 0.01))
    b = trimesh.creation.box(extents=(0.02, 0.02, 0.06))
    b.apply_translation((0.01, 0.01, 0.03))
    return trimesh.boolean.union([a, b], engine="manifold")


def snapshot(home: Path) -> list[tuple[str, float]]:
    """Every file and folder under the catalog (hidden ones too), with modification times."""
    root = home / "objects"
    if not root.exists():
        return []
    return sorted((str(p.relative_to(root)), p.stat().st_mtime) for p in root.rglob("*"))


def cli(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


# ----------------------------------------------------------------------------- geometry
def test_unit_cube_closed_form(home, tmp_path):
    """A 5 cm cube stored off-centre: one part, no deviation; centre of mass, r_max, volume
    and the object frame (origin at the centre of the base) as in closed form."""
    result = import_object(box_file(tmp_path / "cube5.stl", offset=(1.0, -2.0, 3.0)))
    entry, side = result.entry, 0.05
    assert entry["parts"] == 1
    assert max(entry["deviation"][k] for k in ("missing_max", "added_max")) < 1e-9
    # an STL file holds float32 coordinates: 1.2e-7 m rounding at 3 m from the origin
    np.testing.assert_allclose(entry["center_of_mass"], [0, 0, side / 2], atol=5e-7)
    assert entry["r_max"] == pytest.approx(math.sqrt(3) / 2 * side, abs=5e-7)
    assert entry["volume"] == pytest.approx(side**3, rel=1e-5)
    obj = load_object("cube5")
    np.testing.assert_allclose(obj.mesh.bounds, [[-side / 2, -side / 2, 0],
                                                 [side / 2, side / 2, side]], atol=5e-7)
    assert obj.imported and obj.r_max == entry["r_max"]
    np.testing.assert_allclose(entry["source_to_object"][2][3], -(3.0 - side / 2))


def test_mass_properties_of_two_boxes():
    """Volume-weighted centroid and farthest vertex of two disjoint boxes (closed form)."""
    a = trimesh.creation.box(extents=(0.02, 0.02, 0.02)).vertices
    b = trimesh.creation.box(extents=(0.04, 0.02, 0.02)).vertices + np.array([0.1, 0, 0])
    com, r_max, volume = mass_properties([a, b])
    va, vb = 0.02**3, 0.04 * 0.02 * 0.02
    expected = np.array([vb * 0.1 / (va + vb), 0, 0])
    np.testing.assert_allclose(com, expected, atol=1e-15)
    assert volume == pytest.approx(va + vb, rel=1e-12)
    # the farthest vertex: a corner of the small box, on the far side from the big one
    far = np.array([-0.01, 0.01, 0.01]) - expected
    assert r_max == pytest.approx(np.linalg.norm(far), rel=1e-12)


def test_deviation_of_a_hull_closed_form():
    """The L against its own convex hull (one part): nothing missing; the hull adds the
    triangle between the L's arms, whose slanted face lies at most 20 mm from the L
    (closed form, at the middle of the slant); sampled, within 1 mm below that."""
    mesh = l_shape()
    dev = deviation(mesh, [np.asarray(mesh.convex_hull.vertices)])
    assert dev.missing_max < 1e-12
    assert 0.019 < dev.added_max <= 0.02 + 1e-12


def test_deviation_of_coacd_parts_of_the_l(home):
    """CoACD splits the L into 2 parts close to it (< 0.1 mm both ways); the centre of mass
    of the parts is the L's (closed form: (22, 10, 22) mm) within their overlap."""
    from kinegrasp_env.world.decompose import decompose

    mesh = l_shape()
    parts = decompose(mesh)
    dev = deviation(mesh, parts)
    assert len(parts) == 2
    assert dev.missing_max < 1e-4 and dev.added_max < 1e-4
    com, _, volume = mass_properties(parts)
    np.testing.assert_allclose(com, [0.022, 0.01, 0.022], atol=1e-5)
    assert volume == pytest.approx(4e-5, rel=1e-3)


def test_surface_distance_against_brute_force(rng):
    """Point-to-mesh distance (pruned by bounding spheres) against trimesh's brute force over
    every triangle: equal."""
    mesh = trimesh.creation.torus(0.04, 0.015)
    points = rng.uniform(-0.07, 0.07, size=(400, 3))
    ours = surface_distance(np.asarray(mesh.triangles), points)
    _, theirs, _ = trimesh.proximity.closest_point_naive(mesh, points)
    np.testing.assert_allclose(ours, theirs, atol=1e-12)


def test_winding_number_against_contains(rng):
    """Inside/outside by the winding number equals trimesh's ray-parity ``contains``."""
    pytest.importorskip("rtree")
    mesh = trimesh.creation.torus(0.04, 0.015)
    points = rng.uniform(-0.06, 0.06, size=(300, 3))
    inside = np.abs(winding_number(np.asarray(mesh.triangles), points)) > 0.5
    np.testing.assert_array_equal(inside, mesh.contains(points))


def test_simplified_hull_error_is_exact():
    """A 642-vertex sphere hull cut to 96 vertices: a subset of the vertices, and the error it
    reports is the exact distance of the farthest original vertex outside the simplified hull
    (independent: exact point-to-polytope distances); a tolerance stops it earlier."""
    from kinegrasp_env.world.decompose import simplify_hull

    vertices = np.asarray(trimesh.creation.icosphere(subdivisions=3, radius=0.03).vertices)
    kept, error = simplify_hull(vertices, cap=96, tolerance=0.0)
    assert len(kept) == 96
    assert {tuple(v) for v in kept} <= {tuple(v) for v in vertices}
    part = ConvexPart(kept, face_planes(kept))
    assert error == pytest.approx(part.closest(vertices)[1].max(), abs=1e-12)
    assert 0 < error < 0.03 * (1 - math.cos(0.5))  # below a 1-radian cap's sagitta
    coarse, coarse_error = simplify_hull(vertices, cap=96, tolerance=2e-3)
    assert len(coarse) < 96 and coarse_error <= 2e-3
    same, none = simplify_hull(vertices[:50], cap=96)
    assert none == 0.0 and np.array_equal(same, vertices[:50])


def test_compiled_grid_distances_equal_numpy(rng):
    """The grid kernel (every object's grid) against ConvexPart.closest (numpy) on a CoACD-like
    part with many edges: equal to 1e-12 m, and it keeps ``current`` only where that is
    provably not larger."""
    from kinegrasp_env.world.sdf import node_distances

    vertices = trimesh.creation.icosphere(subdivisions=2, radius=0.03).vertices
    part = ConvexPart(vertices, face_planes(vertices))
    points = rng.uniform(-0.07, 0.07, size=(3000, 3))
    exact = part.closest(points)[1]
    fast = node_distances(part, points, np.full(len(points), np.inf))
    np.testing.assert_allclose(fast, exact, atol=1e-12)
    current = np.full(len(points), 0.01)
    capped = node_distances(part, points, current)
    np.testing.assert_allclose(np.minimum(capped, current), np.minimum(exact, current),
                               atol=1e-12)


def test_hand_span_from_the_urdf():
    """The size check's hand numbers against the shipped hand URDF (independent parse)."""
    root = ET.parse(asset_path("robots", "sdh_hand.urdf")).getroot()
    joints = {j.get("name"): j for j in root.iter("joint")}

    def xyz(name):
        return np.array([float(v) for v in joints[name].find("origin").get("xyz").split()])

    thumb, finger = xyz("f3_base"), xyz("f1_spread")
    length = xyz("f1_distal")[2] + xyz("f1_distal_to_tip")[2]
    capsule = next(link for link in root.iter("link") if link.get("name") == "f1_distal")
    radius = float(capsule.find("collision/geometry/capsule").get("radius"))
    assert HAND_SPAN == pytest.approx(finger[0] - thumb[0] + 2 * length - 2 * radius, abs=1e-12)


def test_size_check_messages():
    big = clean_mesh(trimesh.creation.box(extents=(60.0, 80.0, 100.0)).vertices,
                     trimesh.creation.box(extents=(60.0, 80.0, 100.0)).faces)
    with pytest.raises(MeshError, match=r"too large for the hand: 60, 80, 100 m.*--units mm"):
        check_size(big, 60.0)
    tiny = trimesh.creation.box(extents=(0.004, 0.005, 0.006))
    with pytest.raises(MeshError, match=r"too small for the hand: 0\.004, 0\.005, 0\.006 m"):
        check_size(tiny, 0.004)
    check_size(trimesh.creation.box(extents=(0.3, 0.3, 0.3)), 0.3)  # within the span


@pytest.mark.parametrize("extents, scale", [((500.0, 500.0, 600.0), 1e-3),
                                           ((0.5, 0.4, 0.4), 1e-3), ((0.3, 0.2, 0.2), 10.0)])
def test_the_suggested_scale_makes_the_object_graspable(home, tmp_path, extents, scale):
    """A file read with a scale (or units) that leaves it too large or too small: the hint's
    ``--scale`` is from the file's units to metres (it was the extra factor on top of the
    one given, and imported a 500 mm box as 100 m); importing with it gives an object
    0.1 m across."""
    import re

    path = box_file(tmp_path / "b.stl", extents=extents)
    with pytest.raises(MeshError) as info:
        import_object(path, settings=ImportSettings(scale=scale))
    hint = float(re.search(r"--scale (?:\(e\.g\. --scale )?([0-9.e+-]+)", str(info.value))[1])
    assert "instead of the units or scale given" in str(info.value)
    import_object(path, settings=ImportSettings(scale=hint), name="fixed")
    assert max(load_object("fixed").mesh.extents) == pytest.approx(0.1, rel=1e-2)  # 3 digits


def test_an_empty_name_is_refused(home, tmp_path):
    """``--name ""`` named no object and the import took the file's name instead."""
    with pytest.raises(CatalogError, match="invalid object name ''"):
        import_object(box_file(tmp_path / "b.obj"), name="")
    assert not (home / "objects" / "b").exists()


def test_a_scale_far_too_small_is_named_as_too_small(home, tmp_path):
    """A 5 cm box imported at --scale 1e-9 is 5e-11 m across: cleaning merges every vertex
    (trimesh's merge tolerance is far above that), and the import said the mesh had no
    faces. The size is checked on the scaled vertices first and named, with a fix."""
    path = box_file(tmp_path / "b.obj")
    with pytest.raises(MeshError, match=r"too small for the hand: 5e-11, 5e-11, 5e-11 m.*"
                                        r"--scale"):
        import_object(path, settings=ImportSettings(scale=1e-9))


# ----------------------------------------------------------------------------- file formats
@pytest.mark.parametrize("suffix", [".obj", ".ply", ".off", ".glb"])
def test_mesh_formats(home, tmp_path, suffix):
    entry = import_object(box_file(tmp_path / f"b{suffix}", extents=(0.02, 0.03, 0.04))).entry
    assert entry["parts"] == 1
    np.testing.assert_allclose(entry["size"], [0.02, 0.03, 0.04], atol=1e-6)


def test_urdf_collision_mesh_with_scale_and_origin(home, tmp_path):
    """The first link with collision geometry: its mesh scaled by the URDF's ``scale`` and
    turned by its origin (yaw 90 degrees swaps x and y), plus a primitive box."""
    box_file(tmp_path / "meshes_box.stl", extents=(0.02, 0.03, 0.04))
    (tmp_path / "thing.urdf").write_text(
        '<robot name="thing"><link name="world"/><link name="body"><collision>'
        '<origin xyz="0 0 0" rpy="0 0 1.5707963267948966"/><geometry>'
        '<mesh filename="package://thing/meshes_box.stl" scale="2 2 2"/></geometry>'
        '</collision><collision><origin xyz="0 0 0.05"/><geometry><box size="0.01 0.01 0.02"/>'
        "</geometry></collision></link></robot>")
    entry = import_object(tmp_path / "thing.urdf").entry
    # 0.04 x 0.06 x 0.08 turned: 0.06 x 0.04, up to z = 0.04; the box adds 0.04 .. 0.06
    np.testing.assert_allclose(entry["size"], [0.06, 0.04, 0.1], atol=1e-6)
    assert "link 'body'" in entry["source"]["description"]
    assert entry["parts"] == 2


# ----------------------------------------------------------------------------- catalog
def test_reuse_force_remove_and_listing(home, tmp_path, capsys):
    path = box_file(tmp_path / "block.stl", extents=(0.04, 0.06, 0.08))
    first = import_object(path)
    again = import_object(path)
    assert again.reused and again.entry == first.entry
    assert "block" in object_names() and is_object("block")
    code, out, _ = cli(capsys, "objects")
    assert code == 0
    row = next(line for line in out.splitlines() if line.startswith("block "))
    assert "0.040, 0.060, 0.080" in row and "block.stl" in row and "0.00/0.00" in row
    code, out, _ = cli(capsys, "objects", "--json")
    rows = {r["name"]: r for r in json.loads(out)}
    assert list(rows)[:4] == list(OBJECT_NAMES) and rows["block"]["parts"] == 1
    replaced = import_object(path, settings=ImportSettings(scale=2.0), force=True)
    assert not replaced.reused
    assert load_object("block").size == pytest.approx([0.08, 0.12, 0.16])
    # an object a placed copy stands for is not removed before the copy (the copy's commands
    # failed with a traceback once its base was gone)
    from kinegrasp_env.world.placement import place_object

    place_object("block", as_name="block_turned", position=[0.6, 0.0, 0.1])
    broken = catalog_dir() / "broken_entry"  # an unreadable entry keeps no removal from working
    broken.mkdir()
    (broken / "entry.json").write_text("{")
    code, _, err = cli(capsys, "objects", "remove", "block")
    assert code == 2 and "placed object(s) block_turned stand for; remove them first" in err
    assert "block" in imported_names()
    code, out, _ = cli(capsys, "objects", "remove", "block_turned")
    assert code == 0
    code, out, _ = cli(capsys, "objects", "remove", "block")
    assert code == 0 and "block" not in imported_names()
    shutil.rmtree(broken)
    assert os.listdir(catalog_dir()) == []


def test_density_gives_the_mass(home, tmp_path, capsys):
    """``objects add --density``: the mass is density x the box's volume (worked by hand:
    0.04 x 0.06 x 0.08 m at 2,700 kg/m^3 is 0.5184 kg); the default 500 kg/m^3 without it;
    given again for the same file and settings it is set alone (nothing re-imported); a bad
    density is one line and writes nothing."""
    path = box_file(tmp_path / "block.stl", extents=(0.04, 0.06, 0.08))
    code, _, err = cli(capsys, "objects", "add", str(path))
    assert code == 0, err
    assert load_object("block").mass == pytest.approx(500 * 0.04 * 0.06 * 0.08, rel=1e-9)
    code, out, err = cli(capsys, "objects", "add", str(path), "--density", "2700")
    assert code == 0 and "density set to 2700 kg/m^3" in out, err
    assert load_object("block").mass == pytest.approx(0.5184, rel=1e-9)
    before = snapshot(home)
    for bad in ("0", "-1", "nan"):
        code, _, err = cli(capsys, "objects", "add", str(path), "--density", bad)
        assert code == 2 and len(err.strip().splitlines()) == 1 and "--density" in err, bad
    assert snapshot(home) == before


def test_a_scale_equal_but_for_its_last_digits_reuses_the_entry(home, tmp_path, capsys):
    """``objects add`` again with the scale typed to more digits (equal to the stored one
    within a relative 1e-6) reuses the entry; a scale 1e-5 off is another setting."""
    path = box_file(tmp_path / "inch_box.stl", extents=(2.0, 2.0, 2.0))  # inches
    code, _, err = cli(capsys, "objects", "add", str(path), "--scale", "0.0254")
    assert code == 0, err
    before = snapshot(home)
    for retyped in ("0.025400001", "0.0254000001", "0.02539999999999"):  # 8th digit and on
        code, out, err = cli(capsys, "objects", "add", str(path), "--scale", retyped)
        assert code == 0 and "already imported from this file with these settings" in out, \
            (retyped, err)
        assert snapshot(home) == before, retyped
    code, _, err = cli(capsys, "objects", "add", str(path), "--scale", "0.02540025")
    assert code == 2 and "already exists" in err and "--force" in err
    assert snapshot(home) == before
    assert load_object("inch_box").size == pytest.approx([0.0508] * 3)


def test_show_draws_a_png(home, tmp_path, capsys):
    import_object(box_file(tmp_path / "cube5.stl"))
    code, _, _ = cli(capsys, "objects", "show", "cube5", "--plot", str(tmp_path / "c.png"))
    assert code == 0 and (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, _, _ = cli(capsys, "objects", "show", "drill", "--plot", str(tmp_path / "d.png"))
    assert code == 0


def write_bad_inputs(folder: Path) -> dict[str, tuple[list[str], str]]:
    """name -> (arguments after ``objects add``, expected part of the error)."""
    (folder / "empty.obj").write_bytes(b"")
    (folder / "text.obj").write_text("this is a shopping list, not a mesh\n")
    (folder / "one.obj").write_text("v 0 0 0\nv 0.05 0 0\nv 0 0.05 0\nf 1 2 3\n")
    flat = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    flat.vertices[:, 2] = 0.0
    flat.export(folder / "flat.stl")
    box_file(folder / "huge.stl", extents=(60.0, 60.0, 60.0))
    (folder / "novis.urdf").write_text(
        '<robot name="r"><link name="base"><visual><geometry><box size="0.05 0.05 0.05"/>'
        "</geometry></visual></link></robot>")
    return {
        "empty": ([str(folder / "empty.obj")], "the file is empty"),
        "text": ([str(folder / "text.obj")], "no triangles found"),
        "one face": ([str(folder / "one.obj")], "1 non-degenerate face"),
        "flat": ([str(folder / "flat.stl")], "the mesh is flat (zero volume)"),
        "1000x": ([str(folder / "huge.stl")], "too large for the hand"),
        "urdf": ([str(folder / "novis.urdf")], "no link has collision geometry"),
        "missing": ([str(folder / "nope.obj")], "no such file"),
        "folder": ([str(folder)], f"{folder} is a folder; give a mesh file or a URDF"),
        "type": ([str(folder / "one.obj"), "--name", "cube"], "'cube' is a built-in object"),
        "scale": ([str(folder / "one.obj"), "--scale", "-1"], "--scale must be > 0"),
    }


def test_bad_input_one_line_and_nothing_written(home, tmp_path, capsys):
    """Each bad input: exit status 2, one line on stderr naming the problem, and the catalog
    exactly as it was (no entry, no hidden leftovers); an existing name needs --force."""
    import_object(box_file(tmp_path / "keep.stl"))
    before = snapshot(home)
    for label, (args, expected) in write_bad_inputs(tmp_path).items():
        code, _, err = cli(capsys, "objects", "add", *args)
        assert code == 2, label
        assert len(err.strip().splitlines()) == 1 and expected in err, (label, err)
        assert err.startswith("kinegrasp objects add: error:"), label
        assert snapshot(home) == before, label
    code, _, err = cli(capsys, "objects", "add", str(tmp_path / "keep.stl"), "--scale", "2")
    assert code == 2 and "already exists" in err and "--force" in err
    assert snapshot(home) == before and load_object("keep").size == pytest.approx([0.05] * 3)
    code, _, err = cli(capsys, "objects", "add", str(tmp_path / "huge.stl"), "--units", "mm")
    assert code == 0, err  # the fix the message suggests works


def test_unknown_names_and_missing_grasp_sets(home, tmp_path, capsys):
    import_object(box_file(tmp_path / "cube5.stl"))
    with pytest.raises(ValueError, match="unknown object 'teapot'; known objects: cube, "
                       "spray_flask, drill, mug, cube5"):
        load_object("teapot")
    code, _, err = cli(capsys, "evaluate", "--object", "cube5", "--samples", "4")
    assert code == 2 and "has no shipped grasp set" in err and "kinegrasp plan" in err
    assert len(err.strip().splitlines()) == 1
    code, _, err = cli(capsys, "objects", "remove", "drill")
    assert code == 2 and "built-in" in err
    from kinegrasp_env.montecarlo.sweep import SpecError, SweepSpec

    with pytest.raises(SpecError, match="'cube5' is an imported object and has no shipped"):
        SweepSpec.from_dict({"objects": ["cube5"], "sigmas": [0.01]})


def test_interrupted_import_leaves_the_catalog_as_it_was(home, tmp_path):
    """SIGKILL during the convex decomposition: the object never appears; the hidden work
    folder it leaves is removed by the next import."""
    import_object(box_file(tmp_path / "keep.stl"))
    before_names = imported_names()
    torus = trimesh.creation.torus(0.04, 0.015)
    torus.export(tmp_path / "torus.obj")
    proc = subprocess.Popen([sys.executable, "-m", "kinegrasp_env.cli", "objects", "add",
                             str(tmp_path / "torus.obj")], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    root = catalog_dir()
    deadline = time.monotonic() + 120
    try:
        while not list(root.glob(".tmp-torus-*/mesh.obj")):  # written right before CoACD
            assert proc.poll() is None, "the import ended before it could be interrupted"
            assert time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(0.5)
        assert proc.poll() is None
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert imported_names() == before_names and not (root / "torus").exists()
    assert list(root.glob(".tmp-torus-*"))  # the killed import's work folder
    import_object(box_file(tmp_path / "other.stl"))
    assert not list(root.glob(".tmp-*"))
    assert imported_names() == ("keep", "other")


def test_evaluate_a_grasp_of_a_file(home, capsys):
    """``evaluate --grasps FILE --grasp ID|INDEX`` gives what the shipped set gives."""
    shipped = str(asset_path("grasps", "kuka_sdh", "cube.json"))
    common = ("--samples", "8", "--engine", "fast", "--json")
    runs = [cli(capsys, "evaluate", "--object", "cube", "--grasp", "1", *common),
            cli(capsys, "evaluate", "--grasps", shipped, "--grasp", "1", *common)]
    assert [r[0] for r in runs] == [0, 0] and runs[0][1] == runs[1][1]
    code, _, err = cli(capsys, "evaluate", "--grasps", shipped, "--grasp", "99", *common)
    assert code == 2 and "no grasp with this id" in err
    code, _, err = cli(capsys, "evaluate", "--grasps", shipped, "--grasp", "nosuch", *common)
    assert code == 2 and f"--grasp nosuch: no grasp with this id in {shipped} (ids: 0, 1" in err
    code, _, err = cli(capsys, "evaluate", "--grasps", shipped, "--object", "drill", *common)
    assert code == 2 and "is a grasp of cube" in err


# ----------------------------------------------------------------------------- end to end
@pytest.mark.expensive
def test_bunny_end_to_end(home, tmp_path, capsys):
    """pybullet_data's bunny (2 m tall: --scale 0.1) imported coarsely, planned, evaluated by
    both engines, ranked, and one env episode; the pybullet body and the fast engine's grid
    are the catalog's parts."""
    code, out, err = cli(capsys, "objects", "add", str(PYBULLET_DATA / "bunny.obj"), "--scale",
                         "0.1", "--threshold", "0.2", "--max-parts", "4")
    assert code == 0, err
    obj = load_object("bunny")
    assert 1 <= len(obj.parts) <= 4 and obj.size[2] == pytest.approx(0.1975, abs=1e-3)
    check_bullet_body_and_grid(obj)
    grasps = tmp_path / "bunny_grasps.json"
    code, out, err = cli(capsys, "plan", "--object", "bunny", "--count", "2", "--seed", "0",
                         "--max-attempts", "400", "--out", str(grasps))
    assert code == 0, err
    ids = [g["id"] for g in json.loads(grasps.read_text())["grasps"]]
    results = {}
    for engine in ("pybullet", "fast"):
        code, out, err = cli(capsys, "evaluate", "--grasps", str(grasps), "--grasp", ids[0],
                             "--sigma", "0", "--samples", "4", "--engine", engine, "--json")
        assert code == 0, err
        results[engine] = json.loads(out)
    # zero noise: every draw is the planned grasp, which the planner found in force closure
    # with the pybullet engine; the fast engine (the grid built at import) agrees
    assert results["pybullet"]["p_fc"] == 1.0 and results["fast"]["p_fc"] == 1.0
    assert results["fast"]["q_mean"] == pytest.approx(results["pybullet"]["q_mean"], rel=0.05)
    code, out, err = cli(capsys, "rank", str(grasps), "--samples", "40", "--engine", "fast",
                         "--out", str(tmp_path / "ranked.csv"))
    assert code == 0, err
    from kinegrasp_env.envs.kinegrasp import KineGraspEnv

    env = KineGraspEnv(objects=("bunny",), grasp_file=str(grasps), n_draws=8, engine="fast")
    obs, info = env.reset(seed=0)
    assert info["object"] == "bunny" and np.all(np.isfinite(obs))
    _, reward, _, _, info = env.step(np.array([0.5, 1.0], dtype=np.float32))
    check_reward_is_the_evaluation(env, reward, info)
    env.close()


def check_bullet_body_and_grid(obj) -> None:
    """pybullet's distance from probe points to each part of the object's body (base = part
    0, link k = part k + 1) equals the exact distance to that catalog part, less the part's
    collision margin as pybullet reports it (0 for the base; pybullet keeps 1 mm on links
    whatever changeDynamics asks, for the built-in objects too), within pybullet's own GJK
    error (measured: at most 1.1e-3 of the distance, on the built-in objects as here; bound
    1e-6 m + 1.5e-3 x distance); the grid stored at import equals a fresh build."""
    from kinegrasp_env.world.sdf import build_grid, object_grid
    from kinegrasp_env.world.sim import ObjectWorld

    rng = np.random.default_rng(1)
    lo, hi = obj.mesh.bounds
    probes = rng.uniform(lo - 0.02, hi + 0.02, size=(30, 3))
    exact = np.stack([part.closest(probes)[1] for part in obj.convex_parts], axis=1)
    with ObjectWorld(obj) as world:
        bullet = world.bullet
        body = world.bodies["object"]
        assert bullet.getNumJoints(body) == len(obj.parts) - 1
        margins = [bullet.getDynamicsInfo(body, k - 1)[11] for k in range(len(obj.parts))]
        assert margins[0] == 0.0 and all(m <= 1e-3 for m in margins)
        sphere = bullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=1e-4)
        probe = bullet.createMultiBody(0.0, sphere)
        bullet.changeDynamics(probe, -1, collisionMargin=0.0)
        for point, row in zip(obj.to_world(probes), exact, strict=True):
            bullet.resetBasePositionAndOrientation(probe, point.tolist(), [0, 0, 0, 1])
            for k, distance in enumerate(row):
                if distance < 2e-3:  # inside or touching: pybullet reports penetration depth
                    continue
                found = bullet.getClosestPoints(probe, body, 0.3, linkIndexB=k - 1)
                assert found[0][8] + 1e-4 == pytest.approx(distance - margins[k],
                                                           abs=1e-6 + 1.5e-3 * distance)
    stored = object_grid(obj.name)
    np.testing.assert_array_equal(stored.values, build_grid(obj).values)
