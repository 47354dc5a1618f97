"""``plan --robot`` with ``--variants``, ``--max-attempts`` and ``--time-budget``.

What each test proves: every variant is the planned grasp's palm pose reached with another
arm configuration (forward kinematics of its q0, an independent computation, to 1e-8 m/rad)
at another elbow angle, in force closure at its nominal closing; a spent time budget closes
no candidate (a one-line error, nothing written); a plan's tally accounts for every palm pose
it drew, and an object placed beyond any arm's reach (3 m from the base: the iiwa's links
add up to 1.3 m) is named as out of reach, with its distance.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.cli import main
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.world.grasps import load_grasps


def test_variants_keep_the_palm_and_move_the_elbow(tmp_path, capsys):
    out = tmp_path / "g.json"
    assert main(["plan", "--robot", "panda", "--object", "cube", "--count", "2", "--variants",
                 "3", "--max-attempts", "80", "--out", str(out)]) == 0
    assert "null-space variants) of cube for robot panda" in capsys.readouterr().out
    grasps = {g.id: g for g in load_grasps(out)}
    planned = [g for g in grasps.values() if "variant_of" not in g.meta]
    variants = [g for g in grasps.values() if "variant_of" in g.meta]
    assert len(planned) == 2 and len(variants) >= 2
    description = load_robot("panda")
    kinematics = Kinematics(description.model)
    for v in variants:
        source = grasps[v.meta["variant_of"]]
        palm = kinematics.pose(np.asarray(v.q0)[None], description.palm_link)[0]
        np.testing.assert_allclose(palm, source.palm_pose, atol=1e-8)
        assert v.q_nominal > 0 and v.robot == "panda"
    angles = [v.meta["elbow_angle"] for v in variants if v.meta["variant_of"] == "0"]
    assert len(set(np.round(angles, 6))) == len(angles)


def test_a_spent_time_budget_plans_nothing(tmp_path, capsys):
    out = tmp_path / "g.json"
    assert main(["plan", "--robot", "panda", "--object", "cube", "--time-budget", "1e-9",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no force-closure grasp of cube" in err[0] and not out.exists()


def test_the_tally_accounts_for_every_palm_pose():
    """With more grasps asked than the palm poses can give, no pose is left unchecked: the
    poses drawn are those dropped (by reason) and those kept, and the kept ones are the
    grasps returned."""
    from kinegrasp_env.toolkit.grasp_planner import plan_grasps
    from kinegrasp_env.toolkit.plan_checks import PlannerSettings, PlanTally

    for robot in ("panda", "kuka_sdh"):  # the antipodal and the approach planner
        tally = PlanTally()
        grasps = plan_grasps(robot, "cube", count=100, seed=3,
                             settings=PlannerSettings(attempts=40), tally=tally)
        assert tally.drawn == 40 and tally.kept == len(grasps) > 0, tally
        assert sum(tally.dropped.values()) + tally.kept == tally.drawn, tally


def test_an_object_out_of_reach_is_named(tmp_path, monkeypatch, capsys):
    """The cube placed 3 m from the robot's base (its centre of mass 3 cm above its base: 3.00
    m away): every palm pose is out of reach, and the refusal says so and how far."""
    monkeypatch.setenv("KINEGRASP_HOME", str(tmp_path / "home"))
    assert main(["objects", "place", "cube", "--as", "far", "--position", "3", "0", "0"]) == 0
    capsys.readouterr()
    out = tmp_path / "g.json"
    assert main(["plan", "--object", "far", "--count", "1", "--max-attempts", "20",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("kinegrasp plan: error: no force-closure grasp of far found for robot "
                   "kuka_sdh (20 palm poses: 20 out of reach): far stands 3.00 m from the "
                   "robot's base; place it within reach (`kinegrasp objects place`); nothing "
                   "written"), err
    assert not out.exists()


def test_the_reach_note_needs_every_pose_the_arm_was_asked_for_out_of_reach():
    """The note names the object's distance only where every pose the IK was asked for (the
    poses not facing up) was out of reach: not where every pose faced up, nor where some
    were reached; and poses left unchecked are counted as not tried."""
    from collections import Counter

    from kinegrasp_env.cli.toolkit import _reach_note
    from kinegrasp_env.toolkit.plan_checks import PlanTally

    assert _reach_note(PlanTally(20, Counter({"facing up": 20})), "cube") == ""
    # one pose out of reach (--max-attempts 1) says nothing of where the object stands
    assert _reach_note(PlanTally(1, Counter({"out of reach": 1})), "cube") == ""
    assert PlanTally(1, Counter({"out of reach": 1})).summary() == "1 palm pose: 1 out of reach"
    assert _reach_note(PlanTally(20, Counter({"facing up": 5, "out of reach": 14})),
                       "cube") == ""
    assert "cube stands 0." in _reach_note(
        PlanTally(25, Counter({"facing up": 5, "out of reach": 20})), "cube")
    summary = PlanTally(20, Counter({"facing up": 5, "out of reach": 3}), 1).summary()
    assert summary == "20 palm poses: 5 facing up, 3 out of reach, 1 kept, 11 not tried"
