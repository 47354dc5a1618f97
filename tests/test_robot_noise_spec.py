"""Every source of a noise spec for a description robot (the Panda): joints, hand, palm,
object, friction.

What each test proves:

* a palm error that turns the hand about the flange's z axis is what the arm's last joint
  does (the Panda's joint 7 turns its link about that axis through its origin): the palm
  error's draws equal those of the joint moved, contacts to 1e-9 m, in the fast engine and
  in the reference (pybullet) engine. The kinematics is an independent computation of the
  hand's pose, so a palm error composed on the wrong side, or in the wrong frame, fails
  (the reference's contacts to 5e-8 m: pybullet's closest points on the body it turned);
* an object error is the object placed elsewhere: the fast engine's draws with the error
  equal the reference engine's on a world built with the object loaded at its true pose
  (pybullet's own placement, no error path), contacts to 1e-6 m (the two closings' steps
  differ once the object is turned: 5e-6 m measured at most, within the 2e-4 m contact
  tolerance), outcomes equal;
* the reference engine (which moves the object body in pybullet) and the fast engine (which
  maps the links) agree on noisy draws of every source at once;
* a joints-only spec draws what ``--sigma`` draws; a fixed friction source scores as
  ``--friction`` does; a run on two worker processes draws the run's rows;
* the hand source: the Panda's one finger motor takes one offset, within its limits, and
  adding the source leaves the arm's draws as they were (the SDH's layout, hard-coded, is
  checked in test_noise_model.py and test_draw_streams.py);
* what a robot cannot take is one line each.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from kinegrasp_env.cli import main
from kinegrasp_env.closing.generic_fast import FastRobotHand
from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.montecarlo import chunks
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.sampling.noise_model import offset_transforms
from kinegrasp_env.sampling.noise_spec import noise_model_from_spec
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import load_object

EVERY_SOURCE = {"joints": {"sigma": 0.005},
                "palm": {"translation_sigma": 0.003, "rotation_sigma": 0.02},
                "object": {"translation_sigma": 0.004, "rotation_sigma": 0.03},
                "friction": {"distribution": "gaussian", "mean": 0.5, "sigma": 0.1}}


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda"), load_object("cube"), shipped_grasps("cube", "panda")[0]


def _contacts(batch, row):
    return batch.points[batch.row == row]


def test_a_palm_turn_about_the_flange_axis_is_the_last_joint_turned(panda):
    description, obj, grasp = panda
    angles = np.linspace(-0.06, 0.06, 7)
    q = np.repeat(np.asarray(grasp.q0)[None], len(angles), axis=0)
    turned = q.copy()
    turned[:, description.arm_joints.index("panda_joint7")] += angles
    palm = offset_transforms(np.column_stack([np.zeros((len(angles), 5)), angles]))
    fast = FastRobotHand(description, obj)
    by_palm, by_joint = fast.close_batch(q, palm=palm), fast.close_batch(turned)
    np.testing.assert_array_equal(by_palm.start_collision, by_joint.start_collision)
    np.testing.assert_array_equal(by_palm.missed, by_joint.missed)
    np.testing.assert_allclose(by_palm.points, by_joint.points, atol=1e-9)
    with RobotWorld(description, obj) as world:
        for i in range(len(angles)):
            a = world.auto_close(q[i], palm=palm[i])
            b = world.auto_close(turned[i])
            assert a.missed == b.missed and len(a.contacts) == len(b.contacts)
            for ca, cb in zip(a.contacts, b.contacts, strict=True):
                # pybullet's closest points on the object body it turned: 7e-9 m measured
                np.testing.assert_allclose(ca.point, cb.point, atol=5e-8)
    assert by_palm.contact_counts.min() == 2  # every draw closes on the cube


def test_an_object_error_is_the_object_placed_at_its_true_pose(panda):
    description, obj, grasp = panda
    rng = np.random.default_rng(5)
    offsets = offset_transforms(np.hstack([rng.normal(size=(6, 3)) * 0.004,
                                           rng.normal(size=(6, 3)) * 0.03]),
                                obj.center_of_mass)
    q = np.repeat(np.asarray(grasp.q0)[None], len(offsets), axis=0)
    batch = FastRobotHand(description, obj).close_batch(q, object_offset=offsets)
    for i, offset in enumerate(offsets):
        placed = dataclasses.replace(obj, pose=obj.pose @ offset)
        with RobotWorld(description, placed) as world:
            result = world.auto_close(q[i])
        assert bool(batch.start_collision[i]) == result.start_collision
        assert tuple(batch.missed[i]) == result.missed
        points = np.array([c.point for c in result.contacts]).reshape(-1, 3)
        np.testing.assert_allclose(_contacts(batch, i), points, atol=1e-6)


def test_the_engines_agree_on_every_source(panda):
    _, _, grasp = panda
    model = noise_model_from_spec(EVERY_SOURCE)
    fast = evaluate_grasp(grasp, n=200, seed=4, engine="fast",
                          noise_model=model)
    reference = evaluate_grasp(grasp, n=200, seed=4, engine="pybullet",
                               noise_model=model)
    same = fast.draws.outcome == reference.draws.outcome
    assert same.mean() >= 0.99, same.mean()  # 200 of 200 measured
    assert fast.counts["start_collision"] > 0 and fast.counts["force_closure"] > 0
    # the source changes the draws: without palm and object errors P(FC) differs
    joints = noise_model_from_spec({"joints": EVERY_SOURCE["joints"]})
    alone = evaluate_grasp(grasp, n=200, seed=4, engine="fast",
                           noise_model=joints)
    assert alone.counts != fast.counts


def test_joints_and_friction_specs_draw_what_the_options_draw(panda):
    _, _, grasp = panda
    options = dict(n=150, seed=2, engine="fast")
    plain = evaluate_grasp(grasp, sigma=0.0133, friction=0.3, **options)
    spec = noise_model_from_spec({"joints": {"sigma": 0.0133},
                                  "friction": {"distribution": "fixed", "value": 0.3}})
    specified = evaluate_grasp(grasp, noise_model=spec, **options)
    assert plain.counts == specified.counts
    np.testing.assert_array_equal(plain.draws.quality, specified.draws.quality)
    model = noise_model_from_spec(EVERY_SOURCE)
    inline = evaluate_grasp(grasp, noise_model=model, **options)
    with LocalExecutor(2) as executor:
        pooled = evaluate_grasp(grasp, noise_model=model, executor=executor,
                                **options)
    chunks.close_engines()
    np.testing.assert_array_equal(inline.draws.quality, pooled.draws.quality)
    np.testing.assert_array_equal(inline.draws.points, pooled.draws.points)


def test_the_cli_takes_a_spec_and_refuses_what_a_robot_cannot(tmp_path, capsys):
    spec = tmp_path / "every.json"
    spec.write_text(json.dumps(EVERY_SOURCE))
    args = ["evaluate", "--robot", "panda", "--object", "cube", "--samples", "60",
            "--engine", "fast", "--seed", "4"]
    assert main([*args, "--noise-spec", str(spec), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["noise_spec"] == str(spec) and sum(shown["outcomes"].values()) == 60
    assert main([*args, "--noise-spec", str(spec)]) == 0
    text = capsys.readouterr().out
    assert f"noise spec {spec}, 60 draws" in text and "mu per draw" in text
    hand = tmp_path / "hand.yaml"
    hand.write_text("hand: {spread_sigma: 0.01}\n")
    three = tmp_path / "three.yaml"
    three.write_text("hand: {closing_sigma: [0.001, 0.002, 0.003]}\n")
    cases = [([*args, "--noise-spec", str(hand)], "drop hand.spread_sigma"),
             ([*args, "--noise-spec", str(three)], "robot 'panda' has 2 fingers"),
             ([*args, "--noise-spec", str(spec), "--static-hold"], "holds at one mu"),
             ([*args, "--noise-spec", str(spec), "--hold-test"],
              "takes joint and hand noise only"),
             ([*args[:-4], "--engine", "physics", "--noise-spec", str(spec)],
              "physics engine")]
    for command, words in cases:
        assert main(command) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], (command, err)
    # one closing sigma per finger of the robot: two for the Panda's two fingers; four for
    # the default robot's three refused naming its fingers in the order the values take
    # (the parser took one or three values alone, then the robot check asked for one)
    two = tmp_path / "two.yaml"
    two.write_text("hand: {closing_sigma: [0.001, 0.002]}\n")
    assert main([*args, "--noise-spec", str(two)]) == 0
    capsys.readouterr()
    four = tmp_path / "four.yaml"
    four.write_text("hand: {closing_sigma: [0.001, 0.002, 0.003, 0.004]}\n")
    assert main([*args[:2], "kuka_sdh", *args[3:], "--noise-spec", str(four)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "robot 'kuka_sdh' has 3 fingers (" in err[0] and \
        "one per finger in that order" in err[0], err


def test_a_robot_sweep_cell_of_a_noise_model_is_its_evaluation(tmp_path, capsys):
    """A sweep cell of a noise model is ``evaluate_grasp`` with that model and the
    cell's sigma as its joints' (the sweep's chunks are rows of the same streams)."""
    import csv

    spec = tmp_path / "sweep.yaml"
    model = {k: v for k, v in EVERY_SOURCE.items() if k != "joints"}
    spec.write_text(json.dumps({"objects": ["cube"], "grasps": [0], "sigmas": [0.01],
                                "engines": ["fast"], "samples": 120, "chunk": 50,
                                "seed": 3, "robot": "panda", "noise": [model]}))
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 0
    capsys.readouterr()
    chunks.close_engines()
    row = next(csv.DictReader((tmp_path / "out" / "summary.csv").open()))
    expected = evaluate_grasp(
        shipped_grasps("cube", "panda")[0], n=120, seed=3, engine="fast",
        noise_model=noise_model_from_spec({**model, "joints": {"sigma": 0.01}}))
    assert int(row["force_closure"]) == expected.counts["force_closure"]
    assert int(row["start_collision"]) == expected.counts["start_collision"]


def test_report_of_a_robot_takes_a_spec_and_processes(tmp_path, capsys):
    """``report --robot --noise-spec FILE --processes 2``: each grasp's run is evaluate's
    with the same spec and seed (the chunks on two workers draw the run's rows)."""
    spec = tmp_path / "every.json"
    spec.write_text(json.dumps(EVERY_SOURCE))
    assert main(["report", "--robot", "panda", "--object", "cube", "--grasp", "0,1",
                 "--noise-spec", str(spec), "--samples", "60", "--engine", "fast",
                 "--processes", "2", "--out", str(tmp_path / "r.html"), "--json"]) == 0
    runs = json.loads(capsys.readouterr().out)["runs"]
    chunks.close_engines()
    for index, run in enumerate(runs):
        assert main(["evaluate", "--robot", "panda", "--object", "cube", "--grasp", str(index),
                     "--noise-spec", str(spec), "--samples", "60", "--engine", "fast",
                     "--json"]) == 0
        shown = json.loads(capsys.readouterr().out)
        assert run["p_fc"] == shown["p_fc"] and run["outcomes"] == shown["outcomes"]


def test_the_pandas_one_finger_motor_takes_one_offset_within_its_limits(panda):
    from kinegrasp_env.montecarlo.noise_rows import hand_layout, model_rows

    description, obj, grasp = panda
    assert hand_layout(description).tolist() == [0]  # one motor, finger 0's offset
    joints = noise_model_from_spec({"joints": {"sigma": 0.01}})
    both = noise_model_from_spec({"joints": {"sigma": 0.01}, "hand": {"closing_sigma": 0.004}})
    q, _ = model_rows(both, grasp.q0, description, 5, 0, 500, obj.center_of_mass)
    alone, _ = model_rows(joints, grasp.q0, description, 5, 0, 500, obj.center_of_mass)
    np.testing.assert_array_equal(q[:, :7], alone[:, :7])
    hand = q[:, 7]
    assert np.all(hand <= description.model.upper[7]) and np.all(hand >= 0)
    assert (hand < grasp.q0[7] - 1e-4).mean() > 0.4  # about half start narrower


def test_the_holding_test_takes_a_joints_and_hand_spec(tmp_path, capsys):
    """``evaluate --hold-test`` of the Panda with a noise spec: a joints-only spec holds the
    draws ``--sigma`` holds (the same rows, through the model's path); a hand source is taken
    too (its draws' pre-shapes)."""
    joints, hand = tmp_path / "joints.yaml", tmp_path / "hand.yaml"
    joints.write_text("joints: {sigma: 0.02}\n")
    hand.write_text("joints: {sigma: 0.02}\nhand: {closing_sigma: 0.01}\n")
    args = ["evaluate", "--robot", "panda", "--object", "cube", "--grasp", "1", "--samples",
            "6", "--seed", "3", "--engine", "fast", "--hold-test", "--json"]
    shown = []
    for extra in (["--sigma", "0.02"], ["--noise-spec", str(joints)],
                  ["--noise-spec", str(hand)]):
        assert main([*args, *extra]) == 0
        shown.append(json.loads(capsys.readouterr().out))
    assert shown[0]["p_hold"] == shown[1]["p_hold"]
    assert shown[0]["outcomes"] == shown[1]["outcomes"]
    assert 0.0 <= shown[2]["p_hold"] <= 1.0


def test_a_hand_source_is_checked_against_the_description_given(panda):
    """A description outside the catalog (the Panda renamed) is checked as given, not looked
    up by its name: a closing sigma passes, a spread sigma is refused naming it."""
    from kinegrasp_env.montecarlo.noise_rows import check_robot_noise

    description = dataclasses.replace(panda[0], name="mypanda")
    check_robot_noise(noise_model_from_spec({"hand": {"closing_sigma": 0.002}}), description,
                      7, "fast")
    with pytest.raises(ValueError, match="the hand of robot 'mypanda' has no pre-shape joint"):
        check_robot_noise(noise_model_from_spec({"hand": {"spread_sigma": 0.01}}),
                          description, 7, "fast")


def test_a_six_joint_arms_joint_spec_draws_its_covariance_and_bias():
    """A joints source of six per-joint values (covariance and bias) drawn for an arm of six
    joints (``joint_rows``, what every engine of such a robot adds to its arm): the rows'
    sample mean and covariance match the spec's (20,000 rows; tolerances at about 5 standard
    errors: 5 sigma / sqrt(n) for a mean, 5 sqrt(2 / n) times the variance scale for a
    covariance entry); per-joint sigmas give per-column standard deviations; seven values
    for a six-joint arm are refused in one line naming both counts."""
    from kinegrasp_env.montecarlo.noise_rows import check_robot_noise, joint_rows
    from kinegrasp_env.sampling.noise_spec import noise_model_from_spec

    rng = np.random.default_rng(3)
    factor = rng.normal(0.0, 0.01, (6, 6))
    cov = factor @ factor.T + np.diag(np.full(6, 1e-5))
    bias = [0.01, -0.02, 0.0, 0.005, 0.03, -0.01]
    model = noise_model_from_spec({"joints": {"covariance": cov.tolist(), "bias": bias}})
    n = 20_000
    rows = joint_rows(model, 6, seed=7, offset=0, size=n)
    assert rows.shape == (n, 6)
    scale = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(rows.mean(axis=0), bias, rtol=0, atol=5 * scale.max() / np.sqrt(n))
    np.testing.assert_allclose(np.cov(rows.T), cov, rtol=0,
                               atol=5 * np.sqrt(2.0 / n) * scale.max() ** 2)
    sigmas = [0.001, 0.002, 0.004, 0.008, 0.016, 0.032]
    independent = noise_model_from_spec({"joints": {"sigma": sigmas,
                                                    "distribution": "uniform"}})
    spread = joint_rows(independent, 6, seed=7, offset=0, size=n).std(axis=0)
    np.testing.assert_allclose(spread, sigmas, rtol=5 * np.sqrt(0.2 / n))  # uniform: kurtosis 1.8
    seven = noise_model_from_spec({"joints": {"sigma": [0.01] * 7}})
    with pytest.raises(ValueError, match="has 6 arm joints; the spec's joints describe 7") as e:
        check_robot_noise(seven, "six_joint_arm", 6, "fast")
    assert "\n" not in str(e.value)
    check_robot_noise(independent, "six_joint_arm", 6, "fast")  # six values: taken


def test_the_library_refuses_other_closing_sigmas_before_any_chunk():
    """``evaluate_grasp`` checks a hand source's closing sigmas against the default robot's
    three fingers before any chunk runs (on two worker processes): two sigmas were refused
    only inside the chunk workers, after the pool had started."""
    model = noise_model_from_spec({"joints": {"sigma": 0.01},
                                   "hand": {"closing_sigma": [0.01, 0.02]}})
    with LocalExecutor(2) as executor:
        with pytest.raises(ValueError, match="robot 'kuka_sdh' has 3 fingers") as info:
            evaluate_grasp(shipped_grasps("cube")[0], noise_model=model, n=8,
                           engine="fast", executor=executor)
        assert executor._pool is None  # no worker process was started
    assert "\n" not in str(info.value)
