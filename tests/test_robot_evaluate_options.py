"""``evaluate --elbow`` and ``--plot`` for a description robot (the Panda)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.null_motion import ArmSelfMotion
from kinegrasp_env.world.grasps import shipped_grasps


def test_elbow_moves_the_arm_and_keeps_the_palm(capsys, tmp_path):
    """The grasp evaluated at --elbow PSI is the shipped one with its arm moved: the palm
    pose by forward kinematics equal to 1e-9, the elbow angle PSI; its draws are those of
    evaluate_grasp at that configuration (the same numbers); an unreachable angle is
    one line; --plot writes a PNG."""
    from kinegrasp_env.cli.evaluation import robot_grasp_at_elbow
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp

    grasp = shipped_grasps("cube", "panda")[0]
    moved = robot_grasp_at_elbow(grasp, "panda", "0.4")
    description = load_robot("panda")
    kin = Kinematics(description.model)
    np.testing.assert_allclose(kin.pose(moved.q0[None], description.palm_link),
                               kin.pose(np.asarray(grasp.q0)[None], description.palm_link),
                               atol=1e-9)
    assert abs(ArmSelfMotion(description).elbow_angle(moved.q0[None])[0] - 0.4) < 1e-6
    png = tmp_path / "contacts.png"
    args = ["evaluate", "--robot", "panda", "--object", "cube", "--grasp", "0", "--sigma",
            "0.0133", "--samples", "60", "--json", "--engine", "fast"]
    assert main([*args, "--elbow", "0.4", "--plot", str(png)]) == 0
    shown = json.loads(capsys.readouterr().out)
    direct = evaluate_grasp(moved, sigma=0.0133, n=60, seed=0, robot="panda",
                            engine="fast")
    assert shown["p_fc"] == direct.p_fc and shown["outcomes"] == direct.counts
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main([*args, "--elbow", "3.0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "out of reach" in err[0]
    # the range it names: its ends are reached (the palm kept), 0.2 rad past them is not
    lo, hi = (float(v) for v in err[0].split("reachable ")[1].split(" rad")[0].split(" .. "))
    for psi in (lo, hi):
        end = robot_grasp_at_elbow(grasp, "panda", repr(psi))
        np.testing.assert_allclose(
            kin.pose(end.q0[None], description.palm_link),
            kin.pose(np.asarray(grasp.q0)[None], description.palm_link), atol=1e-9)
    for psi in (lo - 0.2, hi + 0.2):
        with pytest.raises(ValueError, match="out of reach"):
            robot_grasp_at_elbow(grasp, "panda", repr(psi))
    # an angle beyond pi (degrees, likely) is refused, not wrapped; the text names the angle
    assert main([*args, "--elbow", "100"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["kinegrasp evaluate: error: --elbow 100: an elbow angle is in radians, "
                   "within -pi .. pi"]
    assert main([*[a for a in args if a != "--json"], "--elbow", "0.4"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("cube grasp 0 at elbow angle 0.400 rad of robot panda, "), first


def test_rank_json_for_any_robot(capsys, tmp_path):
    """``rank --json`` prints one JSON object: the rows in rank order as the CSV has them
    (P(FC) equal to the CSV's to its printed digits), no hold columns that were not scored;
    for the Panda's grasps and for the default robot's palm poses alike."""
    import csv

    from kinegrasp_env.world.grasps import save_grasps

    grasps = tmp_path / "g.json"
    save_grasps(shipped_grasps("cube", "panda")[:2], grasps)
    candidates = Path(__file__).resolve().parents[1] / "docs" / "palm_pose_candidates.json"
    for source, extra in ((grasps, []), (candidates, [])):
        out = tmp_path / "r.csv"
        assert main(["rank", str(source), "--sigma", "0.0133", "--samples", "30", "--out",
                     str(out), "--json", *extra]) == 0
        shown = json.loads(capsys.readouterr().out)
        rows = list(csv.DictReader(out.open()))
        assert [r["rank"] for r in shown["ranking"]] == list(range(1, len(rows) + 1))
        assert [r["id"] for r in shown["ranking"]] == [r["id"] for r in rows]
        for js, row in zip(shown["ranking"], rows, strict=True):
            assert abs(js["p_fc"] - float(row["p_fc"])) < 1e-4
        assert "p_hold" not in shown["ranking"][0] and shown["written"] == str(out)


def test_evaluate_report_for_a_robot(capsys, tmp_path):
    """``evaluate --robot panda --report FILE``: one page of this grasp and run, whose table
    holds the run's P(FC) (the JSON's, to its 4 printed digits) and whose command line
    reproduces it; a report path in a missing folder is one line, before any draw."""
    page = tmp_path / "page.html"
    args = ["evaluate", "--robot", "panda", "--object", "cube", "--grasp", "0", "--samples",
            "50", "--engine", "fast", "--json"]
    assert main([*args, "--report", str(page)]) == 0
    shown = json.loads(capsys.readouterr().out)
    text = page.read_text()
    assert f"{shown['p_fc']:.4f}" in text
    assert "kinegrasp evaluate --robot panda --object cube --grasp 0" in text
    # the scene draws the run's contacts: every touching draw's, none dropped
    shown_points, total = map(int, re.search(
        r"contact points of its first run&#x27;s draws: (\d+) of (\d+)", text).groups())
    assert shown_points == total > 0
    assert main([*args, "--report", str(tmp_path / "no" / "page.html")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--report" in err[0]


def test_rank_report_for_a_robot(capsys, tmp_path):
    """``rank --report FILE`` of the Panda's candidates: one page, its rows in the CSV's
    rank order with the CSV's P(FC)s."""
    import csv

    from kinegrasp_env.world.grasps import save_grasps

    grasps = tmp_path / "g.json"
    save_grasps(shipped_grasps("cube", "panda")[:3], grasps)
    out, page = tmp_path / "r.csv", tmp_path / "r.html"
    assert main(["rank", str(grasps), "--samples", "40", "--engine", "fast", "--out",
                 str(out), "--report", str(page)]) == 0
    capsys.readouterr()
    rows = list(csv.DictReader(out.open()))
    shown = re.findall(r'<tr class="kg-item" data-detail="[^"]+" data-id="([^"]+)">'
                       r'<td data-value="[^"]*">[^<]*</td><td class="kg-text">[^<]*</td>'
                       r'<td data-value="([^"]+)">', page.read_text())
    assert [g for g, _ in shown] == [r["id"] for r in rows]
    for (_, value), row in zip(shown, rows, strict=True):
        assert abs(float(value) - float(row["p_fc"])) < 1e-6


def test_rank_of_a_robots_grasps_of_several_objects(capsys, tmp_path):
    """``rank`` of the Panda's cube and drill grasps in one file: each candidate's P(FC) is
    ``evaluate``'s of that grasp on its own object (the same seed: the same rows of the
    stream), so no candidate is closed on another's object; the report draws each on its
    own object."""
    import csv

    from kinegrasp_env.world.grasps import save_grasps

    picked = [("cube", 0), ("drill", 1), ("cube", 2), ("drill", 3)]
    grasps = tmp_path / "g.json"
    save_grasps([shipped_grasps(obj, "panda")[i] for obj, i in picked], grasps)
    out, page = tmp_path / "r.csv", tmp_path / "r.html"
    assert main(["rank", str(grasps), "--samples", "60", "--sigma", "0.0233", "--seed", "2",
                 "--engine", "fast", "--out", str(out), "--report", str(page)]) == 0
    capsys.readouterr()
    rows = {r["id"]: r for r in csv.DictReader(out.open())}
    assert len(rows) == 4  # the ids of these four are distinct
    for obj, i in picked:
        assert main(["evaluate", "--robot", "panda", "--object", obj, "--grasp", str(i),
                     "--samples", "60", "--sigma", "0.0233", "--seed", "2", "--engine",
                     "fast", "--json"]) == 0
        alone = json.loads(capsys.readouterr().out)
        grasp_id = shipped_grasps(obj, "panda")[i].id
        assert abs(float(rows[grasp_id]["p_fc"]) - alone["p_fc"]) < 1e-4, (obj, i)
    text = page.read_text()
    assert "4 candidates of cube, drill" in text and "panda: drill grasp" in text


def test_draws_from_an_offset_are_those_rows_of_the_run():
    """``offset``: the draws are rows offset .. offset + n of the seed's run, in one process
    or in chunks on two (the stream layout: a longer run's rows 250 .. 279, closed by the
    same engine); a Generator, which has no rows, is refused with an offset."""
    import pytest

    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.montecarlo.execution import LocalExecutor

    grasp = shipped_grasps("cube", "panda")[0]
    whole = evaluate_grasp(grasp, sigma=0.02, n=280, seed=5, engine="fast")
    tail = whole.draws.quality[250:280]
    part = evaluate_grasp(grasp, sigma=0.02, n=30, seed=5, offset=250, engine="fast")
    np.testing.assert_array_equal(part.draws.quality, tail)
    with LocalExecutor(2) as executor:
        chunked = evaluate_grasp(grasp, sigma=0.02, n=30, seed=5, offset=250,
                                 engine="fast", executor=executor)
    np.testing.assert_array_equal(chunked.draws.quality, tail)
    assert (part.draws.quality != whole.draws.quality[:30]).any()  # other draws
    with pytest.raises(ValueError, match="offset > 0 take an integer or SeedSequence"):
        evaluate_grasp(grasp, sigma=0.02, n=3, seed=np.random.default_rng(0),
                       offset=250, engine="fast")


def test_a_plot_of_no_contact_says_so(tmp_path, capsys, recwarn):
    """At sigma 0.3 no draw of the Panda's cube grasp 1 touches the cube with a finger
    (every draw missed or started in collision): the plot says so, with no empty legend box
    and no matplotlib warning about one."""
    png = tmp_path / "none.png"
    assert main(["evaluate", "--robot", "panda", "--object", "cube", "--grasp", "1",
                 "--sigma", "0.3", "--samples", "30", "--engine", "fast", "--plot",
                 str(png), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["outcomes"]["force_closure"] == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [w for w in recwarn if "No artists with labels" in str(w.message)]


def test_antithetic_draws_are_pairs_of_opposite_joint_errors():
    """``method="antithetic"`` (every robot): rows 2i and 2i+1 of each chunk's joint errors are
    negatives of each other (the sampler's defining property, checked on the configurations
    the evaluation closes), and rows from an offset are those rows of the whole run."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp, evaluation_rows

    grasp = shipped_grasps("cube", "panda")[0]
    with make_engine("fast", "panda", "cube") as engine:
        q, _ = evaluation_rows(grasp, engine, sigma=0.02, n=300, seed=4, method="antithetic")
    eps = q[:, :7] - grasp.q0[:7]
    for start, stop in ((0, 250), (250, 300)):  # each chunk of the streams pairs its own rows
        np.testing.assert_allclose(eps[start:stop:2], -eps[start + 1:stop:2], rtol=0,
                                   atol=1e-15)
    assert np.abs(eps).max() > 0.01
    with make_engine("fast", "panda", "cube") as engine:
        tail, _ = evaluation_rows(grasp, engine, sigma=0.02, n=150, seed=4, offset=150,
                                  method="antithetic")
    np.testing.assert_array_equal(tail, q[150:300])
    with pytest.raises(ValueError, match="method must be one of mc, antithetic, sobol"):
        evaluate_grasp(grasp, sigma=0.02, n=10, seed=4, method="halton", engine="fast")


def test_sobol_draws_fill_every_stratum_once_in_process_and_in_chunks():
    """``method="sobol"``: 128 scrambled Sobol points put exactly one point of each joint's
    error in each of 128 equal-probability bins of its Gaussian (a (0, 7, d)-net property,
    checked against scipy's normal CDF); the evaluation closes those rows, the same draws in
    one process and in chunks on two."""
    from scipy.stats import norm

    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp, evaluation_rows
    from kinegrasp_env.montecarlo.execution import LocalExecutor

    grasp, sigma = shipped_grasps("cube", "panda")[0], 0.02
    with make_engine("fast", "panda", "cube") as engine:
        q, _ = evaluation_rows(grasp, engine, sigma=sigma, n=128, seed=6, method="sobol")
        closed = engine.run(q)
    bins = np.floor(128 * norm.cdf((q[:, :7] - grasp.q0[:7]) / sigma)).astype(int)
    for joint in range(7):
        np.testing.assert_array_equal(np.sort(bins[:, joint]), np.arange(128))
    here = evaluate_grasp(grasp, sigma=sigma, n=128, seed=6, method="sobol", engine="fast")
    np.testing.assert_array_equal(here.draws.quality, closed.quality)
    with LocalExecutor(2) as executor:
        chunked = evaluate_grasp(grasp, sigma=sigma, n=128, seed=6, method="sobol",
                                 engine="fast", executor=executor, progress=lambda *_: None)
    np.testing.assert_array_equal(chunked.draws.quality, closed.quality)


def test_a_run_in_chunks_builds_the_given_engines_settings():
    """A given engine's quality settings (here 3 cone edges instead of 8) reach the workers of
    a run in chunks: the same draws as the engine gives in this process, not the default
    engine's."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.montecarlo.execution import LocalExecutor

    grasp = shipped_grasps("cube", "panda")[0]
    with make_engine("fast", "panda", "cube", num_edges=3) as coarse:
        here = evaluate_grasp(grasp, sigma=0.02, n=300, seed=2, engine=coarse)
        with LocalExecutor(2) as executor:
            chunked = evaluate_grasp(grasp, sigma=0.02, n=300, seed=2, engine=coarse,
                                     executor=executor)
    default = evaluate_grasp(grasp, sigma=0.02, n=300, seed=2, engine="fast")
    np.testing.assert_array_equal(chunked.draws.quality, here.draws.quality)
    assert chunked.q_nominal == here.q_nominal
    assert (default.draws.quality != here.draws.quality).any()  # the setting matters


def test_engine_input_errors_are_one_line_before_any_closing():
    """An engine refuses a bad quality setting when it is built, names the first non-finite
    entry of a batch, and the physics engine (one simulated mu) refuses per-draw mu."""
    from kinegrasp_env.montecarlo.engines import make_engine

    with pytest.raises(ValueError, match="num_edges"):
        make_engine("fast", "panda", "cube", num_edges=2)
    with pytest.raises(ValueError, match="friction must be finite"):
        make_engine("pybullet", "panda", "cube", friction=-1.0)
    grasp = shipped_grasps("cube", "panda")[0]
    q = np.repeat(grasp.q0[None], 3, axis=0)
    q[2, 4] = np.inf
    with make_engine("fast", "panda", "cube") as engine, pytest.raises(
            ValueError, match=r"configuration 2 is not finite: joint 4 = inf \(1 of 3"):
        engine.run(q)
    with make_engine("physics", "panda", "cube") as physics, pytest.raises(
            ValueError, match="takes joint and hand noise only, not friction errors"):
        physics.run(grasp.q0[None], friction=np.array([0.3]))


def test_evaluate_grasp_refuses_what_it_cannot_run_in_one_line():
    """Bad arguments of the evaluation are refused before any closing, naming the value: an
    engine that is not one ``make_engine`` builds (a holding test's engine: a run in chunks
    would rebuild another engine by its name), an executor or progress of another type, no
    sigma without a noise model; with a noise model, sigma is not needed."""
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.montecarlo.hold_engine import quick_hold_engine
    from kinegrasp_env.sampling.noise_model import JointsSource, NoiseModel

    grasp = shipped_grasps("cube", "panda")[0]
    with quick_hold_engine("panda", "cube") as hold, pytest.raises(
            ValueError, match="an engine make_engine builds, got RobotHoldEngine"):
        evaluate_grasp(grasp, sigma=0.01, n=3, engine=hold)
    for kwargs, words in (({"executor": 4}, "executor must be an Executor"),
                          ({"progress": True}, "progress must be a function"),
                          ({"engine": None}, "engine must be a name")):
        with pytest.raises(ValueError, match=words):
            evaluate_grasp(grasp, sigma=0.01, n=3, **kwargs)
    with pytest.raises(ValueError, match=r"sigma \(radians\) or a noise_model"):
        evaluate_grasp(grasp, n=3, engine="fast")
    model = NoiseModel(joints=JointsSource(0.02))
    seen = []
    by_model = evaluate_grasp(grasp, n=40, seed=1, noise_model=model, engine="fast",
                              progress=lambda done, n: seen.append((done, n)))
    by_sigma = evaluate_grasp(grasp, sigma=0.02, n=40, seed=1, engine="fast")
    np.testing.assert_array_equal(by_model.draws.quality, by_sigma.draws.quality)
    assert seen == [(40, 40)]  # in one process: once, at the end


def test_an_engines_options_are_its_settings_off_the_defaults():
    """``options()`` names only what differs from the defaults (a given engine with default
    settings shares a worker's engine by name), and the engine's own settings are checked
    when it is built."""
    from kinegrasp_env.montecarlo.engines import make_engine

    with make_engine("fast", "panda", "cube") as plain:
        assert plain.options() == {}
    with make_engine("fast", "panda", "cube", num_edges=np.int64(6), max_contacts=4) as set_:
        assert set_.options() == {"num_edges": 6, "max_contacts": 4}
        assert type(set_.options()["num_edges"]) is int
    for kwargs, words in (({"max_contacts": 0}, "max_contacts must be an integer >= 1"),
                          ({"finger_radius": -1.0}, "finger_radius must be a length"),
                          ({"finger_radius": float("nan")}, "finger_radius must be a length")):
        with pytest.raises(ValueError, match=words):
            make_engine("fast", "panda", "cube", **kwargs)
