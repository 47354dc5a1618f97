"""Monte Carlo evaluation: nominal reproduction, seeds and processes, contacts, noise trend."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from cli_helpers import run_cli

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.sampling.noise import MAX_SIGMA, JointNoise
from kinegrasp_env.world.grasps import Grasp, shipped_grasps
from kinegrasp_env.world.objects import OBJECT_NAMES, load_object


@pytest.mark.pin
@pytest.mark.parametrize("name", OBJECT_NAMES)
def test_shipped_sets_reproduce_their_nominal_grasps(name):
    """Regression pin: the shipped grasp files (assets/grasps/, written by
    scripts/make_grasp_sets.py with this reference engine, nominal contacts refreshed when the
    reference polish was made exact) are reproduced by the reference engine at zero noise.
    It catches a change of the engine or of the files, not an error in both."""
    grasps = shipped_grasps(name)
    assert len(grasps) >= 10
    with make_engine("pybullet", DEFAULT_ROBOT, name) as engine:
        draws = engine.run(np.stack([g.q0 for g in grasps]))
    assert np.all(draws.outcome == FORCE_CLOSURE)
    for i, g in enumerate(grasps):
        assert draws.quality[i] == pytest.approx(g.q_nominal, rel=1e-9)
        k = len(g.points)
        np.testing.assert_allclose(draws.points[i, :k], g.points, atol=1e-9)


@pytest.mark.pin
def test_sigma_zero_gives_certain_force_closure():
    """Regression pin on the shipped cube grasp 0's stored nominal Q (as above); the certain
    force closure at sigma 0 is a property."""
    grasp = shipped_grasps("cube")[0]
    stats = evaluate_grasp(grasp, sigma=0.0, n=20, seed=3)
    assert stats.p_fc == 1.0
    assert stats.q_mean == pytest.approx(grasp.q_nominal, rel=1e-12)
    assert stats.q_std == pytest.approx(0.0, abs=1e-12)
    # the nominal closing's Q (the old "error" q_nominal - q_mean is 0)
    assert stats.q_nominal - stats.q_mean == pytest.approx(0.0, abs=1e-12)


def _numbers(stats) -> dict:
    """Every statistic of an evaluation (NaN as None, so equal NaNs compare equal)."""
    out = {key: getattr(stats, key) for key in ("n", "counts", "p_fc", "ci", "q_mean",
                                                 "q_std", "q_skew", "q_nominal")}
    return {key: None if isinstance(value, float) and np.isnan(value) else value
            for key, value in out.items()}


@pytest.mark.expensive
def test_same_seed_same_result_any_processes():
    """300 draws: two chunks of the run's streams (250 + 50 rows), in one process and on two
    worker processes: every number and every draw the same; another seed differs."""
    grasp = shipped_grasps("cube")[1]
    one = evaluate_grasp(grasp, sigma=0.02, n=300, seed=7)
    with LocalExecutor(2) as executor:
        two = evaluate_grasp(grasp, sigma=0.02, n=300, seed=7, executor=executor)
    assert _numbers(one) == _numbers(two)
    for name in ("outcome", "quality", "n_contacts", "points", "normals", "finger", "link"):
        np.testing.assert_array_equal(getattr(one.draws, name), getattr(two.draws, name),
                                      err_msg=name)
    other = evaluate_grasp(grasp, sigma=0.02, n=300, seed=8)
    assert _numbers(other) != _numbers(one)
    assert sum(one.counts.values()) == 300


def test_contacts_lie_on_the_surface_with_mesh_normals():
    grasp = shipped_grasps("mug")[0]
    obj = load_object("mug")
    stats = evaluate_grasp(grasp, sigma=0.01, n=60, seed=1)
    draws = stats.draws
    ok = draws.finger >= 0
    points, normals = draws.points[ok], draws.normals[ok]
    _, distance, _ = trimesh.proximity.closest_point(obj.mesh, points)
    assert distance.max() < 1e-3  # contract: within 1 mm of the mesh
    assert np.median(distance) < 5e-5  # typically on it: projected onto the exact parts
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    # normals point into the object: a millimetre along them from the contact is inside
    # (except at rims, where an edge contact may sit up to ~1 mm off the mesh)
    assert obj.mesh.contains(points + 1e-3 * normals).mean() > 0.95
    # on a face (no other face of the mesh within 0.5 mm) the normal is that face's inward
    # normal; at edges and corners it is pybullet's separating direction, in between
    triangles = obj.mesh.triangles
    on_face = 0
    for point, normal in zip(points, normals, strict=True):
        on = trimesh.triangles.closest_point(triangles, np.tile(point, (len(triangles), 1)))
        gap = np.linalg.norm(on - point, axis=1)
        near = np.unique(np.round(-obj.mesh.face_normals[gap < gap.min() + 5e-4], 6), axis=0)
        if len(near) == 1:
            on_face += 1
            assert near[0] @ normal > np.cos(np.deg2rad(1.0))
    assert on_face > 0.15 * len(points)  # the 7.5-degree facets of the mug are 5 mm wide


@pytest.mark.expensive
def test_pfc_falls_as_noise_grows():
    grasps = shipped_grasps("spray_flask")[:5]
    n = 150
    low = np.array([evaluate_grasp(g, sigma=0.0033, n=n, seed=0).p_fc for g in grasps])
    high = np.array([evaluate_grasp(g, sigma=0.0333, n=n, seed=0).p_fc for g in grasps])
    # standard error of a mean of 5 binomial proportions from n draws is <= 0.5/sqrt(5 n);
    # require the drop to exceed 3 combined standard errors
    margin = 3 * np.sqrt(2) * 0.5 / np.sqrt(5 * n)
    assert low.mean() - high.mean() > margin


def test_outcomes_partition_the_draws():
    grasp = shipped_grasps("drill")[0]
    stats = evaluate_grasp(grasp, sigma=0.03, noise="uniform", n=50, seed=2)
    assert set(stats.counts) == set(OUTCOMES)
    assert sum(stats.counts.values()) == 50 and stats.n == 50
    assert stats.p_fc == stats.counts["force_closure"] / 50


def test_cli_evaluate_json():
    proc = run_cli("evaluate", "--object", "cube", "--grasp", "2", "--sigma", "0.0133",
                   "--samples", "40", "--seed", "0", "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert {"p_fc", "p_fc_ci", "q_mean", "q_var", "q_std", "q_skew", "q_nominal", "error",
            "samples", "outcomes", "sigma", "noise", "seed"} <= set(out)
    assert out["samples"] == 40 and len(out["p_fc_ci"]) == 2


@pytest.mark.parametrize(("args", "needle"), [
    (["--object", "teapot"], "unknown object 'teapot'; known objects: cube, spray_flask"),
    (["--object", "cube", "--grasp", "99"], "grasp index 99 out of range"),
    (["--sigma", "-0.1"], "--sigma must be >= 0"),
    (["--samples", "0"], "--samples must be >= 1"),
])
def test_cli_evaluate_bad_input(args, needle):
    proc = run_cli("evaluate", *args)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and needle in proc.stderr, proc.stderr


def test_bad_grasp_configuration(tmp_path):
    from kinegrasp_env.world.grasps import load_grasps

    g = shipped_grasps("cube")[0].to_dict()
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"grasps": [{**g, "q0": g["q0"][:10]}]}))
    with pytest.raises(ValueError, match="q0 must have 14 entries"):
        load_grasps(bad)
    q0 = list(g["q0"])
    q0[1] = 3.0
    bad.write_text(json.dumps({"grasps": [{**g, "q0": q0}]}))
    with pytest.raises(ValueError, match=r"q0\[1\] \(lbr_iiwa_joint_2\) = 3.0000 is outside"):
        load_grasps(bad)
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_grasps(bad)


# ----------------------------------------------------------------------------- non-finite input
FAST_CRASH_PROBE = """
import numpy as np
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.world.grasps import Grasp, shipped_grasps

q = np.repeat(shipped_grasps("cube")[0].q0[None], 4, axis=0)
q[1, 3], q[2, 0], q[3, 5] = np.nan, np.inf, 1e308 * 10
for name in ("fast", "pybullet"):
    engine = make_engine(name, DEFAULT_ROBOT, "cube")
    try:
        engine.run(q)
    except ValueError as exc:
        print(name, "refused:", exc)
    engine.close()
"""


def test_engines_refuse_non_finite_configurations_before_any_kernel():
    """NaN and inf rows are a ValueError from both engines, never an outcome and never a
    crash: run in a subprocess, as the fast engine's compiled kernel used to die of a
    segmentation fault on such input (which would take pytest down with it)."""
    proc = subprocess.run([sys.executable, "-c", FAST_CRASH_PROBE], capture_output=True,
                          text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert [line.split()[0] for line in lines] == ["fast", "pybullet"]
    for line in lines:
        assert "refused: configuration 1 is not finite: joint 3 = nan" in line, line


def test_engine_refuses_a_wrong_shape():
    with make_engine("pybullet", DEFAULT_ROBOT, "cube") as engine:
        with pytest.raises(ValueError, match=r"robot 'kuka_sdh' must have shape \(n, 14\)"
                                             r".*got \(2, 7\)"):
            engine.run(np.zeros((2, 7)))


@pytest.mark.parametrize(("sigma", "needle"), [
    (1e308, r"sigma must be <= pi \(3\.14159 rad\), got 1e\+308"),
    (3.2, r"sigma must be <= pi \(3\.14159 rad\), got 3\.2"),
    ((0.01,) * 6 + (4.0,), r"sigma must be <= pi \(3\.14159 rad\), got 4"),
])
def test_evaluate_refuses_sigma_above_pi(sigma, needle):
    with pytest.raises(ValueError, match=needle):
        evaluate_grasp(shipped_grasps("cube")[0], sigma=sigma, n=10, engine="fast")


def test_evaluate_refuses_a_non_finite_q0_and_accepts_sigma_pi():
    g = shipped_grasps("cube")[0]
    q0 = g.q0.copy()
    q0[2] = np.nan
    bad = Grasp(g.object, q0, g.palm_pose, g.points, g.normals, g.fingers, g.links,
                g.q_nominal)
    with pytest.raises(ValueError, match="grasp '0': q0 has non-finite entries"):
        evaluate_grasp(bad, sigma=0.01, n=4)
    # the bound itself is allowed: every draw is finite and ends in an outcome
    stats = evaluate_grasp(g, sigma=MAX_SIGMA, n=4, seed=1)
    assert sum(stats.counts.values()) == 4


def test_cli_evaluate_huge_sigma_is_one_line_not_a_crash():
    """The command of the issue: a segmentation fault (exit -11) before; now one line, exit 2."""
    proc = run_cli("evaluate", "--object", "cube", "--grasp", "0", "--sigma", "1e308",
                   "--samples", "10", "--engine", "fast")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().count("\n") == 0 and "sigma" in proc.stderr, proc.stderr
    assert proc.stdout == ""


def test_the_library_refuses_bad_arguments_in_one_line_before_any_draw():
    """What a script writer mixes up, each a ValueError naming it (never numpy's, numba's or
    pybullet's own error after the draws): the noise's type (a JointNoise as the sigma, a
    number as the distribution), seeds that are not integers >= 0, sigma above pi, a q0
    outside the joint limits; one process takes a Generator, a run in chunks and a noise
    model's run do not. Cone edges below 3 are the engines' (``make_engine(...,
    num_edges=)``): refused naming the value when the engine is built."""
    from dataclasses import replace

    from kinegrasp_env import plan_grasps
    from kinegrasp_env.sampling.noise_spec import noise_model_from_spec

    g = shipped_grasps("cube")[0]
    with pytest.raises(ValueError, match="sigma must be a number of radians or one per joint, "
                                         "got JointNoise"):
        evaluate_grasp(g, sigma=JointNoise(0.0133), n=10)
    with pytest.raises(ValueError, match=r"unknown noise type 0\.0133"):
        evaluate_grasp(g, sigma=0.01, noise=0.0133, n=10)
    for seed in (1.5, -1, "1"):
        with pytest.raises(ValueError, match="seed must be an integer >= 0, a numpy"):
            evaluate_grasp(g, sigma=0.01, n=10, seed=seed, engine="fast")
    for seed in (1.5, -1):
        with pytest.raises(ValueError, match="seed must be an integer >= 0, a numpy"):
            plan_grasps("panda", "cube", count=1, seed=seed)
    assert evaluate_grasp(g, sigma=0.01, n=5, seed=np.random.default_rng(0),
                          engine="fast").n == 5
    with LocalExecutor(2) as executor, pytest.raises(
            ValueError, match="a run in chunks takes an integer seed >= 0"):
        evaluate_grasp(g, sigma=0.01, n=10, seed=np.random.default_rng(0), engine="fast",
                       executor=executor)
    with pytest.raises(ValueError, match="a noise model's run takes an integer seed >= 0"):
        evaluate_grasp(g, n=10, seed=np.random.default_rng(0), engine="fast",
                       noise_model=noise_model_from_spec({"joints": {"sigma": 0.01}}))
    for edges, shown in ((0, "0"), (-1, "-1"), (1.5, "1.5")):
        with pytest.raises(ValueError, match=f"num_edges must be an integer >= 3 and <= 32 "
                                             f".*got {shown}$"):
            make_engine("fast", DEFAULT_ROBOT, "cube", num_edges=edges)
    with pytest.raises(ValueError, match="sigma must be <= pi"):
        evaluate_grasp(g, sigma=4.0, n=10, engine="fast")
    far = replace(g, q0=np.r_[10.0, g.q0[1:]])
    with pytest.raises(ValueError, match=r"q0\[0\] \(.*\) = 10.0000 is outside its limits"):
        evaluate_grasp(far, sigma=0.01, n=10, engine="fast")
    # an int or numpy-scalar sigma runs to the end
    for sigma in (0, np.int64(0), np.float32(0.0)):
        assert evaluate_grasp(g, sigma=sigma, n=5, engine="fast").n == 5


def test_a_noise_model_of_another_type_is_refused_in_one_line():
    """A number given as ``noise_model`` (joint noise's sigma in the wrong place) is refused
    in one line naming both types, before any engine is built."""
    with pytest.raises(ValueError, match=r"NoiseModel.*float"):
        evaluate_grasp(shipped_grasps("cube")[0], n=10, noise_model=0.0133)


def test_a_process_keeps_a_bounded_number_of_engines():
    """A sweep over frictions in one process keeps at most MAX_ENGINES engines (a pybullet
    engine holds a simulator client and tens of MB): runs in chunks on an executor of one
    (inline) process build their engines here and keep them
    (:func:`~kinegrasp_env.montecarlo.chunks.robot_engine`)."""
    from kinegrasp_env.montecarlo import chunks
    from kinegrasp_env.montecarlo.execution import MAX_ENGINES

    g = shipped_grasps("cube")[0]
    chunks.close_engines()
    try:
        with LocalExecutor(1) as executor:
            for k in range(MAX_ENGINES + 3):
                # a progress callable: the run goes in chunks even on one local process
                evaluate_grasp(g, sigma=0.01, n=2, engine="pybullet", friction=0.3 + 0.01 * k,
                               executor=executor, progress=lambda done, n: None)
                assert 0 < len(chunks._ENGINES) <= MAX_ENGINES
    finally:
        chunks.close_engines()


def test_the_default_robots_engines_are_context_managers():
    with make_engine("pybullet", DEFAULT_ROBOT, "cube") as engine:
        assert engine.run(shipped_grasps("cube")[0].q0[None]).outcome.shape == (1,)


@pytest.mark.parametrize("robot, method", [("kuka_sdh", "mc"), ("panda", "sobol")])
def test_a_run_without_contacts_closes_the_same_rows_in_blocks(monkeypatch, robot, method):
    """``keep_draws=False`` closes the rows in blocks (7 rows here: blocks that cut the
    streams' chunks of 250 rows and the Sobol points' balance) and keeps no contact slot
    and no hand joint: row for row the same outcome, Q, contact count, static hold verdicts
    and jaw push as one call that keeps everything (each block's rows are drawn by their
    offset in the seed's streams), so the same statistics and nominal Q; the same again on
    two processes, whose chunks drop the contacts as they come back."""
    from kinegrasp_env.montecarlo import evaluate as evaluate_module

    monkeypatch.setattr(evaluate_module, "IN_PROCESS_BLOCK", 7)
    grasp = shipped_grasps("cube", robot)[0]
    run = dict(sigma=0.02, n=40, seed=3, static_hold=True, method=method, offset=5)
    calls = []
    with make_engine("fast", robot, "cube", static_hold=True) as engine:
        closed = engine.run
        engine.run = lambda q, **errors: calls.append(len(q)) or closed(q, **errors)
        full = evaluate_grasp(grasp, **run, engine=engine)
        slim = evaluate_grasp(grasp, **run, engine=engine, keep_draws=False)
    # one call of 40 draws + the nominal row, then blocks of 7 (the last with the nominal)
    assert calls == [41, 7, 7, 7, 7, 7, 6]
    run["engine"] = "fast"
    with LocalExecutor(2) as executor:
        chunked = evaluate_grasp(grasp, **run, keep_draws=False, executor=executor)
    assert 0 < full.p_fc < 1 and full.n == 40
    for other in (slim, chunked):
        assert other.draws.points.shape == (40, 0, 3) and other.draws.hand.shape == (40, 0)
        for key in ("outcome", "quality", "n_contacts", "held", "push"):
            np.testing.assert_array_equal(getattr(other.draws, key), getattr(full.draws, key))
        for key in ("counts", "p_fc", "q_mean", "q_std", "p_hold_static", "q_nominal"):
            assert getattr(other, key) == getattr(full, key), key
    assert np.isfinite(full.draws.push).any() == (robot == "panda")
    with pytest.raises(ValueError, match=r"^keep_draws must be True or False, got 'no'$"):
        evaluate_grasp(grasp, **run, keep_draws="no")


def test_arguments_that_contradict_each_other_are_refused_in_one_line():
    """What would be silently ignored is refused before any work, in one line: joint noise
    beside a noise model (whose joints source is the joint noise), a robot other than the
    given engine's, an unknown robot (named as unknown, as every command names it, not as
    the grasp's mismatch), a grasp or a flag of the wrong type."""
    from kinegrasp_env.sampling.noise_model import NoiseModel
    from kinegrasp_env.sampling.noise_spec import noise_model_from_spec

    grasp, panda_grasp = shipped_grasps("cube")[1], shipped_grasps("cube", "panda")[1]
    model = noise_model_from_spec({"joints": {"sigma": 0.0133}})
    cases = [
        (dict(grasp=grasp, noise_model=model, sigma=0.5),
         r"^give sigma and noise, or a noise_model, not both"),
        (dict(grasp=grasp, noise_model=model, noise="bogus"),
         r"^give sigma and noise, or a noise_model, not both"),
        (dict(grasp=grasp, sigma=0.01, robot="nope"),
         r"^unknown robot 'nope'; known robots: kuka_sdh, panda"),
        (dict(grasp=None, sigma=0.01), r"^grasp must be a Grasp .*, got NoneType$"),
        (dict(grasp=grasp, noise_model=NoiseModel()), r"^noise_model names no source of "
                                                      r"error"),
        (dict(grasp=grasp, sigma=0.01, static_hold="yes"),
         r"^static_hold must be True or False, got 'yes'$"),
    ]
    with make_engine("fast", "panda", "cube") as engine:
        cases.append((dict(grasp=panda_grasp, sigma=0.01, engine=engine, robot="kuka_sdh"),
                      r"^robot 'kuka_sdh' is not the engine's robot 'panda'"))
        for kwargs, message in cases:
            with pytest.raises(ValueError, match=message):
                evaluate_grasp(n=20, **{"engine": "fast", **kwargs})
    with pytest.raises(ValueError, match=r"^unknown robot 'nope'; known robots"):
        shipped_grasps("cube", robot="nope")


def test_the_nominal_q_is_the_same_to_the_last_digit_in_and_out_of_process():
    """Under a noise model whose draws carry palm errors and a per-draw mu, the nominal
    closing is closed without errors in one process as the chunks close it (it rode with
    the draws, under identity errors and an explicit mu, and its Q differed in the last
    digits): the same Q, bit for bit, and so every statistic."""
    from kinegrasp_env.sampling.noise_spec import noise_model_from_spec

    model = noise_model_from_spec({"joints": {"sigma": 0.0133}, "palm": {
        "translation_sigma": 0.002, "rotation_sigma": 0.001}, "friction": {
        "distribution": "uniform", "low": 0.4, "high": 0.8}})
    grasp = shipped_grasps("cube")[1]
    here = evaluate_grasp(grasp, noise_model=model, n=30, seed=2, engine="fast")
    with LocalExecutor(2) as executor:
        there = evaluate_grasp(grasp, noise_model=model, n=30, seed=2, engine="fast",
                               executor=executor)
    assert here.q_nominal > 0 and here.q_nominal == there.q_nominal
    assert (here.p_fc, here.q_mean) == (there.p_fc, there.q_mean)
