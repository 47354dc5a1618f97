"""Planner, null-space variants, and the plan/rank command line (incl. resume)."""

from __future__ import annotations

import csv
import json
import signal
import time

import numpy as np
import pytest
from cli_helpers import run_cli, start_cli

from kinegrasp_env import cli
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES
from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
from kinegrasp_env.quality import ferrari_canny
from kinegrasp_env.robot.default_robot import ELBOW_LINK, PALM_LINK
from kinegrasp_env.robot.kinematics import Kinematics, pose_error
from kinegrasp_env.toolkit.arm_variants import variants_of
from kinegrasp_env.toolkit.grasp_planner import plan_grasps
from kinegrasp_env.world.grasps import load_grasps, shipped_grasps


@pytest.fixture(scope="module")
def drill_engine():
    engine = RobotReferenceEngine("kuka_sdh", "drill")
    yield engine
    engine.close()


@pytest.mark.expensive
def test_planned_grasps_of_the_default_robot_are_valid(drill_engine):
    """The shared planner's SDH grasps: joints within limits, the stored palm pose the
    forward kinematics' (1e-9), force closure when the reference engine closes again, and
    the stored Q qhull's on the stored contacts (not the engine's scoring path, 1e-9
    relative); the pre-shapes drawn (not all the ``open`` one)."""
    grasps = plan_grasps("kuka_sdh", "drill", count=3, seed=5)
    assert len(grasps) == 3
    description = drill_engine.description
    kin, model = Kinematics(description.model), description.model
    for g in grasps:
        assert model.within_limits(g.q0)
        err = pose_error(kin.pose(g.q0, PALM_LINK), g.palm_pose[None])
        assert np.abs(err).max() < 1e-9
        draw = drill_engine.run(g.q0[None])
        assert draw.outcome[0] == FORCE_CLOSURE
        obj = drill_engine.obj
        q_hull = ferrari_canny(g.points, g.normals, method="qhull", torque_scale=1 / obj.r_max,
                               center=obj.center_of_mass)
        assert q_hull == pytest.approx(g.q_nominal, rel=1e-9)
    opened = description.open_configuration()[7:]
    assert any(not np.allclose(g.q0[7:], opened) for g in grasps)


def test_variants_keep_palm_and_contacts(drill_engine):
    """Null-space variants of a shipped grasp: the palm pose kept (1e-6), the elbow moved
    by more than 2 cm, and the contacts the reference engine finds when it closes each
    variant again within 0.5 mm of the grasp's."""
    grasp = shipped_grasps("drill")[0]
    variants = variants_of(grasp, drill_engine, 3)
    assert len(variants) >= 2
    kin = Kinematics(drill_engine.description.model)
    elbow0 = kin.pose(grasp.q0, ELBOW_LINK)[0, :3, 3]
    for v in variants:
        err = pose_error(kin.pose(v.q0, PALM_LINK), grasp.palm_pose[None])
        assert np.abs(err).max() < 1e-6
        draw = drill_engine.run(v.q0[None])
        k = int(draw.n_contacts[0])
        assert k == len(grasp.points)
        assert np.abs(draw.points[0, :k] - grasp.points).max() < 5e-4
        assert np.linalg.norm(kin.pose(v.q0, ELBOW_LINK)[0, :3, 3] - elbow0) > 0.02
        assert v.meta["variant_of"] == grasp.id


def test_variant_ids_keep_clear_of_the_ids_taken(drill_engine):
    """Variants are named ``<id>v<k>``, k the configuration's place among those tried; ids
    already taken (a grasp file's own variants, when fig10 finds variants of its first grasp)
    are skipped, so two different configurations never share an id."""
    grasp = shipped_grasps("drill")[0]
    plain = [v.id for v in variants_of(grasp, drill_engine, 3)]
    assert plain[0] == f"{grasp.id}v1"
    taken = {f"{grasp.id}v1", f"{grasp.id}v2"}
    named = [v.id for v in variants_of(grasp, drill_engine, 3, taken)]
    assert len(named) == len(plain) and not taken & set(named)
    assert named[0] == f"{grasp.id}v3"


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
                             "q_nominal", "error", "samples", "engine", *OUTCOMES,
                             "nominal_fc"]
    assert {r["engine"] for r in rows} == {"pybullet"}
    for r in rows:  # every draw has one outcome; P(FC) is the force-closure share
        counts = [int(r[name]) for name in OUTCOMES]
        assert sum(counts) == int(r["samples"]) == 60
        assert int(r["force_closure"]) / 60 == pytest.approx(float(r["p_fc"]), abs=1e-6)
    p = [float(r["p_fc"]) for r in rows]
    assert p == sorted(p, reverse=True)
    assert all(float(r["p_fc_lo"]) <= float(r["p_fc"]) <= float(r["p_fc_hi"]) for r in rows)


def _cube_candidates(tmp_path, count=4):
    from kinegrasp_env.world.grasps import save_grasps

    path = tmp_path / "cube.json"
    save_grasps(shipped_grasps("cube")[:count], path)
    return path


def _log(partial) -> tuple[list[dict], list[int]]:
    """The settings lines and the candidate indices of a rank log."""
    items = [json.loads(line) for line in partial.read_text().splitlines()]
    return [i for i in items if "settings" in i], [i["index"] for i in items if "index" in i]


def test_rank_resumes_after_any_number_of_interruptions(tmp_path, monkeypatch, capsys):
    """Stopped before any candidate finished, twice (the second start once wrote a second
    settings line and every later run failed with `error: index`), then after two: the
    log keeps one settings line and each candidate once, and the resumed CSV equals an
    uninterrupted run's byte for byte."""
    from kinegrasp_env.montecarlo import chunks

    candidates = _cube_candidates(tmp_path)
    args = ["rank", str(candidates), "--samples", "40", "--seed", "3", "--engine", "fast"]
    assert cli.main([*args, "--out", str(tmp_path / "full.csv")]) == 0

    real = chunks.chunked_draws
    out = tmp_path / "resumed.csv"
    partial = tmp_path / "resumed.csv.partial.jsonl"
    for stop_at, finished in ((1, []), (1, []), (3, [0, 1])):
        calls = {"n": 0}

        def interrupted(*a, stop_at=stop_at, calls=calls, **k):
            calls["n"] += 1
            if calls["n"] == stop_at:
                raise KeyboardInterrupt
            return real(*a, **k)

        monkeypatch.setattr(chunks, "chunked_draws", interrupted)
        assert cli.main([*args, "--out", str(out)]) == 130
        assert not out.exists()  # nothing half-written
        settings, indices = _log(partial)
        assert len(settings) == 1 and indices == finished
    monkeypatch.setattr(chunks, "chunked_draws", real)
    capsys.readouterr()
    assert cli.main([*args, "--out", str(out)]) == 0
    assert "resuming: 2 of 4 candidates already ranked" in capsys.readouterr().err
    assert out.read_text() == (tmp_path / "full.csv").read_text()
    assert not partial.exists()
    rows = _read(out)
    assert list(rows[0])[-6:] == ["engine", *OUTCOMES, "nominal_fc"] and {
        r["engine"] for r in rows} == {
        "fast"}
    # the resumed candidates' outcome counts came back from the log
    assert all(sum(int(r[name]) for name in OUTCOMES) == 40 for r in rows)


def _stopped_run(tmp_path, monkeypatch, args: list[str]) -> None:
    """``rank args`` stopped (Ctrl-C) before its first candidate finished."""
    from kinegrasp_env.montecarlo import chunks

    def interrupt(*a, **k):
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(chunks, "chunked_draws", interrupt)
        assert cli.main(args) == 130


@pytest.mark.parametrize(("change", "needle"), [
    (["--engine", "pybullet"], '(--engine: "fast" there, "pybullet" now)'),
    (["--sigma", "0.02"], "(--sigma: 0.0133 there, 0.02 now)"),
    (["--noise", "uniform"], '(--noise: "gaussian" there, "uniform" now)'),
    (["--samples", "41"], "(--samples: 40 there, 41 now)"),
    (["--samples", "300"], "(--samples: 40 there, 300 now)"),
    (["--seed", "4"], "(--seed: 3 there, 4 now)"),
    (["other candidates"], "(candidates file content (SHA-256): "),
    (["--adaptive", "--top-k", "1"], "which --adaptive cannot resume"),
    (["older log"], '(layout of the random draws (a log of an older kinegrasp): "not recorded" '
                    'there, "rows of chunks of 250" now)'),
    (["older default-robot log"], "(robot (--robot, or the candidates'; a log of an older "
                                  'kinegrasp records none): "not recorded" there, "kuka_sdh" '
                                  "now)"),
])
def test_rank_resume_with_other_settings_is_refused(tmp_path, monkeypatch, capsys, change,
                                                     needle):
    """A log is resumed only by a run with the same value of every setting that changes a
    number; the refusal is one line that names the setting and leaves the log as it was."""
    candidates = _cube_candidates(tmp_path)
    out = tmp_path / "r.csv"
    partial = tmp_path / "r.csv.partial.jsonl"
    args = ["rank", str(candidates), "--samples", "40", "--seed", "3", "--engine", "fast",
            "--out", str(out)]
    _stopped_run(tmp_path, monkeypatch, args)
    (settings,), indices = _log(partial)
    assert indices == []
    assert set(settings["settings"]) == {"candidates_sha256", "engine", "friction",
                                         "num_edges", "noise", "sigma", "method", "samples",
                                         "chunk", "seed", "draw_layout", "robot",
                                         "criterion_scores"}
    if change == ["older log"]:  # a log written before the layout was recorded
        del settings["settings"]["draw_layout"]
        partial.write_text(json.dumps(settings) + "\n")
        change = []
    if change == ["older default-robot log"]:  # the default robot's former own path's log
        for key in ("robot", "criterion_scores"):
            del settings["settings"][key]
        partial.write_text(json.dumps(settings) + "\n")
        change = []
    log = partial.read_text()
    if change == ["other candidates"]:
        _cube_candidates(tmp_path, count=5)  # the same file name, one grasp more
        change = []
    capsys.readouterr()
    assert cli.main([*args, *change]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], lines
    assert "delete it" in lines[0]
    assert partial.read_text() == log
    assert not out.exists()


def test_rank_best_elbow_log_of_an_older_kinegrasp_is_refused_before_the_search(
        tmp_path, monkeypatch, capsys):
    """A ``--best-elbow`` log records the engine the elbows were chosen with; a log without it
    (an older kinegrasp, whose added robots chose with another engine) is refused in one line
    naming that setting, before any elbow is searched, and the log is left as it was; a
    search that fails writes no log."""
    from kinegrasp_env.cli import ranking

    candidates = _cube_candidates(tmp_path, count=2)
    out = tmp_path / "r.csv"
    partial = tmp_path / "r.csv.partial.jsonl"
    args = ["rank", str(candidates), "--samples", "40", "--seed", "3", "--engine", "fast",
            "--best-elbow", "20", "--out", str(out)]
    searched = []
    with monkeypatch.context() as patch:  # the elbows as they are: only the log matters here
        patch.setattr(ranking, "best_elbows", lambda grasps, *a, **k: searched.append(1)
                      or grasps)
        _stopped_run(tmp_path, monkeypatch, args)
        (settings,), _ = _log(partial)
        assert settings["settings"]["best_elbow_engine"] == "fast"
        del settings["settings"]["best_elbow_engine"]
        partial.write_text(json.dumps(settings) + "\n")
        log, searched[:] = partial.read_text(), []
        capsys.readouterr()
        assert cli.main(args) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and ('(the engine --best-elbow chose with (a log of an older '
                                'kinegrasp): "not recorded" there, "fast" now)') in lines[0]
    assert searched == [] and partial.read_text() == log and not out.exists()
    # a search that fails (one line) leaves no log behind to block the next run
    partial.unlink()

    def refused(*a, **k):
        from kinegrasp_env.cli.common import CLIError

        raise CLIError("no elbow here")

    with monkeypatch.context() as patch:
        patch.setattr(ranking, "best_elbows", refused)
        assert cli.main(args) == 2
    assert not partial.exists() and not out.exists()


def test_rank_criterion_is_not_a_resume_setting(tmp_path, monkeypatch, capsys):
    """--criterion only orders finished candidates: a run stopped under one criterion
    resumes under another, to the CSV an uninterrupted run with that criterion writes."""
    candidates = _cube_candidates(tmp_path)
    args = ["rank", str(candidates), "--samples", "40", "--seed", "3", "--engine", "fast"]
    _stopped_run(tmp_path, monkeypatch, [*args, "--out", str(tmp_path / "r.csv")])
    assert cli.main([*args, "--criterion", "q_mean", "--out", str(tmp_path / "r.csv")]) == 0
    assert cli.main([*args, "--criterion", "q_mean", "--out", str(tmp_path / "u.csv")]) == 0
    assert (tmp_path / "r.csv").read_text() == (tmp_path / "u.csv").read_text()


def test_rank_log_cut_off_by_a_kill_is_repaired_and_a_damaged_one_refused(
        tmp_path, monkeypatch, capsys):
    """A last line cut off mid-write (a kill) is dropped and its candidate computed again;
    a damaged line before the end is refused in one line (never `error: index`)."""
    from kinegrasp_env.montecarlo import chunks

    candidates = _cube_candidates(tmp_path)
    args = ["rank", str(candidates), "--samples", "40", "--seed", "3", "--engine", "fast"]
    assert cli.main([*args, "--out", str(tmp_path / "full.csv")]) == 0
    out = tmp_path / "r.csv"
    partial = tmp_path / "r.csv.partial.jsonl"
    real, calls = chunks.chunked_draws, {"n": 0}

    def third_call_interrupted(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    with monkeypatch.context() as patch:
        patch.setattr(chunks, "chunked_draws", third_call_interrupted)
        assert cli.main([*args, "--out", str(out)]) == 130
    log = partial.read_text()
    assert _log(partial)[1] == [0, 1]

    partial.write_text(log.replace('"index": 0', '"index": 0 garbage'))
    capsys.readouterr()
    assert cli.main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"kinegrasp rank: error: {partial} line 2 is damaged; delete the file to "
                   "start over"]

    partial.write_text(log + '{"index": 2, "successes": 3')  # killed while writing
    assert cli.main([*args, "--out", str(out)]) == 0
    assert "resuming: 2 of 4 candidates already ranked" in capsys.readouterr().err
    assert out.read_text() == (tmp_path / "full.csv").read_text()


def _finished(partial) -> int:
    """Candidates in a rank log that a running process may be appending to (a line without
    its newline yet does not count)."""
    text = partial.read_text() if partial.exists() else ""
    return text[:text.rfind("\n") + 1].count('"index"')


def _wait_for(condition, what: str, process, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert process.poll() is None, f"the run ended before {what}"
        assert time.monotonic() < deadline, f"timed out waiting until {what}"
        time.sleep(0.005)


def _read_until_resuming(process) -> None:
    """Read the run's stderr until it says it has read its log back."""
    for line in process.stderr:
        if line.startswith("resuming:"):
            return
    raise AssertionError("the run ended without resuming")


def _sigint(process, partial) -> int:
    """Ctrl-C the run; it exits 130 leaving a log with one settings line and candidates
    0, 1, ... each once. Returns how many candidates the log holds."""
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == "kinegrasp: interrupted", err
    settings, indices = _log(partial)
    assert len(settings) == 1 and indices == list(range(len(indices)))
    return len(indices)


@pytest.mark.expensive
def test_rank_interrupted_three_times_by_sigint_resumes_to_the_same_csv(tmp_path):
    """A real process stopped by SIGINT three times (twice before any candidate finished,
    once after some did), then resumed, writes the CSV of an uninterrupted run byte for
    byte; resuming with another engine is refused."""
    candidates = _cube_candidates(tmp_path, count=8)
    args = ["rank", str(candidates), "--samples", "300", "--seed", "1", "--engine", "fast"]
    assert cli.main([*args, "--out", str(tmp_path / "full.csv")]) == 0
    out = tmp_path / "r.csv"
    partial = tmp_path / "r.csv.partial.jsonl"
    stops = []
    # 1: a fresh run, stopped once its log exists (its first candidate is still running:
    # building the engine alone takes ~0.5 s, the signal goes within ~10 ms)
    process = start_cli(*args, "--out", str(out))
    _wait_for(partial.exists, "its log exists", process)
    stops.append(_sigint(process, partial))
    # 2: resumed, stopped as soon as it has read the log back
    process = start_cli(*args, "--out", str(out))
    _read_until_resuming(process)
    stops.append(_sigint(process, partial))
    # 3: resumed, stopped after two more candidates finished
    process = start_cli(*args, "--out", str(out))
    _read_until_resuming(process)
    _wait_for(lambda: _finished(partial) >= stops[-1] + 2, "two candidates finished", process)
    stops.append(_sigint(process, partial))
    print(f"candidates finished at each SIGINT: {stops} of 8")
    assert stops[:2] == [0, 0] and 2 <= stops[2] < 8
    assert not out.exists()

    log = partial.read_text()
    refused = run_cli(*args, "--out", str(out), "--engine", "pybullet")
    assert refused.returncode == 2
    assert refused.stderr.strip().splitlines() == [
        f"kinegrasp rank: error: {partial} holds an interrupted ranking with other settings "
        '(--engine: "fast" there, "pybullet" now); delete it to start over, or resume with '
        "the same settings"]
    assert partial.read_text() == log

    resumed = run_cli(*args, "--out", str(out))
    assert resumed.returncode == 0, resumed.stderr
    assert f"resuming: {stops[2]} of 8 candidates already ranked" in resumed.stderr
    assert out.read_bytes() == (tmp_path / "full.csv").read_bytes()
    assert not partial.exists()


def test_rank_bad_candidates(tmp_path):
    proc = run_cli("rank", str(tmp_path / "missing.json"))
    assert proc.returncode == 2 and "missing.json: no such file" in proc.stderr
    bad = tmp_path / "bad.json"
    bad.write_text('{"grasps": [{"object": "cube"}]}')
    proc = run_cli("rank", str(bad))
    assert proc.returncode == 2 and "bad.json grasp 0: field 'q0' missing" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_rank_refuses_repeated_ids_and_bad_paths_in_one_line(tmp_path, capsys):
    """The CSV is keyed by candidate id: two candidates with one id are refused (computing
    both and writing two rows with the same id would leave the reader guessing)."""
    from kinegrasp_env.world.grasps import save_grasps

    grasps = shipped_grasps("cube")[:3]
    twice = tmp_path / "twice.json"
    save_grasps([grasps[0], grasps[1], grasps[0]], twice)
    candidates = _cube_candidates(tmp_path)
    a_file = tmp_path / "file"
    a_file.write_text("")
    for argv, needle in [
        ([str(twice)], f"{twice}: grasps 0 and 2 have the same id '{grasps[0].id}' of "
                       "cube; ids must be unique"),
        ([str(tmp_path)], f"{tmp_path} is a folder, not a grasp file"),
        ([str(candidates), "--out", str(tmp_path)], "is a folder; give a file name"),
        ([str(candidates), "--out", str(a_file / "r.csv")], f"{a_file} is not a folder"),
        ([str(candidates), "--adaptive", "--top-k", "4"],
         "--top-k must be below the number of candidates (4)"),
    ]:
        assert cli.main(["rank", *argv, "--engine", "fast", "--samples", "10"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err
    assert not list(tmp_path.glob("*.csv*"))
    # every command that reads a grasp file refuses the repeated id alike
    for argv in (["evaluate", "--grasps", str(twice), "--grasp", "0", "--samples", "10"],
                 ["report", "--grasps", str(twice), "--grasp", "0,1", "--samples", "10",
                  "--out", str(tmp_path / "r.html")],
                 ["elbow", "--grasps", str(twice), "--grasp", "0", "--samples", "10"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "grasps 0 and 2 have the same id" in err[0], err
    assert not (tmp_path / "r.html").exists()
    # a file of two objects' grasps, each numbered from 0 (agents/prepare.py writes such
    # files): read by every reader; rank, keyed by id, refuses it; --grasp by a shared id
    # asks for the index
    both = tmp_path / "both.json"
    save_grasps([grasps[0], shipped_grasps("mug")[0]], both)
    assert [g.object for g in load_grasps(both)] == ["cube", "mug"]
    assert cli.main(["rank", str(both), "--engine", "fast", "--samples", "10"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "grasps 0 and 1 have the same id '0'; ids must be unique" in err[0]
    args = ["evaluate", "--grasps", str(both), "--samples", "5", "--engine", "fast", "--json"]
    assert cli.main([*args, "--grasp", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"kinegrasp evaluate: error: --grasp 0: 2 grasps of {both} have this id (of "
                   "several objects); give one by its index (0, 1)"]
    assert cli.main([*args, "--grasp", "1"]) == 0
    assert json.loads(capsys.readouterr().out)["object"] == "mug"


def test_plan_without_result_leaves_no_file(tmp_path):
    out = tmp_path / "none.json"
    proc = run_cli("plan", "--object", "drill", "--count", "1", "--max-attempts", "1",
                   "--seed", "4", "--out", str(out))
    assert proc.returncode == 2
    assert "no force-closure grasp of drill found" in proc.stderr
    assert not out.exists()


def test_adaptive_rank_reports_draws(tmp_path):
    candidates = _cube_candidates(tmp_path)
    # 300 draws a candidate: chunks of 250 and 50; the fixed-n run draws 4 x 300, not 4 x 2
    # chunks of 250
    proc = run_cli("rank", str(candidates), "--samples", "300", "--adaptive", "--top-k", "1",
                   "--out", str(tmp_path / "a.csv"))
    assert proc.returncode == 0, proc.stderr
    assert "draws against 1200 for fixed n" in proc.stderr


@pytest.mark.expensive
def test_reproduce_fig7_and_fig10(tmp_path):
    proc = run_cli("reproduce", "fig7", "--samples", "60", "--out", str(tmp_path / "f7"))
    assert proc.returncode == 0, proc.stderr
    rows = _read(tmp_path / "f7" / "fig7.csv")
    objects = {r["object"] for r in rows}  # the robot's every object with two variants
    assert {"drill", "spray_flask"} <= objects <= {"cube", "drill", "mug", "spray_flask"}
    for name in objects:
        robust, fragile = (r for r in rows if r["object"] == name)
        # two different arm configurations of the same contacts (robust >= fragile holds by
        # construction, max >= min: not asserted)
        assert robust["id"] != fragile["id"]
        # same contacts: equal nominal quality
        assert float(robust["q_nominal"]) == pytest.approx(float(fragile["q_nominal"]), rel=1e-6)
        assert (tmp_path / "f7" / f"fig7_{name}.png").exists()
    proc = run_cli("reproduce", "fig10", "--samples", "20", "--out", str(tmp_path / "f10"))
    assert proc.returncode == 0, proc.stderr
    rows = _read(tmp_path / "f10" / "fig10.csv")
    assert len({r["object"] for r in rows}) == 4 and (tmp_path / "f10" / "fig10.png").exists()
