"""``--friction MU`` on the scoring commands, for the default robot and a description robot.

What each test proves:

* a larger mu can only widen each contact's friction pyramid (its edges n + mu t, docs/
  conventions.md), so on the same draws (same seed; the closing's geometry does not depend on
  mu) the wrench hull at a larger mu contains the one at a smaller: force closure and Q can
  only grow draw by draw, and the start-collision and missed counts stay the same. A
  command that ignored ``--friction`` would print the same numbers at every mu; one that
  changed the draws with it would break the equal geometry counts;
* the nominal Q printed is the grasp's nominal contacts (the engine's closing of q0, within
  the engines' agreement of the recorded ones) scored at that mu (an exact formula for point
  contacts: the hull of the edge wrenches, here by the public ``ferrari_canny``), and it
  equals the recorded value at the default mu;
* ``rank``, ``sweep`` and ``reproduce`` run the same draws as ``evaluate`` at the same mu
  (common seeds), so their P(FC) equals evaluate's: the option reaches every command;
* bad values and a friction noise source beside ``--friction`` are one line each.
"""

from __future__ import annotations

import csv
import json

import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.quality import ferrari_canny
from kinegrasp_env.world.grasps import save_grasps, shipped_grasps
from kinegrasp_env.world.objects import load_object

SAMPLES = "200"
GEOMETRY = ("start_collision", "missed")


def _evaluate(capsys, *extra: str) -> dict:
    assert main(["evaluate", "--object", "cube", "--grasp", "0", "--sigma", "0.0133",
                 "--samples", SAMPLES, "--engine", "fast", "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("robot", [[], ["--robot", "panda"]], ids=["kuka_sdh", "panda"])
def test_friction_widens_the_cones_draw_by_draw(capsys, robot):
    runs = {mu: _evaluate(capsys, *robot, "--friction", str(mu)) for mu in (0.2, 0.5, 1.0)}
    for low, high in ((0.2, 0.5), (0.5, 1.0)):
        a, b = runs[low], runs[high]
        assert {k: a["outcomes"][k] for k in GEOMETRY} == {k: b["outcomes"][k]
                                                            for k in GEOMETRY}
        assert a["p_fc"] <= b["p_fc"] and a["q_nominal"] <= b["q_nominal"] + 1e-12
    assert runs[0.2]["p_fc"] < runs[1.0]["p_fc"]  # the option reaches the scoring
    assert runs[0.5] == _evaluate(capsys, *robot)  # the default is mu 0.5


def test_nominal_q_is_the_contacts_rescored(capsys):
    grasp = shipped_grasps("cube")[0]
    obj = load_object("cube")
    for mu in (0.3, 0.5, 0.9):
        shown = _evaluate(capsys, "--friction", str(mu))
        exact = ferrari_canny(grasp.points, grasp.normals, friction=mu,
                              torque_scale=obj.torque_scale, center=obj.center_of_mass)
        # the fast engine closes q0 once: its contacts are the recorded ones to the engines'
        # agreement (1e-8 m), so Q matches to 1e-7 relative (measured 9e-9)
        assert shown["q_nominal"] == pytest.approx(exact, rel=1e-7, abs=1e-15)
    assert _evaluate(capsys)["q_nominal"] == pytest.approx(grasp.q_nominal, rel=1e-7)


@pytest.mark.parametrize("robot", ["kuka_sdh", "panda"])
def test_rank_and_sweep_run_evaluate_at_the_same_friction(capsys, tmp_path, robot):
    grasps = tmp_path / "g.json"
    save_grasps(shipped_grasps("cube", robot)[:2], grasps)
    out = tmp_path / "r.csv"
    assert main(["rank", str(grasps), "--sigma", "0.0133", "--samples", SAMPLES, "--engine",
                 "fast", "--friction", "0.3", "--out", str(out)]) == 0
    capsys.readouterr()
    rows = {r["id"]: r for r in csv.DictReader(out.open())}
    spec = tmp_path / "spec.yaml"
    spec.write_text(f"objects: [cube]\ngrasps: [0, 1]\nsigmas: [0.0133]\nengines: [fast]\n"
                    f"samples: {SAMPLES}\nrobot: {robot}\ngrasp_files: {{cube: {grasps}}}\n"
                    "friction: 0.3\n")
    assert main(["sweep", str(spec), "--out", str(tmp_path / "sweep")]) == 0
    capsys.readouterr()
    cells = list(csv.DictReader((tmp_path / "sweep" / "summary.csv").open()))
    for index, grasp in enumerate(shipped_grasps("cube", robot)[:2]):
        shown = _evaluate(capsys, "--robot", robot, "--grasps", str(grasps), "--grasp",
                          str(index), "--friction", "0.3")
        row = rows[grasp.id]
        assert float(row["p_fc"]) == pytest.approx(shown["p_fc"], abs=1e-6)
        assert int(row["force_closure"]) == shown["outcomes"]["force_closure"]
        # the CSV keeps 6 significant digits: within half a unit of the 6th, 5e-6 relative
        assert float(row["q_nominal"]) == pytest.approx(shown["q_nominal"], rel=5e-6)
        cell = next(c for c in cells if int(c["grasp"]) == index)
        assert float(cell["p_fc"]) == pytest.approx(shown["p_fc"], abs=1e-9)
        # the sweep's nominal Q is the reference engine's closing, evaluate's the fast
        # engine's: their contacts agree to 1e-8 m, the Panda's Q to 2.1e-6 relative
        # (measured); 1e-5 leaves a margin
        assert float(cell["q_nominal"]) == pytest.approx(shown["q_nominal"], rel=1e-5,
                                                         abs=1e-12)


def test_reproduce_table1_at_another_friction(capsys, tmp_path):
    assert main(["reproduce", "table1", "--object", "cube", "--grasps", "1", "--samples",
                 SAMPLES, "--friction", "0.3", "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    row = next(r for r in csv.DictReader((tmp_path / "table1.csv").open())
               if float(r["sigma"]) == 0.0133)
    assert float(row["p_fc"]) == pytest.approx(
        _evaluate(capsys, "--friction", "0.3")["p_fc"], abs=1e-9)


@pytest.mark.parametrize(("value", "words"), [("-0.1", "--friction must be >= 0"),
                                              ("nan", "not a finite number"),
                                              ("x", "is not a number")])
def test_bad_friction_is_one_line(capsys, value, words):
    for command in (["evaluate"], ["rank", "nosuch.json"], ["elbow"], ["plan"]):
        assert main([*command, "--friction", value]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (command, err)


def test_a_simulation_at_zero_friction_is_one_line_before_any_work(capsys, tmp_path,
                                                                   monkeypatch):
    """mu 0 is a valid friction cone (kinematic engines score it) but not a simulated
    contact: every command that simulates (the physics engine, the holding test, validate,
    a sweep's physics cells) refuses it in one line, and writes nothing (rank's log
    included)."""
    from kinegrasp_env.world.grasps import shipped_grasp_file

    monkeypatch.chdir(tmp_path)
    (tmp_path / "j.yaml").write_text("joints: {sigma: 0.0133}\n")
    (tmp_path / "s.yaml").write_text("objects: [cube]\ngrasps: [0]\nsigmas: [0.01]\n"
                                     "engines: [physics]\nsamples: 2\n")
    grasp = ["--object", "cube", "--grasp", "0", "--samples", "2"]
    for command in (["validate", *grasp, "--out", "v"],
                    ["evaluate", *grasp, "--hold-test"],
                    ["evaluate", *grasp, "--engine", "physics"],
                    ["rank", str(shipped_grasp_file("cube")), "--samples", "2", "--criterion",
                     "hold", "--out", "r.csv"],
                    ["sensitivity", *grasp, "--noise-spec", "j.yaml", "--engine", "physics"],
                    ["sweep", "s.yaml", "--out", "w"]):
        assert main([*command, "--friction", "0"]) == 2, command
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "> 0" in err[0], (command, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["j.yaml", "s.yaml"]
    assert main(["evaluate", *grasp, "--engine", "fast", "--friction", "0"]) == 0  # kinematic


def test_friction_beside_a_friction_source_is_refused(capsys, tmp_path):
    spec = tmp_path / "noise.yaml"
    spec.write_text("joints: {sigma: 0.01}\nfriction: {distribution: gaussian, mean: 0.5, "
                    "sigma: 0.1}\n")
    assert main(["evaluate", "--noise-spec", str(spec), "--friction", "0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "friction source" in err[0]


@pytest.mark.parametrize("source, mu", [("{distribution: fixed, value: 0.8}", 0.8),
                                        ("{distribution: uniform, low: 0.6, high: 1.0}", 0.8),
                                        ("{distribution: gaussian, mean: 0.8, sigma: 0.1}",
                                         0.8)])
def test_the_nominal_q_of_a_friction_source_is_at_its_nominal_mu(capsys, tmp_path, source,
                                                                  mu):
    """With a friction source the draws take mu from it; the grasp's nominal Q is then the
    Q of its noise-free closing at the source's nominal mu (its value, the middle of its
    range, its mean), as ``--friction 0.8`` gives it (it was Q at the default 0.5); the
    independent check is Q by hand from the nominal contacts at mu 0.8."""
    spec = tmp_path / "noise.yaml"
    spec.write_text(f"friction: {source}\n")
    assert main(["evaluate", "--object", "cube", "--noise-spec", str(spec), "--samples", "4",
                 "--engine", "fast", "--json"]) == 0
    nominal = json.loads(capsys.readouterr().out)["q_nominal"]
    assert main(["evaluate", "--object", "cube", "--friction", str(mu), "--sigma", "0",
                 "--samples", "1", "--engine", "fast", "--json"]) == 0
    assert nominal == pytest.approx(json.loads(capsys.readouterr().out)["q_nominal"],
                                    rel=1e-12)
    grasp, obj = shipped_grasps("cube")[0], load_object("cube")
    by_hand = ferrari_canny(grasp.points, grasp.normals, friction=mu,
                            torque_scale=obj.torque_scale, center=obj.center_of_mass)
    # as test_nominal_q_is_the_contacts_rescored: to 1e-7 relative
    assert nominal == pytest.approx(by_hand, rel=1e-7) and nominal != pytest.approx(
        grasp.q_nominal, rel=1e-3)


def test_friction_beside_a_source_is_refused_whatever_its_value(capsys, tmp_path):
    """``--friction 0.5`` (the default's value) beside a friction source was taken as no
    option, and in a sweep it set every cell's mu, the plain cells' too, to the source's
    nominal one. Given at all, it is refused."""
    spec = tmp_path / "noise.yaml"
    spec.write_text("joints: {sigma: 0.01}\nfriction: {distribution: fixed, value: 0.3}\n")
    assert main(["evaluate", "--noise-spec", str(spec), "--friction", "0.5"]) == 2
    assert "friction source" in capsys.readouterr().err
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"objects: [cube]\ngrasps: [0]\nsigmas: [0.01]\nengines: [fast]\n"
                     f"samples: 4\nnoise: [gaussian, {spec.name}]\n")
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "s"), "--friction", "0.5"]) == 2
    assert "friction source" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_the_library_takes_a_friction_sources_nominal_mu_too():
    """``evaluate_grasp`` under a model with a friction source: the nominal Q is the
    contacts' Q at the source's nominal mu (by hand, as above), as ``evaluate
    --noise-spec`` gives it."""
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.sampling.noise_spec import noise_model_from_spec

    grasp, obj = shipped_grasps("cube")[0], load_object("cube")
    model = noise_model_from_spec({"joints": {"sigma": 0.01},
                                   "friction": {"distribution": "fixed", "value": 0.8}})
    run = evaluate_grasp(grasp, n=4, seed=0, engine="fast", noise_model=model)
    by_hand = ferrari_canny(grasp.points, grasp.normals, friction=0.8,
                            torque_scale=obj.torque_scale, center=obj.center_of_mass)
    assert run.q_nominal == pytest.approx(by_hand, rel=1e-7)


@pytest.mark.parametrize("source, said", [("{distribution: fixed, value: 0.3}",
                                           "friction mu 0.3"),
                                          ("{distribution: uniform, low: 0.2, high: 0.4}",
                                           "friction mu per draw")])
def test_a_fixed_source_is_the_runs_mu_not_a_draw(capsys, tmp_path, source, said):
    """A ``fixed`` friction source gives every draw its value: ``evaluate`` names that mu
    (and its JSON keeps it), as it does a ``--friction``; a source of a distribution is mu
    per draw (no one friction in the JSON)."""
    spec = tmp_path / "noise.yaml"
    spec.write_text(f"joints: {{sigma: 0.01}}\nfriction: {source}\n")
    args = ["evaluate", "--object", "cube", "--noise-spec", str(spec), "--samples", "4",
            "--engine", "fast"]
    assert main(args) == 0
    assert said in capsys.readouterr().out.splitlines()[0]
    assert main([*args, "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record.get("friction") == (0.3 if "fixed" in source else None)
