"""Planner, null-space variants, and the plan/rank command line (incl. resume)."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from cli_helpers import run_cli

from kinegrasp_env import cli
from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE
from kinegrasp_env.robot.kinematics import pose_error
from kinegrasp_env.robot.model import ELBOW_LINK, PALM_LINK
from kinegrasp_env.toolkit.planner import GraspPlanner
from kinegrasp_env.world.grasps import load_grasps, shipped_grasps


@pytest.fixture(scope="module")
def drill_planner():
    planner = GraspPlanner("drill")
    yield planner
    planner.close()


@pytest.mark.expensive
def test_planned_grasps_are_valid(drill_planner):
    grasps = drill_planner.plan(2, seed=5)
    assert len(grasps) == 2
    kin, model = drill_planner.engine.kin, drill_planner.model
    for g in grasps:
        assert model.within_limits(g.q0)
        err = pose_error(kin.pose(g.q0, PALM_LINK), g.palm_pose[None])
        assert np.abs(err).max() < 1e-9
        draw = drill_planner.engine.run(g.q0[None])
        assert draw.outcome[0] == FORCE_CLOSURE
        assert draw.quality[0] == pytest.approx(g.q_nominal, rel=1e-12)


def test_variants_keep_palm_and_contacts(drill_planner):
    grasp = shipped_grasps("drill")[0]
    variants = drill_planner.variants(grasp, 3)
    assert len(variants) >= 2
    kin = drill_planner.engine.kin
    elbow0 = kin.pose(grasp.q0, ELBOW_LINK)[0, :3, 3]
    for v in variants:
        err = pose_error(kin.pose(v.q0, PALM_LINK), grasp.palm_pose[None])
        assert np.abs(err).max() < 1e-6
        assert v.points.shape == grasp.points.shape
        assert np.abs(v.points - grasp.points).max() < 5e-4
        assert np.linalg.norm(kin.pose(v.q0, ELBOW_LINK)[0, :3, 3] - elbow0) > 0.02
        assert v.meta["variant_of"] == grasp.id


def _read(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


@pytest.mark.expensive
@pytest.mark.parametrize("obj", ["cube", "drill"])
def test_plan_then_rank(tmp_path, obj):
    grasps = tmp_path / "g.json"
    proc = run_cli("plan", "--object", obj, "--count", "2", "--seed", "1", "--variants", "1",
                   "--out", str(grasps))
    assert proc.returncode == 0, proc.stderr
    assert len(load_grasps(grasps)) >= 3
    ranked = tmp_path / "r.csv"
    proc = run_cli("rank", str(grasps), "--sigma", "0.0133", "--samples", "60", "--seed", "0",
                   "--out", str(ranked))
    assert proc.returncode == 0, proc.stderr
    rows = _read(ranked)
    assert list(rows[0]) == ["id", "p_fc", "p_fc_lo", "p_fc_hi", "q_mean", "q_std", "q_skew",
                             "q_nominal", "error", "samples"]
    p = [float(r["p_fc"]) for r in rows]
    assert p == sorted(p, reverse=True)
    assert all(float(r["p_fc_lo"]) <= float(r["p_fc"]) <= float(r["p_fc_hi"]) for r in rows)


def _cube_candidates(tmp_path):
    from kinegrasp_env.world.grasps import save_grasps

    path = tmp_path / "cube.json"
    save_grasps(shipped_grasps("cube")[:4], path)
    return path


def test_rank_resumes_after_interruption(tmp_path, monkeypatch, capsys):
    candidates = _cube_candidates(tmp_path)
    args = ["rank", str(candidates), "--samples", "40", "--seed", "3"]
    assert cli.main([*args, "--out", str(tmp_path / "full.csv")]) == 0

    from kinegrasp_env.montecarlo import evaluate

    real = evaluate.run_chunks
    calls = {"n": 0}

    def interrupted(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    out = tmp_path / "resumed.csv"
    monkeypatch.setattr(evaluate, "run_chunks", interrupted)
    assert cli.main([*args, "--out", str(out)]) == 130
    assert not out.exists()  # nothing half-written
    partial = tmp_path / "resumed.csv.partial.jsonl"
    assert len(partial.read_text().splitlines()) == 3  # settings + 2 finished candidates
    monkeypatch.setattr(evaluate, "run_chunks", real)
    assert cli.main([*args, "--out", str(out)]) == 0
    assert out.read_text() == (tmp_path / "full.csv").read_text()
    assert not partial.exists()


def test_rank_bad_candidates(tmp_path):
    proc = run_cli("rank", str(tmp_path / "missing.json"))
    assert proc.returncode == 2 and "missing.json: no such file" in proc.stderr
    bad = tmp_path / "bad.json"
    bad.write_text('{"grasps": [{"object": "cube"}]}')
    proc = run_cli("rank", str(bad))
    assert proc.returncode == 2 and "bad.json grasp 0: missing or malformed field" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_plan_without_result_leaves_no_file(tmp_path):
    out = tmp_path / "none.json"
    proc = run_cli("plan", "--object", "drill", "--count", "1", "--max-attempts", "1",
                   "--seed", "4", "--out", str(out))
    assert proc.returncode == 2
    assert "no force-closure grasp of drill found" in proc.stderr
    assert not out.exists()


def test_adaptive_rank_reports_draws(tmp_path):
    candidates = _cube_candidates(tmp_path)
    proc = run_cli("rank", str(candidates), "--samples", "100", "--adaptive", "--top-k", "1",
                   "--out", str(tmp_path / "a.csv"))
    assert proc.returncode == 0, proc.stderr
    assert "draws against 400 for fixed n" in proc.stderr


@pytest.mark.expensive
def test_reproduce_fig7_and_fig10(tmp_path):
    proc = run_cli("reproduce", "fig7", "--samples", "60", "--out", str(tmp_path / "f7"))
    assert proc.returncode == 0, proc.stderr
    rows = _read(tmp_path / "f7" / "fig7.csv")
    assert {r["object"] for r in rows} == {"drill", "spray_flask"}
    for name in ("drill", "spray_flask"):
        robust, fragile = (r for r in rows if r["object"] == name)
        assert float(robust["p_fc"]) >= float(fragile["p_fc"])
        # same contacts: equal nominal quality
        assert float(robust["q_nominal"]) == pytest.approx(float(fragile["q_nominal"]), rel=1e-6)
        assert (tmp_path / "f7" / f"fig7_{name}.png").exists()
    proc = run_cli("reproduce", "fig10", "--samples", "20", "--out", str(tmp_path / "f10"))
    assert proc.returncode == 0, proc.stderr
    rows = _read(tmp_path / "f10" / "fig10.csv")
    assert len({r["object"] for r in rows}) == 4 and (tmp_path / "f10" / "fig10.png").exists()
