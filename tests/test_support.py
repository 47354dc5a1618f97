"""Object placement and the support table.

What each test proves:
- ``test_probe_matches_point_sampling``: the table test (pybullet's GJK on the links'
  collision shapes) agrees with an independent computation: points sampled on every link's
  collision geometry, read from the URDF here (meshes via trimesh, capsules and cylinders
  sampled by formula) and placed by the project's forward kinematics, tested for lying
  inside the box; draws within a 2 mm band of touching (where sampling cannot decide) are
  left out and counted.
- ``test_table_changes_only_the_draws_in_it``: with a table, exactly the draws the fast
  engine's table test flags (itself checked against the probe in
  ``tests/test_table_check.py``) become ``start_collision`` (both kinematic engines), every
  other draw is the same bits as without the table.
- ``test_turning_the_scene_leaves_the_grasp``: an invariant of placement: the object turned
  by yaw about the robot's base axis and the first arm joint turned by the same angle give
  the same contacts in the object frame and the same Q (both engines).
- ``test_screen_never_drops_a_draw_in_the_table``: the probe's forward-kinematics screen
  changes no verdict (pybullet asked about every draw gives the same answers).
- the placed copies' shipped grasps, the CLI's one-line errors, the planner avoiding the
  table, and the holding test marking draws in the table.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import trimesh

from kinegrasp_env.montecarlo.draws import START_COLLISION
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.physics.protocol import HOLD_OUTCOMES
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.robot.default_robot import default_hand_mount, urdf_path
from kinegrasp_env.robot.model import rpy_to_matrix
from kinegrasp_env.world.grasps import NoGraspSetError, shipped_grasps
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.placement import place_object
from kinegrasp_env.world.support import SupportTable, placement_pose
from tests.cli_helpers import run_cli
from tests.table_probe_reference import TableProbe


@pytest.fixture(scope="module", autouse=True)
def own_catalog(tmp_path_factory):
    """The placed copies of these tests live in a catalog of their own (the one the other
    tests share stays as they expect it: built-in objects only)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("KINEGRASP_HOME", str(tmp_path_factory.mktemp("support_home")))
        yield


@pytest.fixture(scope="module")
def tabled(own_catalog):
    """Placed copies of the cube and the mug on the default table (their shipped grasps: 11
    and 7 of 12 start in it at zero noise)."""
    for name in ("cube", "mug"):
        place_object(name, as_name=f"{name}_on_table", table=SupportTable(), force=True)
    return {name: f"{name}_on_table" for name in ("cube", "mug")}


def noisy(q0s: np.ndarray, sigma: float, per: int, seed: int) -> np.ndarray:
    """(len(q0s) * per, 14) configurations with N(0, sigma) on the arm joints."""
    q = np.repeat(q0s, per, axis=0)
    q[:, :7] += np.random.default_rng(seed).normal(0.0, sigma, (len(q), 7))
    return q


def link_samples(per_shape: int = 1500) -> dict[str, np.ndarray]:
    """Points (m, 3) on every link's collision geometry, in the link frame, from the URDF."""
    rng = np.random.default_rng(0)
    root = ET.parse(urdf_path()).getroot()
    out: dict[str, list[np.ndarray]] = {}
    for link in root.iter("link"):
        for col in link.iter("collision"):
            origin = col.find("origin")
            tf = np.eye(4)
            if origin is not None:
                tf[:3, :3] = rpy_to_matrix(*map(float, origin.get("rpy", "0 0 0").split()))
                tf[:3, 3] = list(map(float, origin.get("xyz", "0 0 0").split()))
            pts = shape_samples(col.find("geometry")[0], per_shape, rng)
            out.setdefault(link.get("name"), []).append(pts @ tf[:3, :3].T + tf[:3, 3])
    return {k: np.concatenate(v) for k, v in out.items()}


def shape_samples(geom, n: int, rng) -> np.ndarray:
    """Points on one URDF geometry (mesh: its vertices and surface samples; capsule and
    cylinder along z: surface samples)."""
    if geom.tag == "mesh":
        mesh = trimesh.load(urdf_path().parent / geom.get("filename"), force="mesh")
        return np.vstack([mesh.vertices, trimesh.sample.sample_surface(mesh, n, seed=1)[0]])
    r, length = float(geom.get("radius")), float(geom.get("length"))
    phi = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(-length / 2, length / 2, n)
    side = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    if geom.tag == "cylinder":
        rad = r * np.sqrt(rng.uniform(0, 1, n))
        caps = np.column_stack([rad * np.cos(phi), rad * np.sin(phi),
                                np.where(rng.uniform(size=n) < 0.5, -1, 1) * length / 2])
        return np.vstack([side, caps])
    assert geom.tag == "capsule", geom.tag
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ends = np.where(d[:, 2:3] < 0, -length / 2, length / 2) * np.array([0, 0, 1.0])
    return np.vstack([side, r * d + ends])


def sampled_hits(q: np.ndarray, kin, box_pose: np.ndarray, half: np.ndarray,
                 samples: dict[str, np.ndarray]) -> np.ndarray:
    """(n,) whether any sampled link point lies inside the box."""
    inv = np.linalg.inv(box_pose)
    hit = np.zeros(len(q), dtype=bool)
    for name, pts in samples.items():
        poses = inv @ kin.pose(q, name)  # (n, 4, 4) link in the box frame
        local = pts @ np.swapaxes(poses[:, :3, :3], 1, 2) + poses[:, None, :3, 3]
        hit |= np.all(np.abs(local) <= half, axis=2).any(axis=1)
    return hit


def probe_distance(probe: TableProbe, q: np.ndarray) -> np.ndarray:
    """(n,) pybullet's smallest signed distance robot-table (capped at 0.05 m)."""
    out = np.empty(len(q))
    bullet, table = probe.bullet, probe.bodies["table"]
    for i, row in enumerate(q):
        probe.hits(row[None])
        pairs = bullet.getClosestPoints(probe.bodies["hand"], table, 0.05)
        for link in probe.arm_links:
            pairs += bullet.getClosestPoints(probe.bodies["arm"], table, 0.05, linkIndexA=link)
        out[i] = min([p[8] for p in pairs], default=0.05)
    return out


def test_probe_matches_point_sampling(tabled, kin):
    samples = link_samples()
    checked = 0
    for base, name in tabled.items():
        obj = load_object(name)
        q = noisy(np.array([g.q0 for g in shipped_grasps(name)]), 0.05, 10, seed=3)
        probe = TableProbe(obj)
        hits = probe.hits(q)
        box_pose, half = obj.table.box(obj.pose)
        sampled = sampled_hits(q, kin, box_pose, half, samples)
        clear = np.abs(probe_distance(probe, q)) > 0.002
        assert hits[clear].any() and (~hits[clear]).any(), base  # both verdicts are tested
        assert np.array_equal(hits[clear], sampled[clear]), base
        checked += int(clear.sum())
        probe.close()
    assert checked >= 200


def test_screen_never_drops_a_draw_in_the_table(tabled):
    """The forward-kinematics screen before the pybullet queries (bounding balls of the links'
    collision geometry) changes no verdict: the screened answer equals pybullet asked about
    every draw, with the hand moved by palm errors and the robot by object errors too."""
    from tests.table_probe_reference import arm_shift

    rng = np.random.default_rng(6)
    for name in tabled.values():
        obj = load_object(name)
        probe = TableProbe(obj)
        q = noisy(np.array([g.q0 for g in shipped_grasps(name)]), 0.05, 15, seed=7)
        offsets = np.repeat(np.eye(4)[None], len(q), axis=0)
        offsets[:, :3, 3] = rng.normal(0.0, 0.01, (len(q), 3))
        shifts = arm_shift(obj.pose, offsets)
        roots = shifts @ probe.kin.pose(q, default_hand_mount())
        roots[:, :3, 3] += rng.normal(0.0, 0.005, (len(q), 3))  # a palm-mount error
        screened = probe.hits(q, roots, shifts)
        values = probe.model.expand(q)
        joints = [n for n in probe.hand_joints if n in values]
        every = np.array([(probe.place(i, values, joints, roots[i], shifts[i]),
                           probe.touching())[1] for i in range(len(q))])
        assert 0 < every.sum() < len(q)
        assert np.array_equal(screened, every), name
        probe.close()


@pytest.mark.parametrize("engine", ["fast", "pybullet"])
def test_table_changes_only_the_draws_in_it(tabled, engine):
    name = tabled["mug"]
    q = noisy(np.array([g.q0 for g in shipped_grasps(name)]), 0.02, 6, seed=4)
    with_table = make_engine(engine, DEFAULT_ROBOT, name)
    without = make_engine(engine, DEFAULT_ROBOT, "mug")
    # the fast engine's table test: pybullet's own, test_table_check
    probe = make_engine("fast", DEFAULT_ROBOT, name)
    hits = probe.hand.table_hits(q)
    probe.close()
    assert 0 < hits.sum() < len(q)
    a, b = with_table.run(q), without.run(q)
    assert np.all(a.outcome[hits] == START_COLLISION)
    assert np.all(a.n_contacts[hits] == 0) and np.all(np.isnan(a.hand[hits]))
    for f in ("outcome", "quality", "n_contacts", "points", "normals", "finger", "hand"):
        np.testing.assert_array_equal(getattr(a, f)[~hits], getattr(b, f)[~hits], err_msg=f)
    with_table.close()
    without.close()


@pytest.mark.parametrize("engine", ["fast", "pybullet"])
def test_turning_the_scene_leaves_the_grasp(engine):
    yaw = 0.4
    pose = load_object("spray_flask").pose
    turned = placement_pose(placement_pose([0, 0, 0], yaw)[:3, :3] @ pose[:3, 3], yaw)
    place_object("spray_flask", as_name="flask_turned", position=turned[:3, 3], yaw=yaw,
                 force=True)
    q = noisy(np.array([g.q0 for g in shipped_grasps("spray_flask")[:4]]), 0.01, 5, seed=5)
    q_turned = q.copy()
    q_turned[:, 0] += yaw  # joint 1 turns about the base's z axis
    a = make_engine(engine, DEFAULT_ROBOT, "spray_flask").run(q)
    b = make_engine(engine, DEFAULT_ROBOT, "flask_turned").run(q_turned)
    assert np.array_equal(a.outcome, b.outcome)
    fc = a.outcome == 3
    assert fc.sum() >= 10
    # measured: points agree to 3e-12 m and Q to 2e-11 relative (rounding in the turned
    # frames); the margins are 100x
    np.testing.assert_allclose(b.points[fc], a.points[fc], atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(b.quality[fc], a.quality[fc], rtol=1e-8)


def test_placed_copies_and_their_grasps(tabled):
    assert [g.q0.tolist() for g in shipped_grasps(tabled["cube"])] == \
        [g.q0.tolist() for g in shipped_grasps("cube")]
    assert {g.object for g in shipped_grasps(tabled["cube"])} == {tabled["cube"]}
    place_object("cube", as_name="cube_moved", position=[0.5, 0.1, 0.1], force=True)
    with pytest.raises(NoGraspSetError, match="stands elsewhere"):
        shipped_grasps("cube_moved")
    moved = load_object("cube_moved")
    assert moved.table is None and moved.base == "cube"
    np.testing.assert_allclose(moved.pose[:3, 3], [0.5, 0.1, 0.1])
    # the same rule for every robot with a shipped set: the Panda's cube grasps for the copy
    # in place, none for the moved one, and none of an object it has no set of
    panda = shipped_grasps(tabled["cube"], "panda")
    assert [g.q0.tolist() for g in panda] == \
        [g.q0.tolist() for g in shipped_grasps("cube", "panda")]
    assert {g.object for g in panda} == {tabled["cube"]}
    assert {g.robot for g in panda} == {"panda"}
    with pytest.raises(NoGraspSetError, match=r"stands elsewhere .* --robot panda"):
        shipped_grasps("cube_moved", "panda")
    with pytest.raises(NoGraspSetError, match="robot 'panda' has no shipped grasps of 'mug_on"):
        shipped_grasps(tabled["mug"], "panda")


def test_a_sweep_reads_a_placed_copys_grasps_as_the_copy_stands_now(tabled):
    """A sweep spec takes a placed copy's shipped set while the copy stands where its base
    object does, and refuses it in one line once the copy is placed elsewhere under the same
    name in the same process (the set is read per version of the object, not once)."""
    from kinegrasp_env.montecarlo.sweep_spec import SpecError, SweepSpec

    data = {"objects": ["cube_again"], "sigmas": [0.01], "samples": 10}
    place_object("cube", as_name="cube_again", force=True)
    assert len(SweepSpec.from_dict(data).grasp_set("cube_again")) == len(shipped_grasps("cube"))
    place_object("cube", as_name="cube_again", position=[0.5, 0.1, 0.1], force=True)
    with pytest.raises(SpecError, match="stands elsewhere"):
        SweepSpec.from_dict(data)

def test_full_orientation_as_a_data_set_gives_it(tabled, capsys):
    """``--orientation X Y Z W``: the object's rotation is scipy's matrix of that quaternion
    (an independent conversion); position and table as asked; a tilted object stands without
    a table (one-line refusal, nothing written); a later move keeps the tilt."""
    from scipy.spatial.transform import Rotation

    from kinegrasp_env.cli.main import main
    from kinegrasp_env.world.store import catalog_dir

    quat = Rotation.from_euler("xyz", [90, 0, 30], degrees=True).as_quat()
    args = ["objects", "place", "cube", "--as", "cube_tilted", "--force", "--position",
            "0.6", "0.05", "0.12", "--orientation", *map(str, quat)]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "orientation (" in out and "yaw" not in out
    tilted = load_object("cube_tilted")
    np.testing.assert_allclose(tilted.pose[:3, :3], Rotation.from_quat(quat).as_matrix(),
                               atol=1e-12)
    np.testing.assert_allclose(tilted.pose[:3, 3], [0.6, 0.05, 0.12])
    place_object("cube_tilted", as_name="cube_tilted2", position=[0.5, 0, 0.1], force=True)
    np.testing.assert_allclose(load_object("cube_tilted2").pose[:3, :3], tilted.pose[:3, :3])
    before = sorted(p.name for p in catalog_dir().iterdir())
    for call, message in (([*args, "--table"], "upright object"),
                          ([*args, "--yaw", "10"], "give one"),
                          ([*args[:-5], "--orientation", "0", "0", "0", "2"],
                           "not a unit one")):
        assert main(call) == 2, call
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], (call, err)
    assert sorted(p.name for p in catalog_dir().iterdir()) == before


def test_place_echoes_a_small_turn_and_no_negative_zero(capsys):
    """The echo of ``objects place`` is read from the pose as stored, not the listing's
    rounded row: a turn of a thousandth of a degree is a turn (it read "default
    placement"), and a position a hundredth of a millimetre below 0 prints 0.000."""
    from kinegrasp_env.cli.main import main

    assert main(["objects", "place", "cube", "--as", "cube_turned", "--force",
                 "--yaw", "-1e-3"]) == 0
    out = capsys.readouterr().out
    assert "yaw -0.001 deg" in out and "default placement" not in out, out
    assert main(["objects", "place", "cube", "--as", "cube_moved", "--force",
                 "--position", "-1e-5", "0.6", "0"]) == 0
    out = capsys.readouterr().out
    assert "at (0.000, 0.600, 0.000) m" in out and "-0.000" not in out, out


@pytest.mark.expensive
def test_place_cli_errors_write_nothing(tabled, tmp_path):
    from kinegrasp_env.world.store import catalog_dir

    before = sorted(p.name for p in catalog_dir().iterdir())
    for args, message in (
            (["drill", "--table"], "built-in object"),
            (["nope", "--table"], "unknown object 'nope'"),
            (["drill", "--as", tabled["cube"], "--table"], "exists; use --force"),
            (["drill", "--as", "bad name"], "invalid object name"),
            (["drill", "--as", "d9", "--position", "0", "0", "inf"], "not a finite number"),
            (["drill", "--as", "d9", "--table-size", "0", "1"], "must be > 0"),
            (["drill", "--as", "d9", "--no-table", "--table"], "cannot go with")):
        result = run_cli("objects", "place", *args)
        assert result.returncode == 2, (args, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (args, result.stderr)
    assert sorted(p.name for p in catalog_dir().iterdir()) == before
    listed = json.loads(run_cli("objects", "--json").stdout)
    row = next(r for r in listed if r["name"] == tabled["cube"])
    assert row["source"] == "placed cube" and row["table"]["size"] == [0.6, 0.8]


@pytest.mark.expensive
def test_planner_avoids_the_table(tabled, kin):
    """The default robot's planned grasps of a cube on a table: neither the open nor the
    closed hand (nor the arm) in the table by the sampled link points' own test."""
    from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
    from kinegrasp_env.toolkit.grasp_planner import plan_grasps

    name = tabled["cube"]
    grasps = plan_grasps("kuka_sdh", name, count=3, seed=0, time_budget=240)
    assert len(grasps) >= 2
    q0 = np.array([g.q0 for g in grasps])
    with RobotReferenceEngine("kuka_sdh", name) as engine:
        draws = engine.run(q0)
    assert np.all(draws.outcome == 3)  # the nominal draw closes in force closure
    obj = load_object(name)
    box_pose, half = obj.table.box(obj.pose)
    closed = np.concatenate([q0[:, :7], draws.hand], axis=1)
    samples = link_samples()
    assert not sampled_hits(q0, kin, box_pose, half, samples).any()      # open hand
    assert not sampled_hits(closed, kin, box_pose, half, samples).any()  # closed hand


@pytest.mark.expensive
def test_the_holding_test_marks_draws_in_the_table(tabled):
    """A draw whose robot starts in the table (the fast engine's test) is a start collision
    of the holding test, its closing and its verdict, not simulated; the other is run."""
    from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine
    from kinegrasp_env.physics.protocol import HoldProtocol

    name = tabled["cube"]
    grasps = shipped_grasps(name)
    q = np.array([grasps[8].q0, grasps[0].q0])  # measured: 8 clear of the table, 0 in it
    engine = make_engine("fast", DEFAULT_ROBOT, name)
    assert engine.hand.table_hits(q).tolist() == [False, True]
    engine.close()
    with RobotHoldEngine("kuka_sdh", name, protocol=HoldProtocol()) as physics:
        draws, hold = physics.run_hold(q)
    assert draws.outcome[1] == START_COLLISION
    assert HOLD_OUTCOMES[hold.outcome[1]] == "start_collision"
    assert draws.outcome[0] != START_COLLISION
    assert HOLD_OUTCOMES[hold.outcome[0]] != "start_collision"


@pytest.mark.expensive
def test_a_table_the_hand_never_touches_changes_no_holding_test(tabled):
    """A draw clear of the table gets the holding test's verdict, grip shift and pin force
    of the same object without a table, bit for bit: the pinned object does not touch the
    table (its contacts there, at zero force, changed pybullet's solution and a verdict),
    and the release puts the table out of reach."""
    from kinegrasp_env.physics.protocol import HoldProtocol
    from kinegrasp_env.physics.robot_hold import RobotHold
    from kinegrasp_env.robot.catalog import load_robot

    q = shipped_grasps("cube")[8].q0  # clear of the table (test above)
    results = []
    for name in ("cube", tabled["cube"]):
        hold = RobotHold(load_robot("kuka_sdh"), load_object(name), 0.5, HoldProtocol())
        try:
            results.append(hold.run_draw(q)[1])
        finally:
            hold.close()
    plain, on_table = results
    assert HOLD_OUTCOMES[plain.outcome] == HOLD_OUTCOMES[on_table.outcome] == "held"
    assert (plain.grip_shift, plain.pin_force) == (on_table.grip_shift, on_table.pin_force)


def test_a_grasp_file_of_an_object_moved_since_is_refused(tabled, tmp_path):
    """A grasp file records where its object stood (its world palm poses beside its
    object-frame ones); once ``objects place`` moves the object, every reader refuses the
    file in one line naming how far it moved (here 50 mm and 30 degrees, as placed), and the
    same entries read as candidates solve again."""
    from kinegrasp_env.toolkit.candidates import read_candidates
    from kinegrasp_env.world.grasps import load_grasps, save_grasps

    cube = load_object("cube")
    place_object("cube", as_name="cube_here", force=True)
    path = save_grasps(shipped_grasps("cube_here")[:2], tmp_path / "g.json")
    assert len(load_grasps(path)) == 2
    # poses rounded to 8 decimals (a file another tool rewrote) are not a move
    rounded = json.loads(path.read_text())
    for entry in rounded["grasps"]:
        for key in ("palm_pose", "position", "quaternion"):
            entry[key] = np.round(entry[key], 8).tolist()
    (tmp_path / "rounded.json").write_text(json.dumps(rounded))
    assert len(load_grasps(tmp_path / "rounded.json")) == 2
    yaw = float(np.arctan2(cube.pose[1, 0], cube.pose[0, 0]))
    place_object("cube_here", position=cube.pose[:3, 3] + [0.05, 0.0, 0.0],
                 yaw=yaw + np.radians(30))
    with pytest.raises(ValueError, match=r"g.json grasp 0 \(id '0'\): planned with cube_here "
                       r"at another pose than the catalog's now \(50.0 mm, 30.0 degrees"):
        load_grasps(path)
    data = json.loads(path.read_text())
    data["candidates"] = data.pop("grasps")
    path.write_text(json.dumps(data))
    assert [c.id for c in read_candidates(path).candidates] == ["0", "1"]
