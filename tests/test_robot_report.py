"""``kinegrasp report --robot panda`` and ``kinegrasp reproduce --robot``.

The page's P(FC) values are compared with ``kinegrasp evaluate`` run on its own for each
grasp (same options, same seed: the same draws); the drawn robot is compared with where
forward kinematics puts its links: the palm with the project's own kinematics
(:class:`~kinegrasp_env.robot.kinematics.Kinematics`, the URDF's joint chain), a jaw moved by
the closing with pybullet's ``getLinkState`` in the engine's own world after its closing,
each applied to the link's mesh read independently from its OBJ file (trimesh).
"""

from __future__ import annotations

import csv
import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from kinegrasp_env.cli.main import main
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.toolkit.report.plotly import decode_typed_array
from kinegrasp_env.world.grasps import shipped_grasps

OBJECT, SIGMA, SAMPLES, SEED = "cube", "0.02", "12", "3"
#: Largest distance (m) between a drawn link's vertex centroid and the centroid placed by
#: forward kinematics: measured 9.8e-7 (palm, against the project's kinematics: pybullet
#: keeps the URDF's joint origins in single precision, 0.333 as 0.33300000429) and 3.3e-7
#: (jaws, against pybullet) over the cube's 4 grasps; tolerance 1e-5 m, a margin of 10x,
#: far below what a wrong frame gives (the hand's inertial offset alone is 4 cm).
CENTROID_TOL = 1e-5


@pytest.fixture(scope="module")
def page(tmp_path_factory) -> dict:
    """The panda report of the cube's shipped grasps: its HTML, its --json output."""
    out = tmp_path_factory.mktemp("report") / "panda.html"
    import contextlib
    import io

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main(["report", "--robot", "panda", "--object", OBJECT, "--grasp",
                     ",".join(g.id for g in shipped_grasps(OBJECT, "panda")), "--sigma", SIGMA,
                     "--samples", SAMPLES, "--seed", SEED, "--out", str(out), "--json"])
    assert code == 0
    return {"html": out.read_text(), "json": json.loads(buffer.getvalue())}


def figure(html: str, key: str) -> dict:
    """The JSON of the page's script element ``key``."""
    match = re.search(rf'<script type="application/json" id="{key}">(.*?)</script>', html,
                      re.S)
    assert match, key
    return json.loads(match.group(1).replace("<\\/", "</"))


def test_one_scene_per_grasp(page):
    grasps = shipped_grasps(OBJECT, "panda")
    scenes = re.findall(r'id="fig-(scene-\d+)"', page["html"])
    assert scenes == [f"scene-{k}" for k in range(len(grasps))]
    for key in scenes:
        traces = figure(page["html"], f"fig-{key}")["data"]
        robot = [t for t in traces if t.get("name") == "robot (closed, nominal)"]
        assert robot and all(t["kgInstances"] for t in robot)
    assert "collision geometry" in page["html"] and "panda_hand" in page["html"]


def test_pfc_equals_evaluate(page, capsys):
    """Each grasp's P(FC) on the page and in --json equals ``kinegrasp evaluate``'s on the
    same draws (its own command, its own engine)."""
    on_page = {g: float(v) for g, v in re.findall(
        r'class="kg-pfc" data-grasp="([^"]*)" data-value="([^"]*)"', page["html"])}
    in_json = {r["grasp"]: r["p_fc"] for r in page["json"]["runs"]}
    grasps = shipped_grasps(OBJECT, "panda")
    assert len(on_page) == len(in_json) == len(grasps)
    capsys.readouterr()
    for index, grasp in enumerate(grasps):
        assert main(["evaluate", "--robot", "panda", "--object", OBJECT, "--grasps",
                     f"assets/grasps/panda/{OBJECT}.json", "--grasp", str(index), "--sigma",
                     SIGMA, "--samples", SAMPLES, "--seed", SEED, "--json"]) == 0
        expected = json.loads(capsys.readouterr().out)["p_fc"]
        assert on_page[grasp.id] == expected
        assert in_json[grasp.id] == expected
    assert len(set(on_page.values())) > 1  # the grasps differ: a mix-up would show


def drawn_link(html: str, scene: int | str, link: str) -> np.ndarray:
    """The world vertices (V, 3) of ``link`` as scene ``scene`` (an index, or the figure's
    key) draws the closed robot (the page's script: the library mesh placed by its instance
    pose)."""
    from kinegrasp_env.robot.picture import robot_geometry

    shapes = robot_geometry(load_robot("panda"), []).shapes  # which piece is which link
    keys = {f"robot:panda:{k}" for k, s in enumerate(shapes) if s.link == link}
    library = figure(html, "kg-meshes")
    points = []
    key = f"fig-scene-{scene}" if isinstance(scene, int) else f"fig-{scene}"
    for trace in figure(html, key)["data"]:
        if trace.get("name") != "robot (closed, nominal)":
            continue
        for key, pose in trace["kgInstances"]:
            if key in keys:
                vertices = decode_typed_array(library[key]["v"]).reshape(-1, 3)
                pose = np.asarray(pose).reshape(3, 4)
                points.append(vertices @ pose[:, :3].T + pose[:, 3])
    assert points, link
    return np.concatenate(points)


def obj_centroid(link: str) -> np.ndarray:
    """The centroid of the convex hull's vertices of ``link``'s collision OBJ, in the link
    frame (the URDF's collision origin applied), read by trimesh."""
    import trimesh

    from kinegrasp_env.robot.model import rpy_to_matrix

    description = load_robot("panda")
    root = ET.parse(description.urdf).getroot()
    element = next(e for e in root.findall("link") if e.get("name") == link).find("collision")
    mesh = element.find("geometry/mesh").get("filename").replace("package://", "")
    hull = trimesh.load(description.urdf.parent / mesh, force="mesh").convex_hull
    origin = element.find("origin")
    rot, shift = np.eye(3), np.zeros(3)
    if origin is not None:
        rot = rpy_to_matrix(*map(float, origin.get("rpy", "0 0 0").split()))
        shift = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
    return np.asarray(hull.vertices).mean(axis=0) @ rot.T + shift


def test_palm_where_kinematics_puts_it(page):
    """The palm (not moved by the closing) against the project's own forward kinematics."""
    from kinegrasp_env.robot.kinematics import Kinematics

    description = load_robot("panda")
    kin = Kinematics(description.model)
    for k, grasp in enumerate(shipped_grasps(OBJECT, "panda")):
        pose = kin.pose(grasp.q0, description.palm_link)[0]
        expected = pose[:3, :3] @ obj_centroid(description.palm_link) + pose[:3, 3]
        drawn = drawn_link(page["html"], k, description.palm_link).mean(axis=0)
        assert np.linalg.norm(drawn - expected) < CENTROID_TOL


def test_jaws_where_pybullet_puts_them(page):
    """Each jaw, as the closing left it, against ``getLinkState`` in the engine's own
    world after its own closing of the grasp."""
    from kinegrasp_env.closing.generic_reference import RobotWorld
    from kinegrasp_env.world.objects import load_object

    description = load_robot("panda")
    world = RobotWorld(description, load_object(OBJECT))
    try:
        for k, grasp in enumerate(shipped_grasps(OBJECT, "panda")):
            world.auto_close(grasp.q0)
            for link in description.fingertip_links:
                pose = world.link_pose(link)
                expected = pose[:3, :3] @ obj_centroid(link) + pose[:3, 3]
                drawn = drawn_link(page["html"], k, link).mean(axis=0)
                assert np.linalg.norm(drawn - expected) < CENTROID_TOL
    finally:
        world.close()


def scene_traces(html: str, scene: int, prefix: str) -> list[dict]:
    return [t for t in figure(html, f"fig-scene-{scene}")["data"]
            if t.get("name", "").startswith(prefix)]


def test_noisy_arms_where_pybullet_puts_them(page):
    """Each grasp's scene draws the arm's skeleton at its first draws (all 12: fewer than
    the default 20), one trace per outcome with evaluate's counts; the skeletons of an
    outcome's trace end, in draw order, at the palm origins that pybullet's own forward
    kinematics (``getLinkState`` of the URDF) gives at the configurations of the draws with
    that outcome (evaluate's draws of the same seed)."""
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

    from kinegrasp_env.montecarlo.draws import OUTCOMES
    from kinegrasp_env.montecarlo.evaluate import (
        evaluate_grasp,
        make_engine,
        robot_configurations,
    )

    description = load_robot("panda")
    client = BulletClient(connection_mode=pybullet.DIRECT)
    body = client.loadURDF(str(description.urdf), useFixedBase=True)
    index = {client.getJointInfo(body, j)[1].decode(): j for j in range(client.getNumJoints(body))}
    palm = next(j for j in range(client.getNumJoints(body))
                if client.getJointInfo(body, j)[12].decode() == description.palm_link)
    counts = {r["grasp"]: r["outcomes"] for r in page["json"]["runs"]}
    with make_engine("pybullet", "panda", OBJECT) as engine:
        for k, grasp in enumerate(shipped_grasps(OBJECT, "panda")):
            q = robot_configurations(grasp, engine, sigma=float(SIGMA), n=int(SAMPLES),
                                     seed=int(SEED))
            outcome = evaluate_grasp(grasp, sigma=float(SIGMA), n=int(SAMPLES),
                                     seed=int(SEED), engine=engine).draws.outcome
            palms = []
            for row in q:
                for joint, value in zip(description.arm_joints, row, strict=False):
                    client.resetJointState(body, index[joint], float(value))
                palms.append(client.getLinkState(body, palm, computeForwardKinematics=True)[4])
            palms = np.asarray(palms)
            traces = {t["name"].split(": ")[1].split(" (")[0]: t
                      for t in scene_traces(page["html"], k, "noisy arms: ")}
            assert sum(int(t["name"].split("(")[-1][:-1]) for t in traces.values()) == int(
                SAMPLES)
            for o, name in enumerate(OUTCOMES):
                rows = np.flatnonzero(outcome == o)
                trace = traces.get(name.replace("_", " "))
                assert len(rows) == (0 if trace is None else int(
                    trace["name"].split("(")[-1][:-1])) == counts[grasp.id][name]
                if trace is None:
                    continue
                line = np.column_stack([decode_typed_array(trace[a]) for a in "xyz"])
                ends = line[np.flatnonzero(np.isnan(line[:, 0])) - 1]
                np.testing.assert_allclose(ends, palms[rows], atol=CENTROID_TOL)
    client.disconnect()


def test_contact_points_on_the_cube_and_capped(tmp_path, capsys):
    """``--max-points 10``: ten of the draws' contact points drawn per grasp (the page says
    of how many), each on the cube's surface (within 0.1 mm of trimesh's closest point on
    its mesh, in the cube's frame: a point drawn in the wrong frame lies centimetres off)."""
    from kinegrasp_env.world.objects import load_object

    out = tmp_path / "capped.html"
    assert main(["report", "--robot", "panda", "--object", OBJECT, "--grasp", "0", "--sigma",
                 SIGMA, "--samples", "20", "--seed", SEED, "--max-points", "10",
                 "--arm-draws", "0", "--out", str(out)]) == 0
    html = out.read_text()
    assert "first run&#x27;s draws: 10 of" in html
    assert not scene_traces(html, 0, "noisy arms")
    cube = load_object(OBJECT)
    shown = [t for t in figure(html, "fig-scene-0")["data"] if t.get("mode") == "markers"
             and t.get("visible") is True]
    points = np.concatenate([np.column_stack([decode_typed_array(t[a]) for a in "xyz"])
                             for t in shown])
    assert len(points) == 10
    local = points @ cube.pose_inverse[:3, :3].T + cube.pose_inverse[:3, 3]
    _, distance, _ = cube.mesh.nearest.on_surface(local)  # trimesh's closest points
    assert distance.max() < 1e-4


@pytest.mark.parametrize("figure_name", ["table1", "fig7", "fig9"])
def test_reproduce_refuses_in_one_line(figure_name, capsys, tmp_path):
    """An object the robot has no grasps of is one line, and nothing is written."""
    code = main(["reproduce", figure_name, "--robot", "panda", "--object", "mug",
                 "--samples", "5", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1
    assert "no shipped grasps of 'mug'" in err
    assert not (tmp_path / "out").exists()


def test_reproduce_fig10_of_panda(capsys, tmp_path):
    """fig10 of the panda: variants of the cube's grasp 0 along the self-motion (distinct
    elbow angles), the robust and the fragile one marked."""
    out = tmp_path / "fig10"
    assert main(["reproduce", "fig10", "--robot", "panda", "--object", OBJECT, "--grasps", "3",
                 "--samples", "8", "--engine", "pybullet", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "fig10.csv").open()))
    assert len(rows) >= 2 and {r["robot"] for r in rows} == {"panda"}
    angles = [float(r["elbow_angle"]) for r in rows]
    assert min(np.diff(sorted(angles))) > 0.1
    assert sorted(r["config"] for r in rows if r["config"]) == ["fragile", "robust"]


@pytest.fixture()
def elbow_page(tmp_path, capsys) -> tuple[dict, str]:
    """(the printed optimization, the page) of ``elbow --robot panda --report``."""
    out = tmp_path / "elbow.html"
    assert main(["elbow", "--robot", "panda", "--object", OBJECT, "--grasp", "0", "--sigma",
                 SIGMA, "--samples", "30", "--seed", SEED, "--json", "--report",
                 str(out)]) == 0
    return json.loads(capsys.readouterr().out), out


def test_elbow_report_of_the_panda(elbow_page):
    """``elbow --robot panda --report``: the printed optimization's curve on the page, the
    command that reproduces it, and the arm at the best elbow drawn where the project's
    forward kinematics puts its elbow link at the printed best configuration."""
    from kinegrasp_env.robot.kinematics import Kinematics

    printed, out = elbow_page
    html = out.read_text()
    curve = figure(html, "fig-elbow")["data"][0]
    assert curve["y"] == [c["p_fc"] for c in sorted(printed["curve"], key=lambda c: c["psi"])]
    assert (f"kinegrasp elbow --robot panda --object {OBJECT} --grasp 0 --sigma {SIGMA} "
            f"--noise gaussian --samples 30 --seed {SEED} --engine fast") in html
    description = load_robot("panda")
    pose = Kinematics(description.model).pose(np.array(printed["best_q"]), "panda_link4")[0]
    expected = pose[:3, :3] @ obj_centroid("panda_link4") + pose[:3, 3]
    drawn = drawn_link(html, "arm-best", "panda_link4").mean(axis=0)
    assert np.linalg.norm(drawn - expected) < CENTROID_TOL
    assert printed["best_psi"] != printed["nominal_psi"]  # the two views differ


@pytest.mark.expensive
def test_elbow_report_of_the_panda_in_chromium(elbow_page):
    """The page loads in headless Chromium: every figure drawn, both 3-D scenes' WebGL
    canvases not blank, no console error (:meth:`~kinegrasp_env.toolkit.report.browser.
    PageCheck.problems`)."""
    import importlib.util

    from kinegrasp_env.toolkit import report

    if report.find_chromium() is None or importlib.util.find_spec("playwright") is None:
        pytest.skip("the browser tests need Chromium on PATH and Playwright")
    check = report.check_page(elbow_page[1])
    assert check.problems(scenes=2) == []



def test_near_white_links_are_drawn_in_a_colour_that_shows():
    """The Panda's links are white in its URDF: on the scenes' near-white background they
    vanished (and their legend swatch with them). A colour whose every channel is above
    LIGHT_CHANNEL is drawn in LIGHT_LINK_COLOUR; other colours are kept."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.picture import LIGHT_LINK_COLOUR, _rgb, robot_geometry

    light = "rgb({}, {}, {})".format(*(round(255 * v) for v in LIGHT_LINK_COLOUR))
    assert _rgb((1.0, 1.0, 1.0, 1.0)) == _rgb((0.9, 0.95, 0.9, 1.0)) == light
    assert _rgb((0.9, 0.2, 0.1, 1.0)) == "rgb(230, 51, 26)"
    colours = {shape.color for shape in robot_geometry(load_robot("panda"), [{}]).shapes}
    channels = [[int(v) for v in c[4:-1].split(",")] for c in colours]
    assert light in colours and all(min(c) <= 0.85 * 255 for c in channels), colours
