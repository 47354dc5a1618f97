"""Imported objects everywhere: ``sweep`` and ``reproduce fig9|fig10`` with a grasp file,
``objects add --up``, and per-object caches that follow a re-import under the same name.

The reference for the first and last: a 6 cm box imported from an OBJ file has exactly the
built-in cube's part (6 cm, origin at the centre of its base), so the cube's shipped grasps
relabelled as grasps of the box must give the built-in cube's numbers.
"""

from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import pytest
import trimesh

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli.main import main
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.montecarlo.sweep import SpecError, SweepSpec, run_sweep
from kinegrasp_env.world import importer
from kinegrasp_env.world.grasps import grasp_by_index
from kinegrasp_env.world.import_settings import ImportSettings, entry_key
from kinegrasp_env.world.importer import import_object
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.store import CatalogError

BOX = "box6"


@pytest.fixture(scope="module")
def catalog(tmp_path_factory):
    """A catalog of its own holding ``box6`` (the built-in cube's geometry) and a grasp file
    of the cube's shipped grasps relabelled as grasps of ``box6``."""
    folder = tmp_path_factory.mktemp("everywhere")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("KINEGRASP_HOME", str(folder / "home"))
        importer.forget()
        trimesh.creation.box(extents=(0.06, 0.06, 0.06)).export(folder / "box6.obj")
        import_object(folder / "box6.obj", BOX)
        data = json.loads(asset_path("grasps", "kuka_sdh", "cube.json").read_text())
        data["object"] = BOX
        for grasp in data["grasps"]:
            grasp["object"] = BOX
        (folder / "box6_grasps.json").write_text(json.dumps(data))
        yield folder
    importer.forget()


def rows_of(path) -> list[dict]:
    with open(path) as handle:
        return list(csv.DictReader(handle))


def cli(capsys, *args: str) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


# ----------------------------------------------------------------------------- sweep
def test_sweep_of_an_imported_object_equals_the_builtin_cube(catalog):
    """Both engines: every cell of box6 (grasps from its file) equals the cube's cell."""
    spec_file = catalog / "spec.yaml"
    spec_file.write_text(f"objects: [cube, {BOX}]\ngrasp_files: {{{BOX}: box6_grasps.json}}\n"
                         "grasps: [0, 3]\nsigmas: [0.0, 0.02]\nengines: [pybullet, fast]\n"
                         "samples: 12\nchunk: 6\nseed: 3\n")
    spec = SweepSpec.from_file(spec_file)  # the grasp file is relative to the spec file
    with LocalExecutor(1) as ex:
        rows, ran, _ = run_sweep(spec, catalog / "sweep", ex, progress=False)
    assert ran == 2 * 2 * 2 * 2 * 2
    cube = {(r["grasp"], r["sigma"], r["engine"]): r for r in rows if r["object"] == "cube"}
    box = {(r["grasp"], r["sigma"], r["engine"]): r for r in rows if r["object"] == BOX}
    assert cube.keys() == box.keys() and len(box) == 8
    for key, row in box.items():
        assert row["p_fc"] == cube[key]["p_fc"] and row["samples"] == 12
        # r_max of the two differs in the last bit: Q (scaled by 1 / r_max; the nominal one
        # computed from the contacts too) by as much
        assert row["q_nominal"] == pytest.approx(cube[key]["q_nominal"], rel=1e-9)
        assert row["q_mean"] == pytest.approx(cube[key]["q_mean"], rel=1e-9, nan_ok=True)
    assert any(0 < r["p_fc"] < 1 for r in box.values())  # the noise does something
    # the store knows the grasp file: another file under the same name is not mixed in
    other = json.loads((catalog / "box6_grasps.json").read_text())
    other["grasps"] = other["grasps"][::-1]
    (catalog / "reversed.json").write_text(json.dumps(other))
    changed = catalog / "changed.yaml"
    changed.write_text(spec_file.read_text().replace("box6_grasps.json", "reversed.json"))
    with LocalExecutor(1) as ex, pytest.raises(SpecError, match="box6 with other grasps"):
        run_sweep(SweepSpec.from_file(changed), catalog / "sweep", ex, progress=False)
    # nor numbers of the object as it was before a re-import
    import_object(catalog / "box6.obj", BOX, force=True)
    with LocalExecutor(1) as ex, pytest.raises(SpecError, match="another version of the obj"):
        run_sweep(SweepSpec.from_file(spec_file), catalog / "sweep", ex, progress=False)


def test_sweep_spec_errors_for_grasp_files(catalog, capsys):
    """One line each, before any work: no file for an imported object, a missing file, a
    file of another object's grasps, a key not among the objects."""
    cases = [({"objects": [BOX]}, "'box6' is an imported object and has no shipped grasp "
                                  "set; give its grasp file in 'grasp_files'"),
             ({"objects": [BOX], "grasp_files": {BOX: "nope.json"}}, "no such file"),
             ({"objects": ["cube"], "grasp_files": {"cube": "box6_grasps.json"}},
              "is a grasp of box6"),
             ({"objects": [BOX], "grasp_files": {"cube": "box6_grasps.json"}},
              "grasp_files names 'cube', which is not in 'objects'"),
             ({"objects": [BOX], "grasp_files": {BOX: "box6_grasps.json"}, "grasps": [12]},
              "grasp 12 does not exist for box6 (its grasp file has grasps 0..11)")]
    for change, message in cases:
        with pytest.raises(SpecError, match=message.replace("(", r"\(").replace(")", r"\)")):
            SweepSpec.from_dict({"sigmas": [0.01], **change}, base=catalog)
    spec = catalog / "no_file.yaml"
    spec.write_text(f"objects: [{BOX}]\nsigmas: [0.01]\n")
    code, _, err = cli(capsys, "sweep", spec, "--out", catalog / "never")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "grasp_files" in err
    assert not (catalog / "never").exists()


# ----------------------------------------------------------------------------- reproduce
def test_the_env_says_how_to_give_it_grasps_of_an_imported_object(catalog):
    """The env's words, not a command's flags: the grasp file goes in as ``grasp_file``."""
    from kinegrasp_env.envs.kinegrasp import KineGraspEnv

    with pytest.raises(ValueError, match=f"^'{BOX}' is an imported object and has no shipped "
                                         "grasp set; plan grasps .* and give the env that "
                                         f"file: grasp_file='{BOX}_grasps.json'$"):
        KineGraspEnv(objects=(BOX,))
    env = KineGraspEnv(objects=(BOX,), grasp_file=str(catalog / "box6_grasps.json"))
    env.reset(seed=0)
    assert env.grasp.object == BOX


def test_reproduce_fig9_on_an_imported_object_equals_the_builtin_cube(catalog, capsys):
    """``reproduce fig9 --grasps FILE``: the file's first 10 grasps, both engines, the same
    numbers as the cube's first 10 shipped grasps."""
    common = ("--samples", "6", "--processes", "1")
    for engine in ("pybullet", "fast"):
        out_box, out_cube = catalog / f"f9_{engine}", catalog / f"f9c_{engine}"
        code, _, err = cli(capsys, "reproduce", "fig9", "--grasps", catalog / "box6_grasps.json",
                           "--engine", engine, "--out", out_box, *common)
        assert code == 0, err
        code, _, err = cli(capsys, "reproduce", "fig9", "--object", "cube", "--engine", engine,
                           "--out", out_cube, *common)
        assert code == 0, err
        box, cube = rows_of(out_box / "fig9.csv"), rows_of(out_cube / "fig9.csv")
        assert len(box) == len(cube) == 10 and {r["object"] for r in box} == {BOX}
        assert [(r["id"], r["p_fc"]) for r in box] == [(r["id"], r["p_fc"]) for r in cube]


def test_reproduce_fig10_on_an_imported_object(catalog, capsys):
    """fig10: null-space variants of the file's first grasp; the cube's own variants."""
    common = ("--samples", "4", "--processes", "1", "--engine", "fast")
    code, _, err = cli(capsys, "reproduce", "fig10", "--object", BOX, "--grasps",
                       catalog / "box6_grasps.json", "--out", catalog / "f10", *common)
    assert code == 0, err
    code, _, err = cli(capsys, "reproduce", "fig10", "--object", "cube", "--grasps", "10",
                       "--out", catalog / "f10c", *common)
    assert code == 0, err
    box, cube = rows_of(catalog / "f10" / "fig10.csv"), rows_of(catalog / "f10c" / "fig10.csv")
    assert [(r["id"], r["p_fc"]) for r in box] == [(r["id"], r["p_fc"]) for r in cube]
    assert len(box) == 10 and box[0]["id"] == "0v1"


def test_reproduce_errors_for_imported_objects(catalog, capsys):
    """One line, exit 2, nothing written."""
    grasps = catalog / "box6_grasps.json"
    cases = [(("fig9", "--object", BOX), "box6 is an imported object and has no shipped grasp "
                                         "set; give its grasps with --grasps FILE"),
             (("fig10", "--object", "cube", "--grasps", grasps), "holds grasps of box6"),
             (("fig9", "--grasps", catalog / "nope.json"), "no such file"),
             (("table1", "--object", BOX), "box6 is an imported object and has no shipped "
                                           "grasp set; give its grasps with --grasps FILE"),
             (("table1", "--object", "cube", "--grasps", grasps), "holds grasps of box6")]
    for args, message in cases:
        code, _, err = cli(capsys, "reproduce", *args, "--samples", "4",
                           "--out", catalog / "never")
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not (catalog / "never").exists()


# ----------------------------------------------------------------------------- --up
@pytest.mark.parametrize("up", ["x", "y"])
def test_up_axis_becomes_z(tmp_path, monkeypatch, capsys, up):
    """A cone whose apex points along +``up`` in the file (off the origin) stands on its
    base after ``--up``: height = the file's extent along ``up`` (from the file's own
    vertices), apex alone at the top over the base's centre; the setting is part of the
    entry (another --up needs --force) and listed."""
    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    importer.forget()
    cone = trimesh.creation.cone(0.03, 0.08, sections=24)  # apex along +z
    to_up = {"x": trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]),
             "y": trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0])}[up]
    cone.apply_transform(to_up)
    cone.apply_translation([0.4, -0.2, 0.1])
    cone.export(tmp_path / "cone.obj")
    source = trimesh.load(tmp_path / "cone.obj", force="mesh", process=False).vertices
    axis = "xyz".index(up)
    assert np.sum(source[:, axis] > source[:, axis].max() - 1e-6) == 1  # the apex, along up
    code, _, err = cli(capsys, "objects", "add", tmp_path / "cone.obj", "--up", up)
    assert code == 0, err
    obj = load_object("cone")
    vertices = obj.mesh.vertices
    height = np.ptp(source[:, axis])
    assert obj.size[2] == pytest.approx(height, abs=1e-9)
    others = sorted(np.ptp(source[:, k]) for k in range(3) if k != axis)
    assert sorted(obj.size[:2]) == pytest.approx(others, abs=1e-9)
    top = vertices[vertices[:, 2] > height - 1e-6]
    assert len(top) == 1 and np.allclose(top[0, :2], 0.0, atol=1e-9)  # the apex, centred
    assert np.sum(np.abs(vertices[:, 2]) < 1e-9) >= 24  # the base ring lies on z = 0
    entry = json.loads((tmp_path / "home" / "objects" / "cone" / "entry.json").read_text())
    moved = source @ np.asarray(entry["source_to_object"])[:3, :3].T + \
        np.asarray(entry["source_to_object"])[:3, 3]
    np.testing.assert_allclose(np.sort(moved, axis=0), np.sort(vertices, axis=0), atol=1e-9)
    with pytest.raises(CatalogError, match="already exists"):
        import_object(tmp_path / "cone.obj")  # up z: another setting
    code, out, _ = cli(capsys, "objects", "--json")
    assert {r["name"]: r["up"] for r in json.loads(out)}["cone"] == up
    code, out, _ = cli(capsys, "objects")
    assert [line.endswith(f"cone.obj; up axis {up} (turned to z)")
            for line in out.splitlines() if line.startswith("cone ")] == [True]


def test_up_z_keeps_the_keys_of_earlier_entries():
    """``--up z`` (the default) adds nothing to an entry's key: entries imported before the
    option existed are still reused."""
    assert entry_key("d", ImportSettings()) == entry_key("d", ImportSettings(up="z"))
    assert entry_key("d", ImportSettings()) != entry_key("d", ImportSettings(up="y"))
    with pytest.raises(CatalogError, match="up must be one of x, y, z, got 'w'"):
        ImportSettings(up="w").check()


# ----------------------------------------------------------------------------- caches
def test_a_forced_reimport_reaches_every_cache_in_the_process(tmp_path, monkeypatch):
    """Import a box at half size, use it (engines, packed parts, grid), re-import it at full
    size under the same name in the same process: every engine now gives the built-in
    cube's numbers, the exact segment distance and the grid see the new top face."""
    from kinegrasp_env.closing.capsule_gap import posed_min_distance
    from kinegrasp_env.closing.packed_geometry import packed
    from kinegrasp_env.closing.segment_distance import closest_to_segments
    from kinegrasp_env.world.sdf import object_grid

    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    importer.forget()
    trimesh.creation.box(extents=(0.06, 0.06, 0.06)).export(tmp_path / "blk.obj")
    grasp = dataclasses.replace(grasp_by_index("cube", 0), object="blk")

    def use() -> tuple[dict, float, float]:
        stats = {e: evaluate_grasp(grasp, sigma=0.01, n=6, seed=0, engine=e)
                 for e in ("pybullet", "fast")}
        obj = load_object("blk")
        above = np.array([[-0.01, 0.0, 0.07], [0.01, 0.0, 0.07]])  # 1 cm over a 6 cm top
        gap = float(closest_to_segments(obj, above[:1], above[1:])[2][0])
        grid = float(posed_min_distance(object_grid("blk"), np.eye(4)[None], above[:1])[0])
        assert packed("blk").planes[:, 3].min() == pytest.approx(-obj.size[2], abs=1e-12)
        return stats, gap, grid

    import_object(tmp_path / "blk.obj", "blk", ImportSettings(scale=0.5))
    small, small_gap, small_grid = use()
    # the grid holds float32 values
    assert small_gap == pytest.approx(0.04, abs=1e-12) and small_grid == pytest.approx(0.04,
                                                                                      abs=1e-6)
    import_object(tmp_path / "blk.obj", "blk", ImportSettings(scale=1.0), force=True)
    big, big_gap, big_grid = use()
    assert big_gap == pytest.approx(0.01, abs=1e-12) and big_grid == pytest.approx(0.01,
                                                                                  abs=1e-6)
    cube = {e: evaluate_grasp(grasp_by_index("cube", 0), sigma=0.01, n=6, seed=0, engine=e)
            for e in ("pybullet", "fast")}
    for engine in ("pybullet", "fast"):
        assert big[engine].counts == cube[engine].counts
        assert big[engine].q_mean == pytest.approx(cube[engine].q_mean, rel=1e-9, nan_ok=True)
        assert small[engine].counts != big[engine].counts


def test_every_re_import_is_a_new_version(catalog):
    """A re-import with the same file and settings, at once (within the same second), still
    gives the entry a new version: caches and results stores keyed by it never take the new
    entry for the old one."""
    from kinegrasp_env.world.objects import object_version

    versions = {object_version(BOX)}
    for _ in range(3):
        import_object(catalog / "box6.obj", BOX, force=True)
        versions.add(object_version(BOX))
    assert len(versions) == 4


def test_a_workers_engine_follows_a_re_import(tmp_path, monkeypatch):
    """The engines a worker process keeps for its chunks (``chunks.robot_engine``,
    every robot's sweep and chunked runs) are keyed by the object's version: an object
    re-imported at another size under the same name gets a new engine, which holds the new
    geometry (its height, as the import made it), and the stale one is dropped."""
    from kinegrasp_env.montecarlo import chunks

    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    importer.forget()
    trimesh.creation.box(extents=(0.06, 0.06, 0.06)).export(tmp_path / "blk.obj")
    try:
        import_object(tmp_path / "blk.obj", "blk", ImportSettings(scale=0.5))
        small = chunks.robot_engine("fast", "kuka_sdh", "blk")
        assert small.obj.size[2] == pytest.approx(0.03, abs=1e-9)
        assert chunks.robot_engine("fast", "kuka_sdh", "blk") is small
        import_object(tmp_path / "blk.obj", "blk", ImportSettings(scale=1.0), force=True)
        big = chunks.robot_engine("fast", "kuka_sdh", "blk")
        assert big is not small and big.obj.size[2] == pytest.approx(0.06, abs=1e-9)
        assert small not in chunks._ENGINES.values()
    finally:
        chunks.close_engines()
