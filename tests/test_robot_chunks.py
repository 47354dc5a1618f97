"""A description robot's draws in chunks on worker processes, and the ranking built on them.

What each test proves:

* a run split into chunks on two worker processes closes the same configurations as the run
  in one process (each chunk is rows of the seed's one stream): every per-draw array equal,
  so P(FC), Q's moments, the static hold verdicts and the nominal Q are equal too. A chunk
  that re-seeded its own stream, or lost its offset, would change the draws;
* ``rank`` of the Panda's candidates gives the same CSV on one process and on two, after
  an interruption (resumed from its log) as uninterrupted, and its draws are ``evaluate``'s
  (common noise: each candidate on the same rows);
* ``rank --adaptive`` certifies a top 1 that the fixed-n ranking's estimates agree with;
  ``--best-elbow`` moves each candidate along the arm's self-motion with its palm kept
  (forward kinematics, an independent computation of the palm pose).
"""

from __future__ import annotations

import csv
import dataclasses
import json
from dataclasses import fields

import numpy as np
import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.montecarlo import chunks
from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.null_motion import ArmSelfMotion
from kinegrasp_env.world.grasps import load_grasps, save_grasps, shipped_grasps

#: The elbow angle the CSV names against the moved configuration's (radians): the CSV
#: prints 6 decimals (rounding <= 5e-7); the moved configuration lies at the chosen angle
#: to 4e-12 rad (measured on the Panda's cube grasps).
ELBOW_TOL = 1e-6


@pytest.fixture(autouse=True)
def _no_kept_engines():
    yield
    chunks.close_engines()


def test_chunks_on_two_processes_are_the_run_row_for_row():
    grasp = shipped_grasps("cube", "panda")[0]
    options = dict(sigma=0.0133, n=530, seed=7, engine="fast", static_hold=True, friction=0.4)
    inline = evaluate_grasp(grasp, **options)
    reports = []
    with LocalExecutor(2) as executor:
        pooled = evaluate_grasp(grasp, **options, executor=executor,
                                progress=lambda done, n: reports.append((done, n)))
    # one report per chunk as it comes back (chunks of 250: 250, 500, 530 of 530)
    assert reports == [(250, 530), (500, 530), (530, 530)]
    for f in fields(DrawBatch):
        np.testing.assert_array_equal(getattr(inline.draws, f.name),
                                      getattr(pooled.draws, f.name), err_msg=f.name)
    assert (inline.p_fc, inline.counts, inline.p_hold_static, inline.mass) == (
        pooled.p_fc, pooled.counts, pooled.p_hold_static, pooled.mass)
    assert pooled.q_nominal == inline.q_nominal > 0
    with LocalExecutor(2) as executor, pytest.raises(ValueError, match="integer seed"):
        evaluate_grasp(grasp, **{**options, "seed": np.random.default_rng(0)},
                       executor=executor)


def test_the_fast_engine_closes_several_chunks_a_task_and_the_same_rows():
    """The fast engine's tasks span several chunks of the streams (its closing costs the same
    per call, whatever the batch: 3,000 draws on two processes go in tasks of 750, each
    worker still getting two), and the draws are the run's rows all the same."""
    assert chunks.task_rows("fast", 3000, 2) == 750
    assert chunks.task_rows("fast", 100_000, 2) == 10 * chunks.CHUNK
    assert chunks.task_rows("pybullet", 100_000, 2) == chunks.CHUNK
    grasp = shipped_grasps("cube", "panda")[1]
    inline = evaluate_grasp(grasp, sigma=0.0133, n=3000, seed=3, engine="fast")
    reports = []
    with LocalExecutor(2) as executor:
        pooled = evaluate_grasp(grasp, sigma=0.0133, n=3000, seed=3, engine="fast",
                                executor=executor, progress=lambda done, n: reports.append(done))
    assert reports == [750, 1500, 2250, 3000]
    np.testing.assert_array_equal(pooled.draws.outcome, inline.draws.outcome)
    np.testing.assert_array_equal(pooled.draws.quality, inline.draws.quality)


def _candidates(tmp_path):
    path = tmp_path / "g.json"
    save_grasps(shipped_grasps("cube", "panda")[:3], path)
    return path


def _rank(tmp_path, name: str, *extra: str) -> list[dict]:
    out = tmp_path / name
    assert main(["rank", str(_candidates(tmp_path)), "--sigma", "0.0133", "--samples", "300",
                 "--seed", "2", "--engine", "fast", "--out", str(out), *extra]) == 0
    return list(csv.DictReader(out.open()))


def test_a_run_with_progress_on_one_process_is_the_run_in_one_call():
    """With a progress callback, a run on an executor of one local process goes in chunks
    (what moves ``evaluate``'s bar): the callback sees every draw, and the counts, Q's
    moments and nominal Q are bit for bit those of the same run closed in one engine call
    (another code path: the nominal row rides with the draws there)."""
    grasp = shipped_grasps("cube")[1]
    whole = evaluate_grasp(grasp, sigma=0.0133, n=600, seed=4, engine="fast")
    seen = []
    with LocalExecutor(1) as executor:
        chunked = evaluate_grasp(grasp, sigma=0.0133, n=600, seed=4, engine="fast",
                                 executor=executor,
                                 progress=lambda done, n: seen.append((done, n)))
    assert seen == [(250, 600), (500, 600), (600, 600)]
    assert chunked.counts == whole.counts
    for name in ("q_mean", "q_std", "q_skew", "q_nominal"):
        assert getattr(chunked, name) == getattr(whole, name), name


def test_rank_of_a_robot_on_processes_resumed_and_as_evaluate(tmp_path, capsys, monkeypatch):
    one = _rank(tmp_path, "one.csv")
    assert (tmp_path / "two.csv").exists() is False
    two = _rank(tmp_path, "two.csv", "--processes", "2")
    assert one == two
    # interrupted after the first candidate: the log keeps it, the rerun adds the others
    from kinegrasp_env.cli import ranking_draws

    real, calls = ranking_draws.RankingDraws.__call__, {"n": 0}

    def interrupted(self, *a, **k):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(self, *a, **k)

    monkeypatch.setattr(ranking_draws.RankingDraws, "__call__", interrupted)
    out = tmp_path / "resumed.csv"
    args = ["rank", str(_candidates(tmp_path)), "--sigma", "0.0133", "--samples", "300",
            "--seed", "2", "--engine", "fast", "--out", str(out)]
    assert main(args) == 130 and not out.exists()
    monkeypatch.setattr(ranking_draws.RankingDraws, "__call__", real)
    assert main(args) == 0
    assert "resuming: 1 of 3" in capsys.readouterr().err
    assert list(csv.DictReader(out.open())) == one
    # each row is evaluate's run of that candidate (same seed, same rows)
    for index, grasp in enumerate(shipped_grasps("cube", "panda")[:3]):
        assert main(["evaluate", "--grasps", str(_candidates(tmp_path)), "--grasp",
                     str(index), "--sigma", "0.0133", "--samples", "300", "--seed", "2",
                     "--engine", "fast", "--json"]) == 0
        shown = json.loads(capsys.readouterr().out)
        row = next(r for r in one if r["id"] == grasp.id)
        assert int(row["force_closure"]) == shown["outcomes"]["force_closure"]
        # the CSV prints 6 significant digits
        assert float(row["q_nominal"]) == pytest.approx(shown["q_nominal"], rel=1e-5)


def test_a_planned_elbow_angle_is_no_column_without_best_elbow(tmp_path, capsys):
    """A planned grasp records its arm's elbow angle in ``meta``; only ``--best-elbow``
    (which chose it) adds the column, so the table of a plain ranking keeps its columns."""
    path = tmp_path / "planned.json"
    save_grasps([dataclasses.replace(g, meta={**g.meta, "elbow_angle": 0.1})
                 for g in shipped_grasps("cube", "panda")[:2]], path)
    out = tmp_path / "plain.csv"
    assert main(["rank", str(path), "--samples", "20", "--engine", "fast", "--out",
                 str(out)]) == 0
    assert "elbow" not in capsys.readouterr().out.splitlines()[0].split()  # the header
    assert "elbow_angle" not in next(csv.DictReader(out.open()))


def test_adaptive_and_best_elbow_for_a_robot(tmp_path, capsys):
    fixed = _rank(tmp_path, "fixed.csv")
    adaptive = _rank(tmp_path, "adaptive.csv", "--adaptive", "--top-k", "1", "--samples",
                     "1000")
    top = next(r for r in adaptive if r["certified"] == "top-k")
    assert top["id"] == fixed[0]["id"]  # the fixed-n run's best, by a wide margin
    capsys.readouterr()
    # certified by the static hold: cube grasps and a drill grasp (in force closure about as
    # often as they are, never held: the drill is too heavy for the jaws), so P(FC) and
    # P(hold) order them differently
    mixed = tmp_path / "mixed.json"
    picked = [*shipped_grasps("cube", "panda")[1:3],
              dataclasses.replace(shipped_grasps("drill", "panda")[3], id="d3")]
    save_grasps(picked, mixed)
    out = tmp_path / "held.csv"
    assert main(["rank", str(mixed), "--sigma", "0.0133", "--samples", "1000", "--seed", "2",
                 "--engine", "fast", "--out", str(out), "--adaptive", "--top-k", "1",
                 "--criterion", "hold_static"]) == 0
    held = list(csv.DictReader(out.open()))
    assert "within 0.01 of the best P(hold, static)" in capsys.readouterr().out
    # each row's P(FC) and P(hold, static) are evaluate's on the draws it made (same rows)
    for grasp in picked:
        row = next(r for r in held if r["id"] == grasp.id)
        assert main(["evaluate", "--grasps", str(mixed), "--grasp", grasp.id, "--sigma",
                     "0.0133", "--samples", row["samples"], "--seed", "2", "--engine",
                     "fast", "--static-hold", "--json"]) == 0
        shown = json.loads(capsys.readouterr().out)
        assert int(row["force_closure"]) == shown["outcomes"]["force_closure"]
        assert float(row["p_fc"]) == pytest.approx(shown["p_fc"], abs=1e-6)
        assert float(row["p_hold_static"]) == pytest.approx(shown["p_hold_static"], abs=1e-6)
    drill = next(r for r in held if r["id"] == "d3")
    assert float(drill["p_hold_static"]) == 0 < float(drill["p_fc"])
    assert held[-1]["id"] == "d3" and held[-1]["certified"] == "rest"  # by its hold score
    by_hold = sorted(held, key=lambda r: -float(r["p_hold_static"]))
    assert next(r for r in held if r["certified"] != "rest")["id"] == by_hold[0]["id"]
    grasps = tmp_path / "moved.json"
    rows = _rank(tmp_path, "elbow.csv", "--best-elbow", "20", "--samples", "40")
    assert {r["id"] for r in rows} == {str(g.id) for g in shipped_grasps("cube", "panda")[:3]}
    description = load_robot("panda")
    kinematics = Kinematics(description.model)
    save_grasps(shipped_grasps("cube", "panda")[:3], grasps)
    from kinegrasp_env.cli.ranking import best_elbows
    from kinegrasp_env.sampling.noise import JointNoise

    moved = best_elbows(load_grasps(grasps), "panda", JointNoise(0.0133), 20, 2, "fast", None)
    for before, after in zip(load_grasps(grasps), moved, strict=True):
        np.testing.assert_allclose(
            kinematics.pose(np.asarray(after.q0)[None], description.palm_link),
            kinematics.pose(np.asarray(before.q0)[None], description.palm_link), atol=1e-8)
        # the CSV names the angle each candidate was ranked at: the elbow angle of the moved
        # configuration, as the arm's geometry gives it
        psi = ArmSelfMotion(description).elbow_angle(np.asarray(after.q0)[None])[0]
        row = next(r for r in rows if r["id"] == after.id)
        assert float(row["elbow_angle"]) == pytest.approx(psi, abs=ELBOW_TOL), row
