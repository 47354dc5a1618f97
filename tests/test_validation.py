"""``kinegrasp validate``: its statistics against scipy and hand counts, the holding test's
phase and outcome counts against hand counts, its cache, the same seed giving the same table
twice, the CLI's one-line errors (simulator and torque scale included), and the physics
engine's registration."""

from __future__ import annotations

import csv
import warnings

import numpy as np
import pytest
from scipy import stats

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, MISSED, NO_FORCE_CLOSURE
from kinegrasp_env.physics import simulators
from kinegrasp_env.physics.protocol import DROPPED, GRIP_LOST, HELD, NO_GRIP, PHASES
from kinegrasp_env.toolkit import validation
from kinegrasp_env.toolkit.validation import GraspDraws, ValidationSettings, run_validation
from kinegrasp_env.toolkit.validation_report import summarize, write_results
from kinegrasp_env.toolkit.validation_stats import (
    average_ranks,
    bootstrap_spearman,
    confusion,
    spearman,
)
from kinegrasp_env.world.grasps import shipped_grasps
from tests.cli_helpers import run_cli


def synthetic_columns(seed: int, n: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Two correlated columns of probabilities on a grid of 1/20 (many ties, like P(FC))."""
    rng = np.random.default_rng(seed)
    x = np.round(rng.uniform(size=n) * 20) / 20
    y = np.clip(np.round((x + rng.normal(0, 0.3, n)) * 20) / 20, 0, 1)
    return x, y


@pytest.mark.parametrize("seed", range(5))
def test_ranks_and_spearman_match_scipy(seed):
    x, y = synthetic_columns(seed)
    np.testing.assert_array_equal(average_ranks(x), stats.rankdata(x))
    assert spearman(x, y) == pytest.approx(stats.spearmanr(x, y).statistic, abs=1e-12)


def test_spearman_of_a_constant_column_is_nan():
    assert np.isnan(spearman(np.ones(5), np.arange(5.0)))
    assert np.isnan(spearman(np.array([1.0]), np.array([2.0])))


def test_bootstrap_matches_an_independent_resampling_with_scipy():
    """Same resamples (the same generator draws), scipy's rho on each, numpy's quantiles."""
    x, y = synthetic_columns(7, n=25)
    result = bootstrap_spearman(x, y, seed=3, resamples=300)
    picks = np.random.default_rng(3).integers(0, x.size, size=(300, x.size))
    with warnings.catch_warnings():  # scipy warns on a constant resample (rho NaN)
        warnings.simplefilter("ignore")
        rhos = np.array([stats.spearmanr(x[p], y[p]).statistic for p in picks])
    finite = rhos[np.isfinite(rhos)]
    lo, hi = np.quantile(finite, [0.025, 0.975])
    assert result.rho == pytest.approx(stats.spearmanr(x, y).statistic, abs=1e-12)
    assert result.ci == pytest.approx((lo, hi), abs=1e-12)
    assert result.undefined == rhos.size - finite.size and result.n == 25
    again = bootstrap_spearman(x, y, seed=3, resamples=300)
    assert again.ci == result.ci  # same seed, same interval
    assert bootstrap_spearman(x, y, seed=4, resamples=300).ci != result.ci


def test_no_interval_from_too_few_grasps():
    """Four grasps have 35 distinct resamples, 4 of them constant: a percentile interval
    of them is no interval. Below MIN_INTERVAL_GRASPS (5) there is none (NaN, no resample
    drawn); rho is still given. Two grasps gave [1, 1] before."""
    from kinegrasp_env.toolkit.validation_stats import MIN_INTERVAL_GRASPS

    assert MIN_INTERVAL_GRASPS == 5
    for n in (2, 4):
        x, y = synthetic_columns(1, n=n)
        result = bootstrap_spearman(x, y, seed=0, resamples=100)
        assert np.isnan(result.ci).all() and result.n == n
        assert (result.resamples, result.undefined) == (0, 0)  # none drawn
        assert result.rho == pytest.approx(stats.spearmanr(x, y).statistic, abs=1e-12)
    x, y = synthetic_columns(1, n=5)
    assert np.isfinite(bootstrap_spearman(x, y, seed=0, resamples=100).ci).all()


def test_confusion_against_a_hand_count():
    predicted = np.array([1, 1, 0, 0, 1, 0, 1, 1], bool)
    actual = np.array([1, 0, 0, 1, 1, 0, 0, 1], bool)
    # by hand: (F,F) draws 2, 5 -> 2; (F,T) draw 3 -> 1; (T,F) draws 1, 6 -> 2; (T,T) 0, 4, 7
    np.testing.assert_array_equal(confusion(predicted, actual), [[2, 1], [2, 3]])


def fake_draws(object_name: str, index: int, kin, phys, held, outcome=None,
               phases=None) -> GraspDraws:
    """Draws with the given outcomes: ``held`` 1 -> holding outcome held (every phase but
    the shake held), 0 -> ``outcome`` (default dropped: ``gravity_-z`` failed, the rest held),
    or the given (n,) ``outcome`` codes and (n, P) ``phases``."""
    n = len(held)
    held = np.array(held, bool)
    if outcome is None:
        outcome = np.where(held, HELD, DROPPED)
    outcome = np.array(outcome, np.int8)
    if phases is None:
        phases = np.ones((n, len(PHASES)), np.int8)
        phases[:, PHASES.index("shake")] = -1
        phases[outcome == DROPPED, PHASES.index("gravity_-z")] = 0
        phases[(outcome != HELD) & (outcome != DROPPED)] = -1
    released = (outcome == HELD) | (outcome == DROPPED) | (outcome == GRIP_LOST)
    shift = np.where(released, 0.001 * (1 + np.arange(n)), np.nan)
    return GraspDraws.from_arrays(object_name, index, str(index), np.array(kin, np.int8),
                                  np.where(np.array(kin) == FORCE_CLOSURE, 0.1, 0.0),
                                  np.array(phys, np.int8), np.zeros(n), outcome, shift, shift * 10,
                                  np.full((n, 3), 5.0), np.full((n, 3), 4.0), np.full(n, 1.0),
                                  np.array(phases, np.int8), np.where(phases >= 0, 0.003, np.nan),
                                  np.where(phases >= 0, 0.01, np.nan))


FC, NFC, MISS = FORCE_CLOSURE, NO_FORCE_CLOSURE, MISSED
FAKE = [fake_draws("cube", 0, [FC, FC, FC, NFC], [FC, FC, NFC, NFC], [1, 1, 0, 0]),
        fake_draws("cube", 1, [FC, MISS, NFC, NFC], [FC, FC, NFC, MISS], [0, 1, 0, 1]),
        fake_draws("mug", 0, [NFC, NFC, NFC, NFC], [NFC, NFC, NFC, FC], [0, 0, 0, 0])]


def test_summary_pools_the_draws_and_ranks_the_grasps():
    settings = ValidationSettings(sigma=0.01, samples=4)
    summary = summarize(FAKE, settings, bootstrap_seed=0, resamples=50)
    # hand count over the 12 pooled draws 0..11: kinematic FC 0, 1, 2, 4; physics FC 0, 1,
    # 4, 5, 11; held 0, 1, 5, 7
    # kinematic vs held: TT 0, 1; TF 2, 4; FT 5, 7; FF the other 6
    assert summary["confusion"]["kinematic_fc_vs_held"] == [[6, 2], [2, 2]]
    # physics vs held: TT 0, 1, 5; TF 4, 11; FT 7; FF the other 6
    assert summary["confusion"]["physics_fc_vs_held"] == [[6, 1], [2, 3]]
    # kinematic vs physics: TT 0, 1, 4; TF 2; FT 5, 11; FF the other 6
    assert summary["confusion"]["kinematic_fc_vs_physics_fc"] == [[6, 2], [1, 3]]
    rows = summary["grasps"]
    assert [r["p_fc_kinematic"] for r in rows] == [0.75, 0.25, 0.0]
    assert [r["p_hold"] for r in rows] == [0.5, 0.5, 0.0]
    expected = stats.spearmanr([0.75, 0.25, 0.0], [0.5, 0.5, 0.0]).statistic
    assert summary["spearman"]["kinematic_p_fc_vs_p_hold"]["rho"] == pytest.approx(expected)
    assert summary["draws"] == 12


def test_phase_and_outcome_counts_against_a_hand_count():
    """Two grasps with mixed outcomes, counted by hand: a phase's ``run`` counts the draws
    whose grip stood (held or dropped), ``held`` those that passed it; outcomes per name;
    grip shifts in millimetres per draw (None where nothing was released)."""
    phases = np.full((4, len(PHASES)), -1, np.int8)
    phases[0, :8] = 1                      # held: rest, six directions and the lift
    phases[1, :8] = 1
    phases[1, PHASES.index("gravity_+x")] = 0  # dropped in +x only
    phases[1, PHASES.index("lift")] = 0        # and in the lift
    draws = fake_draws("cube", 0, [FC] * 4, [FC] * 4, [1, 0, 0, 0],
                       outcome=[HELD, DROPPED, GRIP_LOST, NO_GRIP], phases=phases)
    other = fake_draws("cube", 1, [FC, NFC], [FC, NFC], [1, 1])
    summary = summarize([draws, other], ValidationSettings(sigma=0.01, samples=4),
                        resamples=10)
    first = summary["grasps"][0]
    assert first["outcomes"] == {"start_collision": 0, "no_grip": 1, "grip_lost": 1,
                                 "grip_unsteady": 0, "dropped": 1, "held": 1}
    assert first["draw_outcomes"] == ["held", "dropped", "grip_lost", "no_grip"]
    assert first["phases"]["gravity_+x"] == {"run": 2, "held": 1}
    assert first["phases"]["gravity_-y"] == {"run": 2, "held": 2}
    assert first["phases"]["lift"] == {"run": 2, "held": 1}
    assert "shake" not in first["phases"]  # not part of a protocol without the shake
    assert first["grip_shift_mm"] == [1.0, 2.0, 3.0, None]
    assert first["p_hold"] == 0.25
    # pooled: grasp 1 has two held draws, every phase but the shake run and held
    assert summary["phases"]["gravity_+x"] == {"run": 4, "held": 3}
    assert summary["outcomes"]["held"] == 3 and sum(summary["outcomes"].values()) == 6
    assert summary["grip_shift_mm"]["released"] == {"n": 5, "median": 2.0, "max": 3.0}
    assert summary["grip_shift_mm"]["force_closure"]["n"] == 4  # grasp 1's draw 1 is NFC
    assert "motors" not in summary["protocol"]  # no robot given: no motors to name


def test_results_are_written_and_a_cached_run_is_not_rerun(tmp_path, monkeypatch):
    """The cache: a grasp whose file is there is read, not run (run would fail here)."""
    settings = ValidationSettings(sigma=0.01, samples=4)
    grasp = shipped_grasps("cube")[0]
    path = (tmp_path / "cache"
            / f"kuka_sdh_cube_0_{validation.settings_key(grasp, settings)}.npz")
    path.parent.mkdir()
    path.write_bytes(FAKE[0].to_bytes())

    def refuse(task):
        raise AssertionError("a cached grasp was run again")

    monkeypatch.setattr(validation, "grasp_draws", refuse)
    (read,) = run_validation([(0, grasp)], settings, tmp_path)
    np.testing.assert_array_equal(read.held, FAKE[0].held)
    np.testing.assert_array_equal(read.kin_outcome, FAKE[0].kin_outcome)
    other = ValidationSettings(sigma=0.02, samples=4)  # another setting, another file
    assert validation.settings_key(grasp, other) != validation.settings_key(grasp, settings)
    paths = write_results(tmp_path, FAKE, summarize(FAKE, settings, resamples=20),
                          protocol=settings.protocol)
    assert (tmp_path / "grasps.csv").read_text().count("\n") == 4  # header + 3 grasps
    assert (tmp_path / "draws.csv").read_text().count("\n") == 13
    # each draw's margin by hand: 8 phases (no shake), 3 mm of 20 and 0.01 rad of 10 degrees
    # moved (s = 0.85); held: (8 + s) / 9, dropped at gravity_-z after 6 held: (6 + s) / 9
    rows = list(csv.DictReader((tmp_path / "draws.csv").open()))
    for row in rows:
        expected = (8.85 if row["hold_outcome"] == "held" else 6.85) / 9
        assert float(row["hold_margin"]) == pytest.approx(expected, abs=5e-4)
    assert {row["hold_outcome"] for row in rows} == {"held", "dropped"}
    assert set(paths) >= {"draws", "grasps", "summary"}


def test_a_cached_grasp_with_fewer_draws_runs_only_the_missing_ones(tmp_path, monkeypatch):
    settings = ValidationSettings(sigma=0.01, samples=6)
    grasp = shipped_grasps("cube")[0]
    path = (tmp_path / "cache"
            / f"kuka_sdh_cube_0_{validation.settings_key(grasp, settings)}.npz")
    path.parent.mkdir()
    path.write_bytes(FAKE[0].to_bytes())  # 4 draws cached
    starts = []

    def two_more(task):
        starts.append(task[3])
        return fake_draws("cube", 0, [MISS, FC], [MISS, FC], [0, 1])

    monkeypatch.setattr(validation, "grasp_draws", two_more)
    (draws,) = run_validation([(0, grasp)], settings, tmp_path)
    assert starts == [4]
    np.testing.assert_array_equal(draws.held, [1, 1, 0, 0, 0, 1])
    np.testing.assert_array_equal(draws.kin_outcome, [FC, FC, FC, NFC, MISS, FC])
    assert len(GraspDraws.from_file(path, 100)) == 6  # the cache holds all six now


@pytest.mark.expensive
def test_same_seed_same_table_twice(tmp_path):
    """The issue's "same seed, same table": a fresh run of two cube grasps, 3 draws each,
    and another fresh run made of 2 draws then extended to 3 (the cache) give identical
    per-draw tables and identical grasps.csv files."""
    settings = ValidationSettings(sigma=0.0333, samples=3, seed=5)
    grasps = list(enumerate(shipped_grasps("cube")))[:2]
    run_validation(grasps, ValidationSettings(sigma=0.0333, samples=2, seed=5), tmp_path / "b")
    for run in ("a", "b"):
        results = run_validation(grasps, settings, tmp_path / run, processes=1)
        write_results(tmp_path / run, results, summarize(results, settings, resamples=20),
                      protocol=settings.protocol)
    for table in ("grasps.csv", "draws.csv"):
        assert (tmp_path / "a" / table).read_text() == (tmp_path / "b" / table).read_text()


@pytest.mark.parametrize("args, message", [
    (["--sigma", "x"], "--sigma: 'x' is not a number"),
    (["--sigma", "-0.1"], "--sigma must be >= 0"),
    (["--sigma", "4"], "--sigma must be <= pi (3.14159 rad), got 4"),
    (["--samples", "0"], "--samples must be >= 1"),
    (["--object", "teapot"], "--object: unknown object 'teapot'"),
    (["--object", "all", "--grasp", "0"], "--grasp needs one --object"),
    (["--object", "cube", "--grasp", "99"], "grasp index 99 out of range"),
    (["--object", "cube", "--grasp", "1", "1"], "cube grasp 1 is given twice"),
    (["--grasps", "/nonexistent/g.json"], "no such file"),
    (["--grasps", "assets/grasps/kuka_sdh/drill.json", "--object", "cube"],
     "--object cube: assets/grasps/kuka_sdh/drill.json holds grasps of drill"),
    (["--processes", "0"], "--processes must be >= 1"),
    (["--torque-scale", "0"], "--torque-scale must be > 0"),
    (["--torque-scale", "nan"], "--torque-scale"),
    (["--simulator", "gazebo"], "invalid choice: 'gazebo'"),
])
def test_cli_errors_are_one_line(tmp_path, args, message):
    result = run_cli("validate", "--out", str(tmp_path / "out"), *args)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert not (tmp_path / "out").exists()  # nothing written


def test_a_simulator_whose_package_is_missing_is_refused_in_one_line(monkeypatch):
    """A registered simulator whose package is not installed: a one-line ValueError naming
    the package, before any work (the CLI reports it as its error line)."""
    monkeypatch.setitem(simulators.SIMULATORS, "nosuchsim",
                        ("kinegrasp_env.nosuchsim", "Sim", "no_such_package_kinegrasp"))
    with pytest.raises(ValueError, match="needs the Python package 'no_such_package_kinegrasp'"):
        simulators.check_simulator("nosuchsim")
    with pytest.raises(ValueError, match="needs the Python package"):
        ValidationSettings(sigma=0.0, samples=1, simulator="nosuchsim")
    with pytest.raises(ValueError, match="unknown simulator 'x'"):
        simulators.check_simulator("x")
    assert simulators.simulator_class("pybullet").name == "pybullet"
    assert simulators.simulator_class("mujoco").name == "mujoco"


def test_cli_refuses_a_file_as_the_output_folder(tmp_path):
    target = tmp_path / "f"
    target.write_text("")
    result = run_cli("validate", "--object", "cube", "--out", str(target))
    assert result.returncode == 2 and "is a file; give a folder" in result.stderr


def test_physics_engine_is_registered():
    from kinegrasp_env.cli.common import ENGINE_NAMES
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.montecarlo.evaluate import ENGINES
    from kinegrasp_env.robot.catalog import DEFAULT_ROBOT

    assert "physics" in ENGINES and ENGINE_NAMES == ENGINES
    engine = make_engine("physics", DEFAULT_ROBOT, "cube")
    try:
        assert engine.name == "physics"
    finally:
        engine.close()
    with pytest.raises(ValueError, match="physics"):
        make_engine("nope", DEFAULT_ROBOT, "cube")


@pytest.mark.expensive
def test_physics_evaluate_in_a_process_pool_equals_one_process():
    """Engines built once per worker: 2 processes, 2 chunks give the same numbers as 1
    (the run's rows in chunks of 3 on a pool of 2, against ``evaluate_grasp`` in this
    process; ``evaluate_grasp``'s own chunks hold 250 rows, so the pool is given the rows'
    chunks directly)."""
    from kinegrasp_env.montecarlo.chunks import RobotChunk, chunked_draws
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp, summarize
    from kinegrasp_env.montecarlo.execution import LocalExecutor

    grasp = shipped_grasps("cube")[0]
    alone = evaluate_grasp(grasp, sigma=0.0133, n=6, seed=2, engine="physics")
    first = RobotChunk(grasp.robot, grasp.object, "physics", tuple(np.asarray(grasp.q0, float)),
                       0.0133, "gaussian", 2, 0, 6)
    with LocalExecutor(2) as pool:
        pooled = summarize(chunked_draws(first, 6, pool, chunk=3))
    assert alone.counts == pooled.counts
    assert alone.q_mean == pooled.q_mean or (np.isnan(alone.q_mean)
                                             and np.isnan(pooled.q_mean))
