"""The paper's experiments as a user runs them: Table I's contents, results before figures,
file permissions, the overall progress report, out-of-range ``--grasps``; robust / fragile
choices made on selection draws and reported on fresh ones."""

from __future__ import annotations

import csv
import io
import logging
import os
import stat
import subprocess
import sys

import numpy as np
import pytest
from cli_helpers import run_cli
from clock_helpers import Clock

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, DrawBatch
from kinegrasp_env.montecarlo.evaluate import GraspEvaluation, summarize
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.toolkit import experiments, plots
from kinegrasp_env.toolkit import selection as selection_mod
from kinegrasp_env.toolkit.progress import Progress, format_eta
from kinegrasp_env.world.grasps import save_grasps, shipped_grasps


def _read(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture()
def umask_027():
    """Run with umask 027 (group may read, others nothing), then put the old one back."""
    old = os.umask(0o027)
    yield 0o027
    os.umask(old)


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


# ----------------------------------------------------------------------------- Table I
def _table1(samples: int, out, sigmas: tuple[float, ...]) -> list[dict]:
    """Table I of the default robot's first cube grasp (every robot's Table I)."""
    from kinegrasp_env.robot.catalog import load_robot

    return experiments.table1(load_robot("kuka_sdh"), "cube", shipped_grasps("cube")[:1],
                              samples, out, sigmas=sigmas, seed=0)


def test_table1_at_certain_force_closure_writes_tables_and_figure(tmp_path, umask_027):
    """sigma = 0: every draw is the nominal grasp, 10 of 10 in force closure. The Wilson
    upper bound used to compute to 0.9999999999999999 < 1.0 there and matplotlib refused the
    error bars; now the table, its interval and the figure are all written, with the
    user's umask."""
    rows = _table1(10, tmp_path, sigmas=(0.0, 0.02))
    assert [r["sigma"] for r in rows] == [0.0, 0.02]
    certain = rows[0]
    assert certain["p_fc"] == 1.0 and certain["p_fc_hi"] == 1.0
    assert certain["p_fc_lo"] == pytest.approx(wilson_interval(10, 10)[0])
    csv_rows = _read(tmp_path / "table1.csv")
    # backward compatible: the old columns first, in their old order; new ones appended
    assert list(csv_rows[0]) == ["grasp", "sigma", "q_nominal", "q_mean", "q_var", "p_fc",
                                 "p_fc_lo", "p_fc_hi", "samples", "q_skew", "robot", "id"]
    assert float(csv_rows[1]["q_skew"]) == pytest.approx(rows[1]["q_skew"], rel=1e-12)
    for name in ("table1.csv", "table1.md", "pfc_vs_sigma.png"):
        assert _mode(tmp_path / name) == 0o666 & ~0o027, name
    text = (tmp_path / "table1.md").read_text()
    assert "sigma = 0 rad: mean / var / skew / P(FC) [95% CI]" in text
    assert "radians" in text.splitlines()[0]
    lo, hi = wilson_interval(round(rows[1]["p_fc"] * 10), 10)
    assert f"{rows[1]['p_fc']:.3f} [{lo:.3f}, {hi:.3f}]" in text


def test_table1_names_each_grasp_by_its_id(tmp_path):
    """A row's ``grasp`` is its index among the grasps given, its ``id`` the grasp's own id,
    which the table and the figure's legend show: a set of grasps 3 and 0 (or a grasp file
    with variants "0v1") was listed as grasps 0 and 1."""
    from kinegrasp_env.robot.catalog import load_robot

    grasps = [shipped_grasps("cube")[3], shipped_grasps("cube")[0]]
    rows = experiments.table1(load_robot("kuka_sdh"), "cube", grasps, 4, tmp_path,
                              sigmas=(0.0,), seed=0)
    assert [(r["grasp"], r["id"]) for r in rows] == [(0, "3"), (1, "0")]
    table = (tmp_path / "table1.md").read_text().splitlines()
    assert [line.split("|")[1].strip() for line in table[-2:]] == ["3", "0"]
    assert [r["id"] for r in _read(tmp_path / "table1.csv")] == ["3", "0"]


def test_markdown_table1_cells():
    """Hand-made rows: every statistic lands in its cell, n/a where undefined."""
    rows = [{"grasp": 0, "sigma": 0.0133, "q_nominal": 0.0123, "q_mean": 0.0111,
             "q_var": 2.5e-6, "q_skew": -0.4567, "p_fc": 0.9, "p_fc_lo": 0.5958,
             "p_fc_hi": 0.9821, "samples": 10},
            {"grasp": 0, "sigma": 0.0333, "q_nominal": 0.0123, "q_mean": 0.02,
             "q_var": float("nan"), "q_skew": float("nan"), "p_fc": 0.1, "p_fc_lo": 0.0179,
             "p_fc_hi": 0.4042, "samples": 10}]
    text = experiments.markdown_table1(rows, "cube", 10)
    line = text.splitlines()[-1]
    assert line == ("| 0 | 0.0123 | 0.0111 / 2.5e-06 / -0.457 / 0.900 [0.596, 0.982] | "
                    "0.02 / n/a / n/a / 0.100 [0.018, 0.404] |")


def test_a_failing_figure_is_one_warning_and_the_results_stay(tmp_path, monkeypatch, caplog):
    """A plot that raises: table1 still returns its rows and writes its tables; one warning
    names the figure; an older figure at that path (it would show other results) goes."""
    stale = tmp_path / "pfc_vs_sigma.png"
    stale.write_bytes(b"old figure")

    def broken(*args, **kwargs):
        raise ValueError("'yerr' must not contain negative values")

    monkeypatch.setattr(plots, "plot_pfc_vs_sigma", broken)
    with caplog.at_level(logging.WARNING):
        rows = _table1(4, tmp_path, sigmas=(0.0,))
    assert rows[0]["p_fc"] == 1.0
    assert len(_read(tmp_path / "table1.csv")) == 1 and (tmp_path / "table1.md").exists()
    assert not stale.exists()
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "\n" not in warnings[0].getMessage()
    assert "pfc_vs_sigma.png not written (ValueError: 'yerr'" in warnings[0].getMessage()


BROKEN_PLOT = """
import sys
from kinegrasp_env.toolkit import plots
from kinegrasp_env.cli.main import main

def broken(*args, **kwargs):
    raise RuntimeError("no 3-D axes today")

plots.plot_contacts = broken
sys.exit(main(["evaluate", "--object", "cube", "--grasp", "0", "--sigma", "0.01",
               "--samples", "4", "--plot", sys.argv[1]]))
"""


def test_cli_evaluate_prints_results_before_a_failing_plot(tmp_path):
    """As the user sees it (a subprocess, no logging set up): the results on stdout, exit 0,
    and exactly one stderr line about the figure."""
    proc = subprocess.run([sys.executable, "-c", BROKEN_PLOT, str(tmp_path / "c.png")],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "P(FC)" in proc.stdout and "plot written" not in proc.stdout
    lines = [line for line in proc.stderr.splitlines() if "c.png" in line]
    assert len(lines) == 1 and "not written (RuntimeError: no 3-D axes today)" in lines[0]
    assert not (tmp_path / "c.png").exists()


def test_reproduce_refuses_more_grasps_than_the_set_has():
    proc = run_cli("reproduce", "table1", "--grasps", "99", "--samples", "10")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0, proc.stderr
    assert ("--grasps must be between 1 and 12 (spray_flask has 12 shipped grasps of robot "
            "kuka_sdh), got 99") in proc.stderr
    assert len(shipped_grasps("spray_flask")) == 12



@pytest.mark.parametrize("figure, count, words", [
    ("fig9", "20", "--grasps must be between 1 and 12 (cube has 12 shipped grasps of robot "
                   "kuka_sdh), got 20"),  # it ran the 12 without a word
    ("fig10", "1", "--grasps 1: fig10 compares the most and the least robust of N "
                   "configurations, N >= 2"),  # it ran one, and compared nothing
])
def test_reproduce_refuses_a_count_it_cannot_run(tmp_path, capsys, figure, count, words):
    from kinegrasp_env.cli import main

    out = tmp_path / "f"
    assert main(["reproduce", figure, "--grasps", count, "--object", "cube", "--samples", "10",
                 "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip() == f"kinegrasp reproduce: error: {words}"
    assert not out.exists() and len(shipped_grasps("cube")) == 12


# ----------------------------------------------------------------------------- file modes
@pytest.mark.parametrize("mask", [0o022, 0o027, 0o077, 0o002])
def test_written_files_follow_the_umask(tmp_path, mask):
    """New files get 0o666 & ~umask (as open() would), not mkstemp's private 0600."""
    old = os.umask(mask)
    try:
        write_atomic(tmp_path / "a.txt", "x")
        write_atomic(tmp_path / "b.bin", b"\x00\x01")
        save_grasps(shipped_grasps("cube")[:1], tmp_path / "g.json")
        plots.plot_pfc_vs_sigma([{"grasp": 0, "sigma": 0.01, "p_fc": 0.5, "p_fc_lo": 0.4,
                                  "p_fc_hi": 0.6}], tmp_path / "f.png")
    finally:
        os.umask(old)
    for name in ("a.txt", "b.bin", "g.json", "f.png"):
        assert _mode(tmp_path / name) == 0o666 & ~mask, (name, oct(mask))
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"


def test_rewriting_a_file_keeps_its_mode(tmp_path):
    path = tmp_path / "a.txt"
    path.write_text("old")
    os.chmod(path, 0o640)
    write_atomic(path, "new")
    assert path.read_text() == "new" and _mode(path) == 0o640


# ----------------------------------------------------------------------------- progress
def test_progress_lines_off_a_terminal_and_an_eta_without_start_up():
    """Two cells of 1,000 draws in chunks of 250. Start-up: 60 s before the first chunk;
    then 100 draws/s. The rate and ETA must ignore the start-up: 100 draws/s and, after
    cell 1 (1,000 draws left), 10 s to go (with the start-up counted: 1,000 draws in 67.5 s,
    15 draws/s and 67 s)."""
    clock, stream = Clock(), io.StringIO()
    report = Progress("table1", 2000, 2, stream=stream, interactive=False, clock=clock)
    for cell in range(2):
        callback = report.evaluation()
        for chunk in range(1, 5):
            clock.now += 60.0 if (cell, chunk) == (0, 1) else 2.5
            callback(250 * chunk, 1000)
        report.cell_done(f"cube grasp 0 sigma 0.0{cell + 1}: P(FC) 0.500")
    report.close()
    lines = stream.getvalue().splitlines()
    assert lines == [
        "table1: cell 1/2 cube grasp 0 sigma 0.01: P(FC) 0.500, 1000/2000 draws, "
        "100 draws/s, ETA 00:10",
        "table1: cell 2/2 cube grasp 0 sigma 0.02: P(FC) 0.500, 2000/2000 draws, "
        "100 draws/s, ETA 00:00"]


def test_progress_rate_unknown_before_two_reports_and_eta_format():
    clock, stream = Clock(), io.StringIO()
    report = Progress("fig7", 100, 1, stream=stream, interactive=False, clock=clock)
    clock.now = 30.0
    report.evaluation()(100, 100)
    report.cell_done("drill grasp 0 sigma 0.0133: P(FC) 1.000")
    assert stream.getvalue() == ("fig7: cell 1/1 drill grasp 0 sigma 0.0133: P(FC) 1.000, "
                                 "100/100 draws, rate being measured\n")
    assert [format_eta(s) for s in (None, 0.4, 59.6, 3599, 3600, 7384)] == [
        "?", "00:00", "01:00", "59:59", "1:00:00", "2:03:04"]


def test_progress_bar_on_a_terminal_is_one_bar():
    """Interactive: one bar whose text shows the cell, the draws and the rate; no per-cell
    lines."""
    clock, stream = Clock(), io.StringIO()
    with Progress("table1", 1000, 4, stream=stream, interactive=True, clock=clock) as report:
        for _ in range(4):
            callback = report.evaluation()
            for chunk in (1, 2):
                clock.now += 1.0
                callback(125 * chunk, 250)
            report.cell_done("x: P(FC) 1.000")
    text = stream.getvalue()
    assert "table1: cell 4/4" in text and "1000/1000 draws, 125 draws/s" in text
    assert "x: P(FC)" not in text


# ----------------------------------------------------------------------------- selection
def _bernoulli_stats(p: float, n: int, key: tuple) -> GraspEvaluation:
    """A candidate's statistics on n Bernoulli(p) draws from the stream ``key`` (what an
    engine would do for a configuration whose true P(FC) is p; the default robot's 6
    contact slots and 7 hand joints)."""
    fc = np.random.default_rng(np.random.SeedSequence(list(key))).random(n) < p
    draws = DrawBatch.empty(n, 6, 7)
    draws.outcome[:] = np.where(fc, FORCE_CLOSURE, 0)
    stats = summarize(draws)
    assert stats.p_fc == int(fc.sum()) / n
    return stats


def test_reported_gap_of_equal_candidates_is_centred_at_zero():
    """Eight candidates with the same true P(FC) = 0.5, 200 draws each, 300 seeds; each
    candidate's draws of stream c (0: selection, 1: fresh) are independent Bernoulli draws
    keyed (seed, c, candidate). Chosen on the selection draws, the robust - fragile gap there
    is the range of eight binomial estimates: ~0.10 on average (selection bias). Reported on
    the fresh stream, the gap's true value is 0: its mean over 300 seeds has standard error
    sqrt(2 * 0.25 / 200 / 300) = 0.0029, so |mean| < 0.012 (4 standard errors); and the
    printed paired 95% interval must contain 0 in at least 90% of the seeds (binomial
    standard error 1.3% around 95%: 90% is 3.8 of them below). Reporting the selection draws
    instead gives a mean gap of ~0.10 and an interval that misses 0 in most seeds."""
    n, seeds = 200, range(300)
    reported, chosen, covered = [], [], 0
    for seed in seeds:
        selection = [_bernoulli_stats(0.5, n, (seed, 0, i)) for i in range(8)]
        pair = selection_mod.robust_fragile(
            [s.p_fc for s in selection], lambda i, seed=seed: _bernoulli_stats(0.5, n,
                                                                               (seed, 1, i)))
        assert selection[pair.robust].p_fc == max(s.p_fc for s in selection)
        assert selection[pair.fragile].p_fc == min(s.p_fc for s in selection)
        assert [f.p_fc for f in pair.fresh] == [
            _bernoulli_stats(0.5, n, (seed, 1, i)).p_fc for i in (pair.robust, pair.fragile)]
        assert pair.gap == pytest.approx(pair.fresh[0].p_fc - pair.fresh[1].p_fc, abs=1e-12)
        reported.append(pair.gap)
        chosen.append(selection[pair.robust].p_fc - selection[pair.fragile].p_fc)
        covered += pair.gap_lo <= 0.0 <= pair.gap_hi
    assert np.mean(chosen) > 0.07  # the bias the separation removes
    assert abs(np.mean(reported)) < 0.012, np.mean(reported)
    assert covered >= 0.90 * len(seeds), covered


def test_fresh_draws_are_the_next_chunks_of_the_seed():
    """The report stream as documented, checked through the public evaluate_grasp:
    the fresh draws of a 500-draw selection (chunks 2-3 of the seed, rows 500..999) are
    draws 500..999 of a 1,000-draw evaluation with the same seed, outcome for outcome, and
    differ from the selection draws (draws 0..499)."""
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp

    grasp = shipped_grasps("cube")[0]
    assert selection_mod.report_chunks(500) == (2, 2)
    assert selection_mod.report_rows(500) == 500
    fresh = evaluate_grasp(grasp, sigma=0.03, n=500, seed=3, engine="fast",
                           offset=selection_mod.report_rows(500))
    both = evaluate_grasp(grasp, sigma=0.03, n=1000, seed=3, engine="fast")
    assert np.array_equal(fresh.draws.outcome, both.draws.outcome[500:])
    assert np.array_equal(fresh.draws.quality, both.draws.quality[500:])
    assert not np.array_equal(both.draws.quality[:500], both.draws.quality[500:])
    assert 0.05 < fresh.p_fc < 0.95  # the noise level makes outcomes vary draw by draw
    assert selection_mod.provenance(500, 3) == (
        "chosen on 500 draws per candidate (seed 3, chunks 0-1), reported on 500 fresh "
        "draws (chunks 2-3)")


def test_a_pair_is_two_candidates():
    """Largest first, smallest among the others: two different candidates even when every
    estimate ties (all at P(FC) 1 at small noise); fewer than two is a one-line error."""
    assert selection_mod.extremes([0.2, 0.9, 0.1, 0.9, 0.1]) == (1, 2)
    assert selection_mod.extremes([1.0, 1.0, 1.0]) == (0, 1)
    with pytest.raises(ValueError, match="at least 2, got 1"):
        selection_mod.extremes([0.5])


def test_fig10_marks_its_pair_and_reports_it_on_the_next_draws(tmp_path):
    """fig10 of the default robot on three cube variants at sigma 0.02 (250 draws): the rows
    marked robust and fragile are the largest and the smallest P(FC) of the rows (the
    selection draws), and each one's fresh P(FC) is exactly its share of force closure in
    draws 250..499 of the same seed, computed here through the public evaluate_grasp
    on 500 draws (so the fresh draws are neither the selection draws nor a recount of
    them)."""
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit.arm_variants import find_variants

    robot, grasp = load_robot("kuka_sdh"), shipped_grasps("cube")[0]
    rows = experiments.fig10(robot, tmp_path, grasp_sets={"cube": [grasp]}, samples=250,
                             sigma=0.02, count=3, seed=5, engine="fast")
    marked = {r["config"]: r for r in rows if r["config"]}
    assert set(marked) == {"robust", "fragile"} and marked["robust"] is not marked["fragile"]
    assert marked["robust"]["p_fc"] == max(r["p_fc"] for r in rows)
    assert marked["fragile"]["p_fc"] == min(r["p_fc"] for r in rows)
    variants = {g.id: g for g in find_variants(robot, "cube", grasp, 3)}
    for row in marked.values():
        both = evaluate_grasp(variants[row["id"]], sigma=0.02, n=500, seed=5,
                              engine="fast")
        assert row["p_fc"] * 250 + row["fresh_p_fc"] * 250 == pytest.approx(both.p_fc * 500)
        assert row["fresh_samples"] == 250
        assert row["fresh_p_fc_lo"] <= row["fresh_p_fc"] <= row["fresh_p_fc_hi"]
    csv_rows = _read(tmp_path / "fig10.csv")
    assert [r["config"] for r in csv_rows] == [r["config"] for r in rows]


def test_fresh_rows_start_after_the_selections_chunks_and_carry_their_own_q_moments():
    """A 100-draw selection fills chunk 0 (rows 0..99) only: the pair's fresh draws are rows
    250..349 of the seed's run (chunk 1), not rows 100..199. Each chosen row's fresh P(FC)
    and Q mean, variance and skewness equal those of evaluate_grasp on exactly those
    rows (offset 250), and differ from its selection estimate's (rows 0..99)."""
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit.arm_variants import find_variants, variant_block

    robot, grasp = load_robot("kuka_sdh"), shipped_grasps("drill")[0]
    variants = find_variants(robot, "drill", grasp, 3)
    rows, fresh = variant_block(robot, "drill", variants, samples=100, sigma=0.03, seed=4,
                                engine="fast", friction=0.5)
    by_id = {v.id: v for v in variants}
    chosen = [r for r in rows if r["config"]]
    assert len(chosen) == 2 and len(fresh) == 2
    for row in chosen:
        rows_250 = evaluate_grasp(by_id[row["id"]], sigma=0.03, n=100, seed=4,
                                  offset=250, engine="fast")
        rows_100 = evaluate_grasp(by_id[row["id"]], sigma=0.03, n=100, seed=4,
                                  offset=100, engine="fast")
        assert row["fresh_p_fc"] == rows_250.p_fc
        assert (row["fresh_q_mean"], row["fresh_q_var"], row["fresh_q_skew"]) == pytest.approx(
            (rows_250.q_mean, rows_250.q_std ** 2, rows_250.q_skew), rel=1e-12)
        assert (rows_100.p_fc, rows_100.q_mean) != (rows_250.p_fc, rows_250.q_mean)
        assert (row["q_mean"], row["q_std"]) != pytest.approx(
            (row["fresh_q_mean"], row["fresh_q_var"] ** 0.5))


def _last_progress_line(text: str, name: str) -> tuple[int, int, str]:
    """(cells, total draws, the last line) of a command's plain progress lines: line k says
    cell k, the last one cell k/k and done/total draws."""
    import re

    lines = [line for line in text.splitlines() if line.startswith(f"{name}: cell ")]
    cells = len(lines)
    assert [line.startswith(f"{name}: cell {k}/") for k, line in enumerate(lines, 1)] == [
        True] * cells
    assert lines[-1].startswith(f"{name}: cell {cells}/{cells} ")
    done, total = map(int, re.search(r"(\d+)/(\d+) draws,", lines[-1]).groups())
    assert done == total
    return cells, total, lines[-1]


@pytest.mark.parametrize("factor", [None, 1], ids=["batch", "direct-fallback"])
def test_fig10_reweight_progress_counts_the_batch_and_every_fallback(factor, capsys,
                                                                     monkeypatch, tmp_path):
    """fig10 --method reweight's progress: one cell for the batch (BATCH_FACTOR x samples
    closings) and the pair's two fresh cells, the last line at k/k cells and every draw
    counted once. With a batch too small for any variant (BATCH_FACTOR 1: each variant falls
    back to its own direct draws), a cell per fallback is added as it runs, and the totals
    follow."""
    from kinegrasp_env.montecarlo import palm_batch
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit import arm_variants

    if factor is not None:
        for module in (palm_batch, arm_variants):
            monkeypatch.setattr(module, "BATCH_FACTOR", factor)
        from kinegrasp_env.toolkit import batch_stats
        monkeypatch.setattr(batch_stats, "BATCH_FACTOR", factor)
    samples = 100
    rows = experiments.fig10(load_robot("kuka_sdh"), tmp_path, samples=samples, count=4,
                             grasp_sets={"spray_flask": shipped_grasps("spray_flask")},
                             sigma=0.0233, engine="fast", method="reweight", progress=True)
    err = capsys.readouterr().err
    cells, total, last = _last_progress_line(err, "fig10")
    fallbacks = sum(r["estimate"] == "direct" for r in rows)
    batch = (factor or palm_batch.BATCH_FACTOR) * samples
    assert len(rows) == 4 and {r["estimate"] for r in rows} <= {"direct", "reweighted"}
    assert cells == 1 + 2 + fallbacks and total == batch + (2 + fallbacks) * samples, last
    assert f" {total}/{total} draws" in last and "down from" not in last
    assert fallbacks == (4 if factor is not None else 0)
    # the batch is counted when it is closed, before the evaluations it falls back to
    first = next(line for line in err.splitlines() if line.startswith("fig10: cell 1/"))
    assert "one batch of" in first and f" {batch}/" in first, first
    assert all(r["samples"] == samples for r in rows if r["estimate"] == "direct")


def test_a_cell_added_on_the_way_grows_the_totals_on_a_bar_too():
    """Progress.add_cell: one more cell and its draws in the totals, the bar's own total and
    description with them; the last report is every cell and every draw, none "down"."""
    stream = io.StringIO()
    report = Progress("fig10", 300, 3, stream=stream, interactive=True)
    report.finish_cell(100, "a")
    report.add_cell(100)
    assert (report.cells, report.total, report.bar.total) == (4, 400, 400)
    assert "cell 2/4" in stream.getvalue().rsplit("\r", 1)[-1]
    for text in "bcd":
        report.finish_cell(100, text)
    report.close()
    assert (report.done, report.cells_done) == (400, 4)
    assert "cell 4/4 100%" in stream.getvalue() and "down from" not in stream.getvalue()


def test_a_gap_from_one_draw_is_printed_without_an_interval():
    """A paired t-interval needs two draws (paired_interval of one gives infinite ends):
    fig7's line says so instead of printing "95% CI -inf .. +inf"."""
    from kinegrasp_env.sampling.stats import paired_interval
    from kinegrasp_env.toolkit.selection import format_gap

    gap, lo, hi = paired_interval(np.array([0.0]))
    assert (lo, hi) == (-np.inf, np.inf)
    assert format_gap({"gap": gap, "gap_lo": lo, "gap_hi": hi}) == \
        "+0.000 (no interval from one draw)"
    assert format_gap({"gap": 0.05, "gap_lo": 0.01, "gap_hi": 0.09}) == \
        "+0.050 (95% CI +0.010 .. +0.090)"


def test_a_gain_without_a_discordant_draw_is_printed_without_a_point_interval():
    """Fresh draws that end alike at both elbows give a t-interval of one point (no spread):
    the elbow summary says so instead of printing "95% CI +0.000 .. +0.000"."""
    from kinegrasp_env.cli.elbow_output import gain_line
    from kinegrasp_env.sampling.stats import paired_interval

    gain, lo, hi = paired_interval(np.zeros(200))
    assert lo == hi == 0.0
    assert gain_line({"gain": gain, "gain_ci": (lo, hi)}) == \
        "  gain over nominal +0.000 (no discordant draw, paired)"
    assert gain_line({"gain": 0.05, "gain_ci": (0.02, 0.08)}) == \
        "  gain over nominal +0.050 (95% CI +0.020 .. +0.080, paired)"
    gain, lo, hi = paired_interval(np.ones(50))  # every pair differs, alike: a point too
    assert gain_line({"gain": gain, "gain_ci": (lo, hi)}) == \
        "  gain over nominal +1.000 (every pair of draws differs alike, paired)"
    gain, lo, hi = paired_interval(np.array([1.0]))
    assert gain_line({"gain": gain, "gain_ci": (lo, hi)}) == \
        "  gain over nominal +1.000 (no interval from one draw, paired)"
