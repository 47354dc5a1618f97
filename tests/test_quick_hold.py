"""The quick holding test's rules on a scripted object (no simulator: the object's motion in
each phase is given), its lift against the full protocol's, and ``rank --criterion hold``."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from kinegrasp_env.physics.hold_runner import (
    EXIT_MIN_TIME,
    EXIT_RATE_FACTOR,
    projected_verdict,
    run_phases,
)
from kinegrasp_env.physics.motion import peak_lift_acceleration
from kinegrasp_env.physics.protocol import (
    GRAVITY_PHASES,
    QUICK_PROTOCOL,
    HoldProtocol,
    HoldResult,
    final_outcome,
)


class ScriptedObject:
    """The primitives the phases use: the object slides along palm x at ``speeds[phase]``
    m/s (0: at rest) under each phase's gravity, counting the steps run per phase."""

    time_step = 0.001
    center_of_mass = np.zeros(3)

    def __init__(self, speeds: dict[str, float]) -> None:
        self.speeds, self.steps = speeds, {}
        self.phase, self.shift = None, 0.0

    def start_phase(self, gravity: np.ndarray) -> None:
        unit = tuple(np.sign(gravity).astype(float)) if np.any(gravity) else None
        names = {tuple(map(float, d)): n for n, d in GRAVITY_PHASES.items()}
        self.phase = names.get(unit, "rest") if unit != (0.0, 0.0, -1.0) or \
            self.phase != "gravity_-z" else "lift"
        self.shift = 0.0
        self.steps[self.phase] = 0

    def hand_start(self):
        return np.eye(4), np.zeros(3)

    def move_hand(self, position, orientation) -> None:
        pass

    def advance(self, steps: int = 1) -> None:
        self.steps[self.phase] += steps
        self.shift += self.speeds.get(self.phase, 0.0) * self.time_step * steps

    def object_in_palm(self) -> np.ndarray:
        pose = np.eye(4)
        pose[0, 3] = self.shift
        return pose


def phases(protocol: HoldProtocol, speeds: dict[str, float]) -> tuple[HoldResult, dict]:
    sim = ScriptedObject(speeds)
    result = HoldResult(5)
    run_phases(sim, protocol, np.eye(4), result)
    return result, sim.steps


def test_a_still_object_ends_each_phase_early_and_is_held() -> None:
    """At rest the quick test ends every phase without a path two checks after its minimum
    time (the full test runs each to its end); the verdict is the same: held."""
    quick, quick_steps = phases(QUICK_PROTOCOL, {})
    full, full_steps = phases(HoldProtocol(), {})
    assert final_outcome(5, quick.phase_held) == final_outcome(5, full.phase_held) == 5
    interval = QUICK_PROTOCOL.check_interval
    for name, steps in quick_steps.items():
        if name != "lift":
            assert steps * 0.001 == pytest.approx(EXIT_MIN_TIME + interval, abs=1.5e-3)
            assert full_steps[name] == 500


def test_early_exit_stops_at_the_first_failed_phase() -> None:
    """An object sliding off under gravity along +x fails that phase; the quick test runs no
    phase after it (the full test runs them all); both call the draw dropped."""
    speeds = {"gravity_+x": 1.0}
    quick, _ = phases(QUICK_PROTOCOL, speeds)
    full, _ = phases(HoldProtocol(), speeds)
    assert list(quick.phase_held) == ["rest", "gravity_+x"]
    assert not quick.phase_held["gravity_+x"]
    assert len(full.phase_held) == len(HoldProtocol().phases)
    assert final_outcome(5, quick.phase_held) == final_outcome(5, full.phase_held) == 4


class BlownUp(ScriptedObject):
    """A scripted object whose pose turns to NaN in one phase (a simulation that blew up)."""

    def __init__(self, phase: str) -> None:
        super().__init__({})
        self.broken = phase

    def object_in_palm(self) -> np.ndarray:
        pose = super().object_in_palm()
        return np.full((4, 4), np.nan) if self.phase == self.broken else pose


def test_a_blown_up_phase_fails_and_its_margin_is_past_the_limit() -> None:
    """A NaN pose in gravity_+y fails that phase with its movement unknown (NaN), not the
    small movement seen before it; the draw's margin is the phases held before it, 3 of 8 in
    a row (rest, gravity_+x, gravity_-x), over 9: nothing for the movement."""
    from kinegrasp_env.montecarlo.hold_batch import HoldBatch
    from kinegrasp_env.physics.protocol import hold_margin

    result = HoldResult(5)
    run_phases(BlownUp("gravity_+y"), QUICK_PROTOCOL, np.eye(4), result)
    assert not result.phase_held["gravity_+y"]
    assert math.isnan(result.phase_shift["gravity_+y"])
    batch = HoldBatch.empty(1)
    batch.record(0, result)
    margin = hold_margin(batch.phase_held, batch.phase_shift, batch.phase_turn,
                         QUICK_PROTOCOL)
    assert margin[0] == pytest.approx(3 / 9, abs=1e-12)


def test_a_creeping_object_is_watched_to_the_end() -> None:
    """Hand derivation: an object creeping at v with 0.5 s to go is projected to
    v x EXIT_RATE_FACTOR x 0.5 further; at 30 mm/s that leaves the 20 mm criterion, so the
    phase does not end early; at 1 mm/s it does."""
    protocol = QUICK_PROTOCOL
    step = protocol.check_interval
    creeping = projected_verdict(protocol, (0.03 * 0.1, 0.0), (0.03 * (0.1 - step), 0.0), step,
                                 0.1, 0.5)
    assert 0.03 * EXIT_RATE_FACTOR * 0.5 > protocol.max_shift and creeping is None
    slow = projected_verdict(protocol, (0.001 * 0.1, 0.0), (0.001 * (0.1 - step), 0.0), step,
                             0.1, 0.5)
    assert slow is True
    assert projected_verdict(protocol, (0.0, 0.0), (0.0, 0.0), step, 0.5 * EXIT_MIN_TIME,
                             0.5) is None


def test_quick_lift_has_the_full_lifts_peak_acceleration() -> None:
    """The quick lift is shorter and lower but as hard on the grip: the same peak
    acceleration (minimum jerk: 10 h / (sqrt 3 T^2)), to 1e-5."""
    full = peak_lift_acceleration(HoldProtocol())
    assert peak_lift_acceleration(QUICK_PROTOCOL) == pytest.approx(full, rel=1e-5)
    assert full == pytest.approx(10 * 0.1 / math.sqrt(3), rel=1e-5)


def test_early_exit_is_part_of_the_protocols_value() -> None:
    """Result caches hash the protocol: the quick one differs from the full one."""
    assert replace(QUICK_PROTOCOL, early_exit=False) != QUICK_PROTOCOL
    assert HoldProtocol().early_exit is False


def rank_panda_cubes(capsys, tmp_path, criterion: str) -> tuple[str, list[dict]]:
    """``rank`` of the panda's shipped cube grasps at sigma 0.0033 rad, 3 draws each, fast
    engine, by ``criterion``: (its stdout, the CSV's rows)."""
    import csv

    from cli_helpers import run_in_process

    from kinegrasp_env.world.grasps import shipped_grasp_file

    out = tmp_path / "ranked.csv"
    text = run_in_process(capsys, "rank", str(shipped_grasp_file("cube", robot="panda")),
                          "--sigma", "0.0033", "--samples", "3", "--engine", "fast",
                          "--criterion", criterion, "--out", str(out))
    return text, list(csv.DictReader(out.open()))


def test_rank_by_the_holding_test(tmp_path, capsys) -> None:
    """``rank --criterion hold`` of the panda's shipped cube grasps names its score, writes
    the P(hold) columns, and orders the candidates by them."""
    text, rows = rank_panda_cubes(capsys, tmp_path, "hold")
    assert "P(hold): the quick holding test in pybullet" in text
    assert len(rows) == 4
    held = [float(r["p_hold"]) for r in rows]
    assert held == sorted(held, reverse=True)
    assert all(float(r["p_hold_lo"]) <= h <= float(r["p_hold_hi"]) for r, h in zip(rows, held,
                                                                                     strict=True))


def test_rank_by_the_holding_tests_margin(tmp_path, capsys) -> None:
    """``rank --criterion hold_margin`` of the panda's cube grasps: candidates in descending
    mean margin; each mean inside what its P(hold) allows (held draws score in [8/9, 1],
    the others in [0, 8/9]); the first's mean that of the quick test run again on its draws
    (chunk 0 of seed 0); the output names the score. ``--adaptive`` refuses it in one line."""
    from kinegrasp_env.montecarlo.hold_engine import quick_hold_engine
    from kinegrasp_env.world.grasps import shipped_grasp_file, shipped_grasps

    text, rows = rank_panda_cubes(capsys, tmp_path, "hold_margin")
    assert "margin: the mean over the draws of how far each got through it" in text
    margin = [float(r["hold_margin"]) for r in rows]
    assert margin == sorted(margin, reverse=True) and len(set(margin)) > 1
    floor = len(QUICK_PROTOCOL.phases) / (len(QUICK_PROTOCOL.phases) + 1)
    for r, m in zip(rows, margin, strict=True):
        held = float(r["p_hold"])
        assert floor * held - 1e-9 <= m <= floor * (1 - held) + held + 1e-9
    first = {g.id: g for g in shipped_grasps("cube", robot="panda")}[rows[0]["id"]]
    rng = np.random.default_rng(np.random.SeedSequence(0, spawn_key=(0,)))
    q = np.repeat(np.asarray(first.q0)[None], 3, axis=0)
    q[:, :7] += rng.normal(0.0, 0.0033, (3, 7))
    with quick_hold_engine("panda", "cube") as test:
        again = test.run_hold(q)[1].margin(QUICK_PROTOCOL).mean()
    assert margin[0] == pytest.approx(again, rel=1e-5)
    import kinegrasp_env.cli.ranking as ranking
    from kinegrasp_env.cli import main

    def no_work(*args, **kwargs):
        raise AssertionError("the candidates were read before the refusal")

    capsys.readouterr()
    real, ranking._candidates = ranking._candidates, no_work
    try:
        status = main(["rank", str(shipped_grasp_file("cube", robot="panda")), "--criterion",
                       "hold_margin", "--adaptive", "--out", str(tmp_path / "adaptive.csv")])
    finally:
        ranking._candidates = real
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["kinegrasp rank: error: --criterion hold_margin ranks by a mean, "
                   "which --adaptive cannot certify (its tests count the draws that succeed); "
                   "use --criterion pfc, pfc_lcb, hold_static or hold with --adaptive, or "
                   "hold_margin without it"]
    assert not (tmp_path / "adaptive.csv").exists()


def test_the_default_robot_ranks_by_the_quick_holding_test(capsys, tmp_path) -> None:
    """``rank --criterion hold`` of the default robot's cube grasps: the CSV's P(hold) is the
    quick holding test's share of each candidate's draws (on the draws' configurations), in
    descending order; the output names it."""
    import csv

    from cli_helpers import run_in_process

    from kinegrasp_env.montecarlo.hold_engine import quick_hold_engine
    from kinegrasp_env.physics.protocol import HELD
    from kinegrasp_env.world.grasps import shipped_grasp_file, shipped_grasps

    out = tmp_path / "ranked.csv"
    text = run_in_process(capsys, "rank", str(shipped_grasp_file("cube")), "--sigma", "0.0033",
                          "--samples", "2", "--engine", "fast", "--criterion", "hold",
                          "--out", str(out))
    assert "P(hold): the quick holding test in pybullet" in text
    rows = list(csv.DictReader(out.open()))
    held = [float(r["p_hold"]) for r in rows]
    assert held == sorted(held, reverse=True) and 0.0 < np.mean(held) < 1.0
    grasps = {g.id: g for g in shipped_grasps("cube")}
    first = grasps[rows[0]["id"]]
    rng = np.random.default_rng(np.random.SeedSequence(0, spawn_key=(0,)))
    q = np.repeat(np.asarray(first.q0)[None], 2, axis=0)  # its draws: chunk 0 of seed 0
    q[:, :7] += rng.normal(0.0, 0.0033, (2, 7))
    with quick_hold_engine("kuka_sdh", "cube") as test:
        again = test.run_hold(q)[1].outcome == HELD
    assert held[0] == again.mean()


def test_evaluate_reports_both_hold_scores(capsys) -> None:
    """``evaluate --static-hold --hold-test --json`` of a panda grasp: P(hold) of the quick
    test with its Wilson interval and its mean margin (within what P(hold) allows: held draws
    score in [8/9, 1], the others in [0, 8/9]), P(hold, static), and the mass it used: the
    cube's 500 kg/m^3 times its volume (a 6 cm cube: 0.108 kg, by hand)."""
    import json

    from cli_helpers import run_in_process

    out = run_in_process(capsys, "evaluate", "--robot", "panda", "--object", "cube", "--grasp",
                         "0", "--sigma", "0.0033", "--samples", "3", "--engine", "fast",
                         "--static-hold", "--hold-test", "--json")
    record = json.loads(out)
    assert record["mass_kg"] == pytest.approx(500 * 0.06 ** 3, rel=1e-9)
    floor = len(QUICK_PROTOCOL.phases) / (len(QUICK_PROTOCOL.phases) + 1)  # held draws: above
    held = record["p_hold"]
    assert floor * held - 1e-9 <= record["hold_margin"] <= floor * (1 - held) + held + 1e-9
    for key in ("p_hold", "p_hold_static"):
        lo, hi = record[f"{key}_ci"]
        assert 0.0 <= lo <= record[key] <= hi <= 1.0
        assert record[key] * 3 == pytest.approx(round(record[key] * 3))


def test_the_holding_test_runs_in_mujoco_when_asked(capsys) -> None:
    """``evaluate --hold-test --hold-simulator mujoco`` names MuJoCo, and holds the Panda's
    nominal cube grasp 0, as pybullet's holding test does (two simulators, one verdict)."""
    pytest.importorskip("mujoco")
    from cli_helpers import run_in_process

    text = run_in_process(capsys, "evaluate", "--robot", "panda", "--object", "cube",
                          "--grasp", "0", "--sigma", "0", "--samples", "2", "--engine", "fast",
                          "--hold-test", "--hold-simulator", "mujoco")
    assert "the quick holding test in mujoco on the same draws" in text
    assert "P(hold) = 1.0000" in text


@pytest.mark.parametrize(("argv", "needle"), [
    (["evaluate", "--robot", "panda", "--object", "cube", "--samples", "2", "--hold-simulator",
      "mujoco"], "--hold-simulator mujoco is the holding test's simulator; it runs with "
                 "--hold-test"),
    (["evaluate", "--object", "cube", "--samples", "2", "--hold-simulator", "mujoco"],
     "--hold-simulator mujoco is the holding test's simulator; it runs with --hold-test")])
def test_a_hold_simulator_without_a_holding_test_is_one_line(capsys, argv, needle) -> None:
    from kinegrasp_env.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1


def test_a_ranking_log_keeps_each_candidates_margins() -> None:
    """A resumed ranking reads each finished candidate's margins back from its log line (sum
    and count: the mean of 0.95, 0.2 and 0.5 by hand); a line without them reads as none."""
    import json

    from kinegrasp_env.cli.resume import result_from_json, result_to_json
    from kinegrasp_env.toolkit.ranking import CandidateResult

    result = CandidateResult(2, 3, 4, 1)
    result.add_margins(np.array([0.95, 0.2, 0.5]))
    line = json.loads(json.dumps(result_to_json(result)))
    back = result_from_json(line)
    assert back.margins == result.margins
    assert back.hold_margin() == pytest.approx(1.65 / 3, rel=1e-12)
    del line["margins"]
    assert math.isnan(result_from_json(line).hold_margin())


@pytest.mark.parametrize("criterion", ["hold_margin", "q_mean", "weighted"])
def test_the_adaptive_ranking_refuses_a_mean_criterion(criterion) -> None:
    """The library's adaptive run refuses a criterion that is a mean, not a count of
    successes (its certificates would be of P(FC), not of what was asked), in one line."""
    from kinegrasp_env.toolkit.adaptive_ranking import rank_adaptive

    with pytest.raises(ValueError, match=f"criterion '{criterion}' ranks by a mean"):
        rank_adaptive(3, lambda *args: None, 2, 10, top_k=1, criterion=criterion)


def test_a_ranking_log_without_margins_is_not_resumed_under_the_holding_test(tmp_path) -> None:
    """A log of the holding test written without each candidate's margins (an older
    kinegrasp) is refused, naming them, rather than resumed with the margins missing."""
    from kinegrasp_env.cli.common import CLIError
    from kinegrasp_env.cli.resume import check_settings

    stored = {"hold_simulator": "pybullet", "criterion_scores": [False, True]}
    with pytest.raises(CLIError, match="the holding test's margins"):
        check_settings(tmp_path / "r.partial.jsonl", stored,
                       {**stored, "hold_margins": True})


def test_a_ranking_log_of_another_physics_model_is_not_resumed(tmp_path) -> None:
    """A log whose physics results an older kinegrasp's physics made (it records no physics
    model) is refused, naming it, under the physics engine or the holding test; a kinematic
    ranking records none and resumes."""
    from kinegrasp_env.cli.common import CLIError
    from kinegrasp_env.cli.resume import check_settings
    from kinegrasp_env.physics.simulators import PHYSICS_MODEL

    stored = {"engine": "physics"}
    with pytest.raises(CLIError, match="the physics simulated"):
        check_settings(tmp_path / "r.partial.jsonl", stored,
                       {**stored, "physics_model": PHYSICS_MODEL})
    check_settings(tmp_path / "r.partial.jsonl", {"engine": "fast"}, {"engine": "fast"})
