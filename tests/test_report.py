"""HTML reports (`kinegrasp report`, `evaluate --report`, `rank --report`, `elbow --report`):
their geometry and data against independent computations, the command line (noise specs of
several sources, grasp files of imported objects), and the pages in a real browser.

The browser tests load each page type in the system's headless Chromium, driven by Playwright,
with every request off the machine refused, and assert no console error, no request leaving
the file, every figure drawn and non-blank WebGL canvases (:meth:`PageCheck.problems`); a
deliberately broken page (a script error, an empty figure, a request to the web) must fail the
same check. They skip, saying why, when no Chromium is installed (Debian: ``apt-get install
chromium``; `.ci/run` installs it) or Playwright is missing (the ``screenshot`` extra).
"""

from __future__ import annotations

import html
import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest
import trimesh

from kinegrasp_env.assets import asset_path
from kinegrasp_env.cli import main
from kinegrasp_env.cli import report as cli_report
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES, DrawBatch
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.quality.wrenches import tangent_basis
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.robot.default_robot import PALM_LINK
from kinegrasp_env.robot.picture import robot_geometry
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_spec import load_noise_model, spec_of
from kinegrasp_env.toolkit import report
from kinegrasp_env.toolkit.elbow_search import optimize_robot_elbow
from kinegrasp_env.toolkit.report.arms import arm_skeletons, first_arms
from kinegrasp_env.toolkit.report.charts import quality_histogram
from kinegrasp_env.toolkit.report.elbow import curve_point
from kinegrasp_env.toolkit.report.geometry import (
    cone_meshes,
    transform,
)
from kinegrasp_env.toolkit.report.plotly import decode_typed_array, plotly_js
from kinegrasp_env.toolkit.report.robot import RobotRun, nominal_closings, robot_page
from kinegrasp_env.toolkit.report.scene import contact_cloud
from kinegrasp_env.world.grasps import grasp_by_index, load_grasps, shipped_grasps
from kinegrasp_env.world.objects import load_object

CHROMIUM = report.find_chromium()
PLAYWRIGHT = importlib.util.find_spec("playwright") is not None
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None or not PLAYWRIGHT, reason="the browser tests need Chromium on PATH "
    "(Debian: apt-get install chromium; .ci/run installs it) and Playwright (the screenshot "
    "extra)")
SAMPLES = 60
#: A noise model of four sources (joints, hand, object pose, friction).
SPEC = ("joints: {sigma: 0.01, distribution: gaussian}\n"
        "hand: {spread_sigma: 0.01, closing_sigma: 0.02}\n"
        "object: {translation_sigma: 0.002, rotation_sigma: 0.01}\n"
        "friction: {distribution: uniform, low: 0.3, high: 0.7}\n")
#: The most contacts a default-robot closing makes (one per link of each finger's closing
#: chain: 3 fingers x 2 links, the old engine's contact slots) and its hand joints.
MAX_CONTACTS = sum(len(finger.links) for finger in load_robot(DEFAULT_ROBOT).fingers)
HAND_DOF = load_robot(DEFAULT_ROBOT).model.dof - load_robot(DEFAULT_ROBOT).arm_dof


@pytest.fixture(scope="module")
def robot_run():
    """A small fast-engine evaluation (the page's): cube grasp 0 of the default robot, with
    its draws."""
    grasp = grasp_by_index("cube", 0)
    return grasp, evaluate_grasp(grasp, sigma=0.02, n=SAMPLES, seed=3, engine="fast")


def evaluation_page(grasp, runs, *, arms: int = 0, noise_spec=None, **kwargs) -> str:
    """The page ``evaluate --report`` writes for ``runs`` ((sigma, GraspEvaluation) pairs) of
    one grasp of the default robot, with the arm at the first run's first ``arms`` draws."""
    sigma, first = runs[0]
    drawn = first_arms(load_robot(DEFAULT_ROBOT), grasp, first, sigma, 3, "gaussian", arms)
    return robot_page(load_robot(DEFAULT_ROBOT), load_object(grasp.object),
                      [replace(grasp, q_nominal=first.q_nominal)],
                      [RobotRun(0, sigma, e) for sigma, e in runs], arms=[drawn],
                      noise_spec=noise_spec, **{"command": "kinegrasp report ...",
                                                "settings": {}, **kwargs})


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("spec") / "noise.yaml"
    path.write_text(SPEC)
    return path


@pytest.fixture(scope="module")
def elbow_run():
    """A small elbow optimization of cube grasp 0 of the default robot (fast engine, 40 draws
    per angle)."""
    grasp = grasp_by_index("cube", 0)
    return grasp, optimize_robot_elbow(grasp, JointNoise(0.02), 40, seed=3,
                                       evaluate_with="fast")


# ------------------------------------------------------------------------------- geometry
def test_typed_arrays_equal_plotlys_own_encoding():
    """Our base64 typed arrays are what plotly's own JSON encoder writes for float32 and
    uint32 arrays (plotly.io, an independent implementation), and decode back exactly."""
    import plotly.io as pio

    from kinegrasp_env.toolkit.report.plotly import typed_array

    rng = np.random.default_rng(0)
    for values in (rng.normal(size=50).astype(np.float32), np.arange(7, dtype=np.uint32)):
        theirs = json.loads(pio.to_json({"data": [{"type": "scatter3d", "x": values}]}))
        dtype = "<f4" if values.dtype == np.float32 else "<u4"
        ours = typed_array(values, dtype)
        assert ours == theirs["data"][0]["x"]
        np.testing.assert_array_equal(decode_typed_array(ours), values)
    pairs = rng.normal(size=(5, 2))
    np.testing.assert_array_equal(decode_typed_array(typed_array(pairs)), pairs.astype("<f4"))


def test_friction_cones_have_the_half_angle_of_mu():
    """Each cone: apex at the contact, axis along the outward normal with the given height,
    every edge at atan(mu) from the axis (hand formula), faces fanning round the apex."""
    rng = np.random.default_rng(1)
    points = rng.normal(size=(4, 3))
    normals = rng.normal(size=(4, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    mu, edges, height = 0.5, 8, 0.02
    vertices, faces = cone_meshes(points, normals, mu, edges, height)
    assert vertices.shape == (4 * (edges + 1), 3) and faces.shape == (4 * edges, 3)
    for c in range(4):
        apex, ring = vertices[c * (edges + 1)], vertices[c * (edges + 1) + 1:(c + 1) * (edges + 1)]
        np.testing.assert_allclose(apex, points[c], atol=1e-15)
        along = (ring - apex) @ -normals[c]
        np.testing.assert_allclose(along, height, rtol=1e-12)
        radial = np.linalg.norm((ring - apex) + np.outer(along, normals[c]), axis=1)
        np.testing.assert_allclose(np.arctan2(radial, along), np.arctan(mu), rtol=1e-12)
        t1, _ = tangent_basis(normals[c])  # edge 0 lies along t1 (docs/conventions.md)
        np.testing.assert_allclose(ring[0] - apex, -height * (normals[c] + mu * t1), atol=1e-15)
    assert set(faces[:edges, 0]) == {0}


@pytest.mark.parametrize("name", ["cube", "spray_flask", "drill", "mug"])
def test_closed_hand_touches_the_nominal_contacts(name):
    """The robot a page draws closed on the object (pybullet's reading of the URDF placed by
    pybullet's kinematics at the reference closing) touches every nominal contact of the
    shipped grasps with the link the grasp file names (against the planner's contacts,
    object frame -> world by the object's pose). Measured: at most 0.45 mm; a capsule's
    mesh is a polygon inside the capsule (its sides r (1 - cos(pi / sections)) in)."""
    description = load_robot(DEFAULT_ROBOT)
    obj = load_object(name)
    grasps = shipped_grasps(name)[:3]
    closings = nominal_closings(description, obj, grasps)
    geometry = robot_geometry(description, [values for values, _ in closings])
    for k, (grasp, (_, did_close)) in enumerate(zip(grasps, closings, strict=True)):
        assert did_close
        points = transform(grasp.points, obj.pose)
        for point, finger, link in zip(points, grasp.fingers, grasp.links, strict=True):
            name = f"f{finger + 1}_{'distal' if link else 'proximal'}"
            meshes = [trimesh.Trimesh(transform(shape.vertices, geometry.frames[k][name]),
                                      shape.faces)
                      for shape in geometry.shapes if shape.link == name]
            distance = min(trimesh.proximity.closest_point(m, [point])[1][0] for m in meshes)
            assert distance < 6e-4, (grasp.id, finger, link, distance)


def test_skeleton_follows_pybullets_link_frames(bullet_robot, model):
    """The arm skeleton a page draws (:func:`arm_skeletons`, the project's kinematics) is
    pybullet's world link frames (independent FK), from the base to the palm."""
    client, body, joints, links = bullet_robot
    description = load_robot(DEFAULT_ROBOT)
    q = np.random.default_rng(2).uniform(model.lower, model.upper, size=(3, model.dof))
    points = arm_skeletons(description, q)
    chain = [*(f"lbr_iiwa_link_{k}" for k in range(8)), "sdh_base", PALM_LINK]
    assert points.shape == (3, len(chain), 3)
    for i in range(3):
        for name, value in model.expand(q[i]).items():
            client.resetJointState(body, joints[name], float(value))
        for k, link in enumerate(chain):
            if k == 0:  # the fixed base, loaded at the origin (pybullet
                position = (0.0, 0.0, 0.0)  # reports its inertial frame instead)
            else:
                position = client.getLinkState(body, links[link],
                                               computeForwardKinematics=1)[4]
            np.testing.assert_allclose(points[i, k], position, atol=1e-6)


def test_the_pages_arms_are_the_runs_first_draws(robot_run):
    """The arms a page draws (:func:`first_arms`, rebuilt from the seed's streams) are the
    run's first draws: the engine fed them gives the outcomes and Q the run recorded."""
    from kinegrasp_env.montecarlo.engines import make_engine

    grasp, evaluation = robot_run
    arms = first_arms(load_robot(DEFAULT_ROBOT), grasp, evaluation, 0.02, 3, "gaussian", 12)
    assert arms.q.shape == (12, 14)
    np.testing.assert_array_equal(arms.q[:, 7:], np.broadcast_to(grasp.q0[7:], (12, 7)))
    with make_engine("fast", DEFAULT_ROBOT, "cube") as engine:
        again = engine.run(arms.q)
    np.testing.assert_array_equal(again.outcome, evaluation.draws.outcome[:12])
    np.testing.assert_array_equal(arms.outcome, evaluation.draws.outcome[:12])
    np.testing.assert_allclose(again.quality, evaluation.draws.quality[:12], rtol=1e-12)


def _synthetic_draws(n: int, seed: int = 0) -> DrawBatch:
    """n draws, every one with MAX_CONTACTS contacts (the worst case for the page size)."""
    rng = np.random.default_rng(seed)
    draws = DrawBatch.empty(n, MAX_CONTACTS, HAND_DOF)
    draws.outcome[:] = rng.integers(1, len(OUTCOMES), n)
    draws.quality[draws.outcome == FORCE_CLOSURE] = rng.gamma(2.0, 0.002, n)[
        draws.outcome == FORCE_CLOSURE]
    draws.n_contacts[:] = MAX_CONTACTS
    draws.points[:] = rng.normal(0.0, 0.03, (n, MAX_CONTACTS, 3)) + np.array([0.0, 0.0, 0.03])
    draws.normals[:] = [0.0, 0.0, 1.0]
    draws.finger[:] = np.repeat(np.arange(3), 2)
    draws.link[:] = np.tile([0, 1], 3)
    return draws


def test_contact_cloud_keeps_every_point_or_a_uniform_subset():
    draws = _synthetic_draws(100)
    whole = contact_cloud(draws, limit=10_000)
    assert whole.total == whole.shown == 600 and not whole.decimated
    np.testing.assert_array_equal(whole.points, draws.points.reshape(-1, 3))
    part = contact_cloud(draws, limit=250, seed=4)
    assert (part.shown, part.total, part.decimated) == (250, 600, True)
    assert np.all(np.diff(part.draw) >= 0)  # in draw order
    for point, draw, finger in zip(part.points, part.draw, part.finger, strict=True):
        slot = np.flatnonzero(np.all(draws.points[draw] == point, axis=1))
        assert slot.size == 1 and draws.finger[draw, slot[0]] == finger
    again = contact_cloud(draws, limit=250, seed=4)
    np.testing.assert_array_equal(again.points, part.points)


def test_histogram_counts_every_force_closure_draw(robot_run):
    _, stats = robot_run
    quality = stats.draws.quality[stats.draws.outcome == FORCE_CLOSURE]
    figure = quality_histogram(quality, stats.q_mean, stats.q_nominal)
    bars = figure["data"][0]
    assert sum(bars["y"]) == stats.counts["force_closure"] == quality.size
    lines = [shape["x0"] for shape in figure["layout"]["shapes"]]
    assert lines == pytest.approx([quality.mean(), stats.q_nominal], rel=1e-12)


def test_a_histogram_of_no_force_closure_draw_says_so():
    """No force-closure draw: no bar, and a note in place of an empty frame whose axes
    ran over made-up ranges (Q 0 to 6, draws -1 to 4)."""
    figure = quality_histogram(np.array([]), float("nan"), 0.0)
    assert figure["data"] == []
    texts = [note["text"] for note in figure["layout"]["annotations"]]
    assert "no force-closure draw: Q has no distribution to show" in texts
    assert not figure["layout"]["xaxis"]["showticklabels"]


def test_page_is_self_contained_and_deterministic(robot_run):
    grasp, evaluation = robot_run
    page = evaluation_page(grasp, [(0.02, evaluation)], arms=5)
    assert page == evaluation_page(grasp, [(0.02, evaluation)], arms=5)
    assert page.count(plotly_js()) == 1
    assert not re.search(r"<(script|link|img|iframe)[^>]+(src|href)=", page)
    figures = dict(re.findall(r'<script type="application/json" id="([^"]+)">(.*?)</script>',
                              page, re.S))
    assert set(figures) == {"fig-scene-0", "fig-quality-0", "fig-outcomes-0", "kg-meshes"}
    for text in figures.values():
        json.loads(text)
    outcomes = json.loads(figures["fig-outcomes-0"])["data"][0]["x"]
    assert outcomes == [evaluation.counts[name] for name in OUTCOMES]
    bars = json.loads(figures["fig-quality-0"])["data"][0]["y"]
    assert sum(bars) == evaluation.counts["force_closure"]


def test_ten_thousand_draw_page_stays_under_its_limit(robot_run):
    """Worst case: 10,000 draws with 6 contacts each (60,000 points, 15,000 drawn), the arm
    at 20 of them."""
    grasp, evaluation = robot_run
    draws = _synthetic_draws(10_000)
    big = replace(evaluation, draws=draws, n=10_000)
    page = evaluation_page(grasp, [(0.02, big)], arms=report.ARM_DRAWS)
    size = len(page.encode())
    assert size < report.PAGE_LIMIT_BYTES, size
    assert "15000 of 60000 (a uniform random subset)" in page


def test_parser_defaults_equal_the_library_constants():
    assert cli_report.MAX_POINTS_DEFAULT == report.MAX_POINTS
    assert cli_report.ARM_DRAWS_DEFAULT == report.ARM_DRAWS


# ----------------------------------------------------------------------------- command line
@pytest.mark.parametrize(("args", "needle"), [
    (["--sigma", "0.01,-0.02"], "--sigma must be >= 0, got -0.02"),
    (["--sigma", "0.01,0.01"], "--sigma: '0.01,0.01' lists a value twice"),
    (["--sigma", "0.01,,0.02"], "is not a comma-separated list of numbers"),
    (["--sigma", "4"], "--sigma must be <= pi"),
    (["--max-points", "0"], "--max-points must be >= 1, got 0"),
    (["--arm-draws", "-1"], "--arm-draws must be >= 0, got -1"),
    (["--grasp", "99"], "--grasp 99: no grasp with this id in the shipped grasps of cube"),
    (["--grasp", "0,,2"], "--grasp '0,,2': an empty id between commas"),
])
def test_report_bad_input_is_one_line_and_writes_nothing(args, needle, tmp_path, capsys):
    out = tmp_path / "page.html"
    code = main(["report", "--object", "cube", "--samples", "10", "--engine", "fast",
                 "--out", str(out), *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and needle in err[0], err
    assert not out.exists()


def test_report_out_must_not_be_a_folder(tmp_path, capsys):
    assert main(["report", "--samples", "10", "--out", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err


def test_report_command_with_several_sigmas(tmp_path, capsys):
    out = tmp_path / "sigmas.html"
    code = main(["report", "--object", "cube", "--grasp", "0", "--sigma", "0.01,0.03",
                 "--samples", "40", "--seed", "5", "--engine", "fast", "--out", str(out),
                 "--json"])
    assert code == 0
    printed = json.loads(capsys.readouterr().out)
    for sigma, row in zip((0.01, 0.03), printed["runs"], strict=True):
        stats = evaluate_grasp(grasp_by_index("cube", 0), sigma=sigma, n=40, seed=5,
                               engine="fast")
        assert row["p_fc"] == stats.p_fc and row["sigma"] == sigma
    page = out.read_text()
    assert printed["bytes"] == len(page.encode())
    curve = json.loads(re.search(r'id="fig-pfc-0">(.*?)</script>', page, re.S).group(1))
    assert curve["data"][0]["y"] == [r["p_fc"] for r in printed["runs"]]
    assert ("kinegrasp report --robot kuka_sdh --object cube --grasp 0 --sigma 0.01,0.03 "
            f"--noise gaussian --samples 40 --seed 5 --engine fast --out {out}") in page


def _cube_candidates(tmp_path, count: int) -> tuple:
    """(a file of the first ``count`` shipped cube grasps, its JSON)."""
    path = tmp_path / "grasps.json"
    data = json.loads(asset_path("grasps", "kuka_sdh", "cube.json").read_text())
    data["grasps"] = data["grasps"][:count]
    path.write_text(json.dumps(data))
    return path, data


def test_evaluate_and_rank_write_reports(tmp_path, capsys):
    page = tmp_path / "evaluate.html"
    assert main(["evaluate", "--object", "cube", "--grasp", "1", "--samples", "30",
                 "--engine", "fast", "--report", str(page)]) == 0
    assert f"report written to {page}" in capsys.readouterr().out
    text = page.read_text()
    assert "kinegrasp evaluate --robot kuka_sdh --object cube --grasp 1" in text
    assert {"fig-scene-0", "fig-quality-0", "fig-outcomes-0"} <= set(re.findall(
        r'<script type="application/json" id="([^"]+)">', text))
    candidates, data = _cube_candidates(tmp_path, 3)
    ranking = tmp_path / "ranking.html"
    assert main(["rank", str(candidates), "--samples", "20", "--engine", "fast", "--out",
                 str(tmp_path / "ranked.csv"), "--report", str(ranking)]) == 0
    text = ranking.read_text()
    rows = re.findall(r'<tr class="kg-item" data-detail="detail-c(\d+)" data-id="([^"]*)">',
                      text)
    csv_ids = [line.split(",")[0] for line in
               (tmp_path / "ranked.csv").read_text().splitlines()[1:]]
    assert [data["grasps"][int(i)]["id"] for i, _ in rows] == [j for _, j in rows] == csv_ids
    lazy = re.findall(r'<div class="kg-plot"[^>]* data-lazy ', text)
    assert len(lazy) == 3  # one 3-D scene per candidate, drawn on demand


def test_rank_page_rows_are_the_csvs_and_its_arms_the_first_draws(tmp_path, capsys):
    """``rank --report``: each row's outcome counts and P(FC) are the CSV's (written by its
    own code), and with fewer draws than the page's 10 arms it draws and says that many."""
    import csv

    candidates, _ = _cube_candidates(tmp_path, 2)
    page = tmp_path / "ranking.html"
    assert main(["rank", str(candidates), "--samples", "4", "--engine", "fast", "--out",
                 str(tmp_path / "ranked.csv"), "--report", str(page)]) == 0
    capsys.readouterr()
    text = page.read_text()
    rows = list(csv.DictReader((tmp_path / "ranked.csv").open()))
    shown = re.findall(r'<tr class="kg-item" data-detail="[^"]+" data-id="([^"]+)">(.*?)</tr>',
                       text)
    assert [grasp_id for grasp_id, _ in shown] == [r["id"] for r in rows]
    for (_, cells), row in zip(shown, rows, strict=True):
        values = re.findall(r'<td[^>]*data-value="([^"]*)"', cells)
        assert float(values[1]) == pytest.approx(float(row["p_fc"]), abs=1e-6)
        assert [int(float(v)) for v in values[8:12]] == [int(row[o]) for o in OUTCOMES]
    assert _section(text, "Settings")["noisy arms drawn"] == "4"
    scene = _figures(text)["c0-scene"]
    assert [t["name"] for t in scene["data"] if t["name"].startswith("noisy")] == [
        "noisy arms (4)"]


def test_rank_page_shows_the_hold_scores_it_ranked_by(tmp_path, capsys):
    """``rank --criterion hold --static-hold --report`` of the Panda's cube grasps: the page
    has a column for P(hold, static), P(hold) and the holding test's margin, each row's
    values the CSV's (before ``3-D``); a ranking without hold scores has none of them."""
    import csv

    from kinegrasp_env.world.grasps import shipped_grasp_file

    page, out = tmp_path / "held.html", tmp_path / "held.csv"
    assert main(["rank", str(shipped_grasp_file("cube", robot="panda")), "--sigma", "0.0033",
                 "--samples", "3", "--engine", "fast", "--criterion", "hold", "--static-hold",
                 "--out", str(out), "--report", str(page)]) == 0
    capsys.readouterr()
    text = page.read_text()
    heads = re.findall(r"<th[^>]*>([^<]*)</th>", text)
    assert heads[-4:] == ["P(hold, static)", "P(hold)", "hold margin", "3-D"]
    rows = list(csv.DictReader(out.open()))
    shown = re.findall(r'<tr class="kg-item" data-detail="[^"]+" data-id="([^"]+)">(.*?)</tr>',
                       text)
    assert [grasp_id for grasp_id, _ in shown] == [r["id"] for r in rows]
    for (_, cells), row in zip(shown, rows, strict=True):
        values = [float(v) for v in re.findall(r'<td[^>]*data-value="([^"]*)"', cells)[-3:]]
        expected = [float(row[k]) for k in ("p_hold_static", "p_hold", "hold_margin")]
        assert values == pytest.approx(expected, abs=1e-6)
    # the page's command reproduces its CSV, hold scores and all
    command = html.unescape(re.search(r'<pre class="kg-command">(.*?)</pre>', text, re.S)[1])
    words = shlex.split(command)
    again = tmp_path / "again.csv"
    words[words.index("--out") + 1], words[words.index("--report") + 1] = str(again), str(
        tmp_path / "again.html")
    assert words[0] == "kinegrasp" and main(words[1:]) == 0
    capsys.readouterr()
    assert again.read_text() == out.read_text()
    assert main(["rank", str(shipped_grasp_file("cube", robot="panda")), "--sigma", "0.0033",
                 "--samples", "3", "--engine", "fast", "--out", str(out), "--report",
                 str(page)]) == 0
    capsys.readouterr()
    assert "hold margin" not in page.read_text()


# ------------------------------------------------------------------------------- browser
@pytest.fixture(scope="module")
def pages(tmp_path_factory, robot_run, elbow_run, spec_file):
    """One page of each type: an evaluation, a P(FC)-vs-sigma page, a ranking, an elbow
    optimization, an evaluation under a noise model of four sources."""
    folder = tmp_path_factory.mktemp("pages")
    grasp, evaluation = robot_run
    second = evaluate_grasp(grasp, sigma=0.04, n=SAMPLES, seed=3, engine="fast")
    out = {"evaluate": folder / "evaluate.html", "sigmas": folder / "sigmas.html",
           "rank": folder / "rank.html", "elbow": folder / "elbow.html",
           "spec": folder / "spec.html"}
    report.write_page(out["evaluate"], evaluation_page(grasp, [(0.02, evaluation)], arms=12))
    report.write_page(out["sigmas"], evaluation_page(
        grasp, [(0.02, evaluation), (0.04, second)]))
    grasps = shipped_grasps("cube")[:4]
    rows = [{"index": i, "id": g.id, "p_fc": p, "p_fc_lo": p - 0.1, "p_fc_hi": p + 0.1,
             "q_mean": 0.01 * i, "q_std": 0.001, "q_nominal": g.q_nominal, "samples": 20}
            for i, (g, p) in enumerate(zip(grasps, (0.5, 0.9, 0.7, 0.2), strict=True))]
    rows.sort(key=lambda r: -r["p_fc"])
    description = load_robot(DEFAULT_ROBOT)
    report.write_page(out["rank"], report.rank_page(
        description, {"cube": load_object("cube")}, grasps, rows,
        command="kinegrasp rank ...", settings={},
        arms=[first_arms(description, g, None, 0.02, 0, "gaussian", 10) for g in grasps]))
    elbow_grasp, result = elbow_run
    report.write_page(out["elbow"], report.elbow_page(
        load_robot(DEFAULT_ROBOT), elbow_grasp, result, JointNoise(0.02),
        command="kinegrasp elbow ...", settings={}))
    model = load_noise_model(spec_file)
    report.write_page(out["spec"], evaluation_page(
        grasp, [(model.sigma, evaluate_grasp(grasp, n=SAMPLES, seed=3,
                                             engine="fast", noise_model=model))],
        noise_spec=spec_of(model)))
    return out


ROBOT_VERTICES = """(() => { const gd = document.getElementById('plot-scene-0');
  return gd.data.filter(t => t.name === 'robot (closed, nominal)')
    .map(t => [Array.from(t.x), Array.from(t.y), Array.from(t.z)]); })()"""
RANK_ORDER = """(() => Array.from(document.querySelectorAll('table.kg-sortable tbody tr'))
  .map(r => r.classList.contains('kg-item') ? r.children[1].textContent : 'detail-of-'
       + r.id))()"""


def _report_load(name: str, check) -> None:
    print(f"\n{name} page: parsed after {check.parsed_ms:.0f} ms, figures drawn after "
          f"{check.ready_ms:.0f} ms (from navigation start; wall {check.wall_s:.1f} s), "
          f"{len(check.canvases)} WebGL canvases: "
          + ", ".join(f"std {s['std']:.0f}, {s['colours']} colours" for s in (
              report.pixel_stats(check.screenshot, r) for r in check.canvases)))


@needs_chromium
@pytest.mark.expensive
def test_evaluation_page_in_chromium(pages):
    check = report.check_page(pages["evaluate"], probe=ROBOT_VERTICES)
    _report_load("evaluation", check)
    assert check.problems(scenes=1) == []
    assert check.rendered == check.expected == 3  # the scene, the histogram, the outcomes
    assert check.requests and all(u.startswith("file:") for u in check.requests)
    assert check.ready_ms < 20_000  # generous for a loaded 2-core CI machine; printed above
    # the page's script placed the shared meshes where their instance poses put them
    text = pages["evaluate"].read_text()
    library = json.loads(re.search(r'id="kg-meshes">(.*?)</script>', text, re.S).group(1))
    traces = [t for t in _figures(text)["scene-0"]["data"]
              if t.get("name") == "robot (closed, nominal)"]
    assert len(check.probe) == len(traces) > 0
    for (x, y, z), trace in zip(check.probe, traces, strict=True):
        expected = np.concatenate([
            decode_typed_array(library[key]["v"]).reshape(-1, 3) @ np.reshape(m, (3, 4))[:, :3].T
            + np.reshape(m, (3, 4))[:, 3] for key, m in trace["kgInstances"]])
        np.testing.assert_allclose(np.stack([x, y, z], axis=1), expected, atol=1e-6)


@needs_chromium
@pytest.mark.expensive
def test_sigma_curve_page_in_chromium(pages):
    check = report.check_page(pages["sigmas"])
    _report_load("P(FC)-vs-sigma", check)
    assert check.problems(scenes=1) == []
    assert check.rendered == check.expected == 4


def test_a_run_without_chromium_says_so_in_its_last_lines(tmp_path):
    """With no Chromium (``$KINEGRASP_CHROMIUM`` naming none) a run whose browser tests skip
    ends, just above its final counts, with a line saying so and how to install it: the
    README's test command does not skip them silently (tests/conftest.py)."""
    env = {**os.environ, "KINEGRASP_CHROMIUM": "no-such-chromium-here"}
    proc = subprocess.run([sys.executable, "-m", "pytest", __file__, "-q", "-p",
                           "no:cacheprovider", "-k", "test_sigma_curve_page_in_chromium"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, check=False)
    lines = proc.stdout.strip().splitlines()
    assert proc.returncode == 0 and lines[-1].startswith("1 skipped"), proc.stdout[-2000:]
    assert ("browser tests skipped: chromium not on PATH; install it with apt-get install "
            "chromium (1 test)") in lines[-2], proc.stdout[-2000:]


@needs_chromium
@pytest.mark.expensive
def test_rank_page_in_chromium_sorts_and_draws_views_on_demand(pages):
    """Nothing 3-D is drawn until asked; a header click sorts (detail rows follow their
    candidate); 'show 3-D' draws the candidate's scene."""
    opened = ("document.querySelectorAll('table.kg-sortable th')[2].click();"
              "document.querySelector('button.kg-show').click()")
    check = report.check_page(pages["rank"], before_screenshot=opened,
                                      probe=RANK_ORDER)
    _report_load("ranking", check)
    assert check.expected == 0 and check.rendered == 1
    assert check.problems(scenes=1) == []
    # ascending P(FC): 0.2 (id 3), 0.5 (id 0), 0.7 (id 2), 0.9 (id 1)
    assert check.probe == [x for i in ("3", "0", "2", "1")
                           for x in (i, f"detail-of-detail-c{i}")]


#: A page that asks for the web: an image and a fetch (both must be refused and reported).
REMOTE = ('<img src="http://example.com/kg.png"><script>fetch("https://example.org/kg.json")'
          '.catch(() => {});</script></body>')


@needs_chromium
@pytest.mark.expensive
@pytest.mark.parametrize(("breakage", "expected"), [
    ("script error", "kgNoSuchFunction is not defined"),
    ("empty figure", "1 WebGL canvases, expected 2"),
    ("remote request", "network request: http://example.com/kg.png")])
def test_a_broken_page_fails_the_check(pages, tmp_path, breakage, expected):
    page = pages["evaluate"].read_text()
    if breakage == "script error":
        page = page.replace("</body>", "<script>kgNoSuchFunction();</script></body>")
    elif breakage == "empty figure":
        page = re.sub(r'(<script type="application/json" id="fig-grasp">)\{"data":\[.*?\],'
                      r'"layout"', r'\1{"data":[],"layout"', page, count=1, flags=re.S)
    else:
        page = page.replace("</body>", REMOTE)
    broken = tmp_path / "broken.html"
    broken.write_text(page)
    check = report.check_page(broken)
    problems = check.problems(scenes=2)
    print(f"\n{breakage}: {problems}")
    assert any(expected in p for p in problems), problems
    if breakage == "remote request":
        assert sorted(check.remote) == ["http://example.com/kg.png",
                                        "https://example.org/kg.json"]


def test_screenshot_bad_input_is_one_line(pages, tmp_path, capsys):
    """Checked before any browser starts: a missing page, a candidate the page lacks."""
    out = tmp_path / "shot.png"
    assert main(["screenshot", str(tmp_path / "none.html"), "--out", str(out)]) == 2
    assert "none.html: no such file" in capsys.readouterr().err
    assert main(["screenshot", str(pages["rank"]), "--show", "0,nope", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has no candidate 'nope' (ids: 1, 2, 0, 3)" in err[0], err
    assert not out.exists()


@needs_chromium
@pytest.mark.expensive
def test_screenshot_command_writes_the_page_as_png(pages, tmp_path, capsys):
    out = tmp_path / "rank.png"
    assert main(["screenshot", str(pages["rank"]), "--show", "1", "--out", str(out)]) == 0
    assert "0 console errors" in capsys.readouterr().out
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert report.pixel_stats(out.read_bytes())["colours"] > 1000


@needs_chromium
@pytest.mark.expensive
def test_screenshot_command_fails_on_a_request_off_the_machine(pages, tmp_path, capsys):
    page = tmp_path / "remote.html"
    page.write_text(pages["evaluate"].read_text().replace("</body>", REMOTE))
    assert main(["screenshot", str(page), "--out", str(tmp_path / "remote.png")]) == 1
    err = capsys.readouterr().err
    assert "network request refused: http://example.com/kg.png" in err, err
    assert "network request refused: https://example.org/kg.json" in err, err


@needs_chromium
def test_screenshot_of_a_page_that_is_no_report_says_so_at_once(tmp_path, capsys):
    """A page with no report figure sets no ``window.kgReady``: the command waited its whole
    60 s timeout for it, then said "not drawn". It is done once the page has loaded, says
    what the page is not, and fails (exit 1)."""
    import time

    page = tmp_path / "plain.html"
    page.write_text("<html><body>hi</body></html>")
    start = time.monotonic()
    assert main(["screenshot", str(page), "--out", str(tmp_path / "plain.png")]) == 1
    assert time.monotonic() - start < 30  # measured 2 s; the wait was 60 s
    assert "no kinegrasp figure (not a kinegrasp report?)" in capsys.readouterr().out


def test_screenshot_without_playwright_names_the_extra(pages, tmp_path, capsys, monkeypatch):
    """Without Playwright the command stops with one line naming the extra to install."""
    monkeypatch.setitem(sys.modules, "playwright", None)
    monkeypatch.setitem(sys.modules, "playwright.sync_api", None)
    out = tmp_path / "shot.png"
    assert main(["screenshot", str(pages["rank"]), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'kinegrasp-env[screenshot]'" in err[0], err
    assert not out.exists()


@pytest.mark.skipif(not PLAYWRIGHT, reason="needs Playwright (the screenshot extra)")
def test_screenshot_with_a_browser_that_does_not_start_is_one_line(pages, tmp_path, capsys,
                                                                   monkeypatch):
    monkeypatch.setenv("KINEGRASP_CHROMIUM", "false")  # exits at once, never answers
    out = tmp_path / "shot.png"
    assert main(["screenshot", str(pages["rank"]), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "chromium did not start" in err[0], err
    assert not out.exists()


def test_the_parser_and_the_report_room_do_not_import_playwright():
    """Playwright loads when a browser starts, never with ``--help`` or the report modules
    (checked in a fresh interpreter's ``sys.modules``)."""
    code = ("import sys\n"
            "from kinegrasp_env.cli.main import build_parser\n"
            "p = build_parser()\n"
            "[s.format_help() for s in p._subparsers._group_actions[0].choices.values()]\n"
            "import kinegrasp_env.toolkit.report.browser, kinegrasp_env.cli.report\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'playwright'))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]", done.stdout


# -------------------------------------------------------------------- elbow and noise pages
def _figures(page: str) -> dict:
    """The page's figures by key (``fig-KEY``)."""
    return {key: json.loads(text) for key, text in re.findall(
        r'<script type="application/json" id="fig-([^"]+)">(.*?)</script>', page, re.S)}


def test_elbow_page_shows_the_curve_and_both_elbows(elbow_run, bullet_robot):
    """The curve is the optimizer's (psi ascending, Wilson intervals as error bars, nominal
    and best marked). Each arm view draws its own elbow's first ARM_DRAWS selection draws,
    grouped by the outcome the optimizer recorded: the fast engine fed rows 0.. of the run's
    draws at that configuration gives those outcomes again, and each skeleton ends where
    pybullet's own forward kinematics puts the palm at that draw (independent FK); the two
    elbows' draws place the elbow link centimetres apart (the null space)."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.montecarlo.evaluate import robot_configurations

    client, body, joints, links = bullet_robot
    grasp, result = elbow_run
    description = load_robot(DEFAULT_ROBOT)
    page = report.elbow_page(description, grasp, result, JointNoise(0.02), command="c",
                             settings={})
    figures = _figures(page)
    assert set(figures) == {"elbow", "arm-nominal", "arm-best"}
    curve = sorted(result.curve, key=lambda p: p.psi)
    trace = figures["elbow"]["data"][0]
    assert trace["x"] == [p.psi for p in curve] and trace["y"] == [p.p_fc for p in curve]
    y = np.array(trace["y"])
    np.testing.assert_allclose(y + trace["error_y"]["array"], [p.p_fc_ci[1] for p in curve])
    np.testing.assert_allclose(y - trace["error_y"]["arrayminus"], [p.p_fc_ci[0] for p in curve])
    assert [s["x0"] for s in figures["elbow"]["layout"]["shapes"]] == [result.nominal_psi,
                                                                      result.best_psi]
    assert f"best elbow {result.best_psi:+.3f} rad: P(FC) {result.best_p_fc:.4f}" in page
    assert result.best_psi != result.nominal_psi
    elbows = {}
    with make_engine("fast", description, "cube") as engine:
        for label, psi in (("nominal", result.nominal_psi), ("best", result.best_psi)):
            point = curve_point(result, psi)
            q = robot_configurations(replace(grasp, q0=point.q), engine, sigma=0.02,
                                     n=report.ARM_DRAWS, seed=3)
            outcome = engine.run(q).outcome
            np.testing.assert_array_equal(outcome, point.outcome[:len(q)])
            traces = {t["name"]: t for t in figures[f"arm-{label}"]["data"]
                      if t["name"].startswith("noisy arms: ")}
            counts = Counter(OUTCOMES[k] for k in outcome)
            assert set(traces) == {f"noisy arms: {n.replace('_', ' ')} ({c})"
                                   for n, c in counts.items()}
            for name, count in counts.items():
                rows = q[outcome == OUTCOMES.index(name)]
                line = np.column_stack([decode_typed_array(traces[
                    f"noisy arms: {name.replace('_', ' ')} ({count})"][a]) for a in "xyz"])
                starts = np.r_[0, np.flatnonzero(np.isnan(line[:, 0]))[:-1] + 1]
                ends = line[np.flatnonzero(np.isnan(line[:, 0])) - 1]
                palms, elbow = [], []
                for row in rows:
                    for joint, value in description.model.expand(row).items():
                        client.resetJointState(body, joints[joint], float(value))
                    palms.append(client.getLinkState(body, links[PALM_LINK],
                                                     computeForwardKinematics=True)[4])
                np.testing.assert_allclose(ends, palms, atol=1e-6)
                elbow += [line[s + 4] for s in starts]
            elbows[label] = np.mean(elbow, axis=0)
    assert np.linalg.norm(elbows["nominal"] - elbows["best"]) > 0.05


def test_elbow_command_writes_its_page(elbow_run, tmp_path, capsys):
    """`elbow --report`: the library's optimization (same settings, same numbers) on the page,
    with the command that reproduces it; a folder as --report fails before any draw."""
    page = tmp_path / "elbow.html"
    args = ["elbow", "--object", "cube", "--grasp", "0", "--sigma", "0.02", "--samples", "40",
            "--seed", "3", "--json"]
    assert main([*args, "--report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--report" in err[0] and "is a folder" in err[0], err
    assert main([*args, "--report", str(page)]) == 0
    out, err = capsys.readouterr()
    printed = json.loads(out)
    _, result = elbow_run
    assert printed == {"robot": DEFAULT_ROBOT, **json.loads(json.dumps(result.to_json()))}
    assert f"report written to {page}" in err
    text = page.read_text()
    curve = _figures(text)["elbow"]["data"][0]
    assert curve["y"] == [c["p_fc"] for c in sorted(printed["curve"], key=lambda c: c["psi"])]
    assert ("kinegrasp elbow --robot kuka_sdh --object cube --grasp 0 --sigma 0.02 --noise "
            "gaussian --samples 40 "
            f"--seed 3 --engine fast --epsilon 0.05 --delta 0.05 --report {page}") in text


def test_elbow_page_command_reruns_a_file_grasp_by_its_id(tmp_path, capsys):
    """A grasp file's grasps are chosen by id first: the page of `elbow --grasps F --grasp 2`
    on a file holding cube grasps 1 and 2 (ids "1", "2") names grasp 2 by its id, and its
    command, run again, prints the same search (an index 1 would rerun grasp "1")."""
    import shlex

    from kinegrasp_env.world.grasps import save_grasps

    grasps = tmp_path / "sub.json"
    save_grasps(shipped_grasps("cube")[1:3], grasps)
    page = tmp_path / "sub.html"
    args = ["--sigma", "0.02", "--samples", "20", "--json"]
    assert main(["elbow", "--grasps", str(grasps), "--grasp", "2", *args, "--report",
                 str(page)]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["grasp"] == "2"
    command = re.search(r"kinegrasp elbow --[^<]*", page.read_text()).group(0)
    words = shlex.split(html.unescape(command))[1:]
    assert words[words.index("--grasp") + 1] == "2"
    assert main([*words[:words.index("--report")], "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again == first


def _section(page: str, title: str) -> dict:
    """The rows (first cell -> second cell) of the table under ``<h2>title</h2>``."""
    table = re.search(rf"<h2>{title}</h2><table>(.*?)</table>", page, re.S).group(1)
    return dict(re.findall(r'<tr><td class="kg-text">([^<]*)</td><td class="kg-text">([^<]*)'
                           r"</td></tr>", table))


def test_report_with_a_noise_spec_of_several_sources(spec_file, tmp_path, capsys):
    """`report --noise-spec F`: the library's evaluation under the model; the page lists the
    sources with the settings SPEC gives them (read off SPEC by hand), palm exact, and the
    command names the spec instead of a sigma."""
    out = tmp_path / "spec.html"
    assert main(["report", "--object", "cube", "--grasp", "1", "--noise-spec", str(spec_file),
                 "--samples", "50", "--seed", "2", "--engine", "fast", "--out", str(out),
                 "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    model = load_noise_model(spec_file)
    stats = evaluate_grasp(grasp_by_index("cube", 1), noise_model=model, n=50,
                           seed=2, engine="fast")
    (run,) = printed["runs"]
    assert run["outcomes"] == stats.counts and run["p_fc"] == stats.p_fc
    assert run["q_mean"] == pytest.approx(stats.q_mean, rel=1e-9)
    assert (run["noise"], run["noise_spec"]) == ("gaussian", str(spec_file))
    assert run["noise_model"]["friction"] == {"distribution": "uniform", "low": 0.3,
                                              "high": 0.7}
    page = out.read_text()
    assert _section(page, "Noise sources") == {
        "joints": "distribution gaussian; sigma 0.01 rad",
        "hand": "spread_sigma 0.01 rad; closing_sigma 0.02 rad",
        "palm": "exact (not in the spec)",
        "object": "translation_sigma 0.002 m; rotation_sigma 0.01 rad",
        "friction": "distribution uniform; low 0.3; high 0.7"}
    settings = _section(page, "Settings")
    assert settings["noise spec"] == str(spec_file)
    assert settings["friction mu"] == ("per draw (the noise spec&#x27;s friction source); "
                                       "nominal Q at mu 0.5")  # the middle of 0.3 .. 0.7
    assert "under a noise model of 4 sources (joints, hand, object, friction)" in page
    command = re.search(r'<pre class="kg-command">(.*?)</pre>', page).group(1)
    assert command.startswith("kinegrasp report --robot kuka_sdh --object cube --grasp 1 "
                              f"--noise-spec {spec_file} --samples 50 --seed 2 --engine fast "
                              f"--out {out}")
    assert "--sigma" not in command and "--arm-draws" not in command  # no arms drawn


def test_report_with_a_per_joint_noise_spec(tmp_path, capsys):
    """A spec with one sigma per arm joint: the page is written and its P(FC) is the
    library's under that model (its command names the spec, no sigma)."""
    spec = tmp_path / "per_joint.yaml"
    spec.write_text("joints: {sigma: [0.01, 0.02, 0.01, 0.02, 0.01, 0.02, 0.03]}\n")
    out = tmp_path / "per_joint.html"
    assert main(["report", "--object", "cube", "--noise-spec", str(spec), "--samples", "30",
                 "--engine", "fast", "--out", str(out), "--json"]) == 0
    (run,) = json.loads(capsys.readouterr().out)["runs"]
    stats = evaluate_grasp(grasp_by_index("cube", 0), noise_model=load_noise_model(spec),
                           n=30, seed=0, engine="fast")
    assert run["p_fc"] == stats.p_fc and run["outcomes"] == stats.counts
    assert f"--noise-spec {spec} --samples 30" in out.read_text()


def test_report_of_a_palm_pose_file_picks_what_evaluate_picks(tmp_path, capsys):
    """``--grasp N`` of a palm-pose file is candidate N of the file, as for ``evaluate``,
    whatever candidates before it are rejected; a rejected one named is one line with its
    reason."""
    data = json.loads(open("docs/palm_pose_candidates.json").read())
    rejected = next(c for c in data["candidates"] if c["id"] == "far_away")
    data["candidates"] = [rejected] + [c for c in data["candidates"] if c is not rejected]
    path = tmp_path / "palm.json"
    path.write_text(json.dumps(data))
    args = ["--grasps", str(path), "--grasp", "1", "--samples", "20", "--engine", "fast"]
    assert main(["evaluate", *args, "--json"]) == 0
    alone = json.loads(capsys.readouterr().out)
    assert main(["report", *args, "--out", str(tmp_path / "p.html"), "--json"]) == 0
    (run,) = json.loads(capsys.readouterr().out)["runs"]
    assert run["grasp"] == alone["grasp"] == data["candidates"][1]["id"]
    assert run["p_fc"] == alone["p_fc"]
    assert main(["report", "--grasps", str(path), "--grasp", "far_away", "--samples", "5",
                 "--out", str(tmp_path / "q.html")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "candidate far_away of" in err[0] and "is rejected" in err[0]
    assert not (tmp_path / "q.html").exists()


def test_report_picks_the_grasp_evaluate_picks_by_default(tmp_path, capsys):
    """Without ``--grasp`` both read ``0``: the grasp with id ``0`` where a file has one,
    wherever it stands (here second), else the first."""
    from kinegrasp_env.world.grasps import save_grasps

    first, second = shipped_grasps("cube")[:2]
    path = tmp_path / "ids.json"
    save_grasps([replace(first, id="5"), replace(second, id="0")], path)
    args = ["--grasps", str(path), "--samples", "10", "--engine", "fast"]
    assert main(["evaluate", *args, "--json"]) == 0
    alone = json.loads(capsys.readouterr().out)
    assert main(["report", *args, "--out", str(tmp_path / "p.html"), "--json"]) == 0
    (run,) = json.loads(capsys.readouterr().out)["runs"]
    assert run["grasp"] == alone["grasp"] == "0" and run["p_fc"] == alone["p_fc"]


def test_evaluate_report_with_a_noise_spec(spec_file, tmp_path, capsys):
    page = tmp_path / "evaluate.html"
    assert main(["evaluate", "--object", "cube", "--grasp", "1", "--noise-spec",
                 str(spec_file), "--samples", "30", "--engine", "fast", "--report",
                 str(page)]) == 0
    assert f"report written to {page}" in capsys.readouterr().out
    text = page.read_text()
    assert (f"kinegrasp evaluate --robot kuka_sdh --object cube --grasp 1 --noise-spec "
            f"{spec_file} --samples 30 --seed 0 --engine fast --report {page}") in text
    assert _section(text, "Noise sources")["friction"] == "distribution uniform; low 0.3; high 0.7"


@pytest.fixture(scope="module")
def imported_page(tmp_path_factory):
    """``report --grasps FILE --grasp ID`` for a 5 cm box imported into a catalog of its own
    with one planned grasp (40 draws): (page, grasp, the library's evaluation of it, the
    object's mesh vertices, the grasp file). The catalog's caches are keyed by its folder,
    so nothing of it outlives the fixture's catalog."""
    folder = tmp_path_factory.mktemp("imported")
    mesh = folder / "report_box.stl"
    trimesh.creation.box(extents=(0.05, 0.05, 0.05)).export(mesh)
    grasps, page = folder / "grasps.json", folder / "imported.html"
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("KINEGRASP_HOME", str(folder / "home"))
        assert main(["objects", "add", str(mesh)]) == 0
        assert main(["plan", "--object", "report_box", "--count", "1", "--seed", "0",
                     "--out", str(grasps)]) == 0
        grasp = load_grasps(grasps)[0]
        assert main(["report", "--grasps", str(grasps), "--grasp", grasp.id, "--sigma", "0.01",
                     "--samples", "40", "--engine", "fast", "--out", str(page)]) == 0
        stats = evaluate_grasp(grasp, sigma=0.01, n=40, seed=0, engine="fast")
        vertices = np.asarray(load_object("report_box").mesh.vertices)
    return page, grasp, stats, vertices, grasps


def test_report_of_an_imported_objects_grasp_file(imported_page):
    """The page shows the imported object's own mesh and the library's evaluation of the
    file's grasp; its command keeps the grasp file and the id given."""
    page, grasp, stats, vertices, grasps = imported_page
    text = page.read_text()
    outcomes = _figures(text)["outcomes-0"]["data"][0]["x"]
    assert outcomes == [stats.counts[name] for name in OUTCOMES]
    assert f'class="kg-pfc" data-grasp="{grasp.id}" data-value="{stats.p_fc!r}"' in text
    meshes = json.loads(re.search(r'id="kg-meshes">(.*?)</script>', text, re.S).group(1))
    np.testing.assert_allclose(decode_typed_array(meshes["object:report_box"]["v"])
                               .reshape(-1, 3), vertices, atol=1e-7)
    assert _section(text, "Settings")["grasp source"] == str(grasps)
    assert (f"kinegrasp report --robot kuka_sdh --grasps {grasps} --grasp {grasp.id} "
            "--sigma 0.01 --noise gaussian --samples 40 --seed 0 --engine fast") in text


@pytest.mark.parametrize("mask", [0o022, 0o077])
def test_pages_get_the_mode_a_plain_open_gives(tmp_path, mask):
    """write_page (text as UTF-8, or bytes) gives a new file what open() would under the
    umask, not a temporary file's private 0600; a rewritten file keeps its mode."""
    old = os.umask(mask)
    try:
        report.write_page(tmp_path / "page.html", "<p>\u00e9</p>")
        report.write_page(tmp_path / "shot.png", b"\x89PNG")
        with open(tmp_path / "plain.txt", "w"):
            pass
    finally:
        os.umask(old)
    plain = os.stat(tmp_path / "plain.txt").st_mode & 0o777
    assert plain == 0o666 & ~mask
    for name in ("page.html", "shot.png"):
        assert os.stat(tmp_path / name).st_mode & 0o777 == plain, name
    assert (tmp_path / "page.html").read_bytes() == "<p>\u00e9</p>".encode()
    os.chmod(tmp_path / "page.html", 0o640)
    report.write_page(tmp_path / "page.html", "again")
    assert os.stat(tmp_path / "page.html").st_mode & 0o777 == 0o640


@needs_chromium
@pytest.mark.expensive
@pytest.mark.parametrize(("name", "figures", "scenes"), [("elbow", 3, 2), ("spec", 3, 1)])
def test_elbow_and_noise_spec_pages_in_chromium(pages, name, figures, scenes):
    check = report.check_page(pages[name])
    _report_load(name, check)
    assert check.problems(scenes=scenes) == []
    assert check.rendered == check.expected == figures
    assert check.ready_ms < 20_000


@needs_chromium
@pytest.mark.expensive
def test_imported_object_page_in_chromium(imported_page):
    check = report.check_page(imported_page[0])
    _report_load("imported object", check)
    assert check.problems(scenes=1) == []
    assert check.rendered == check.expected == 3
