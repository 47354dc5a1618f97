"""Ranking: fixed-n ordering and adaptive successive elimination on a synthetic problem."""

from __future__ import annotations

import fcntl
import itertools
import os
import pty
import struct
import subprocess
import sys
import termios
import threading

import numpy as np
import pytest

from kinegrasp_env.sampling.stats import StreamingMoments
from kinegrasp_env.toolkit.ranking import (
    AdaptiveProgress,
    CandidateResult,
    order,
    rank_adaptive,
    rank_fixed,
)

CHUNK = 50


def bernoulli_evaluator(p_true, seed):
    """A stub evaluator: chunk c of candidate i is Bernoulli(p_i) with its own stream; Q of
    a success is 1 + candidate index (so q_mean is known exactly)."""
    def evaluate(index, first, count):
        successes = 0
        moments = StreamingMoments(1)
        for chunk in range(first, first + count):
            rng = np.random.default_rng([seed, index, chunk])
            hits = int((rng.random(CHUNK) < p_true[index]).sum())
            successes += hits
            moments.update(np.full(hits, 1.0 + index))
        return successes, count * CHUNK, moments
    return evaluate


def test_fixed_ranking_orders_by_criterion():
    p = np.array([0.2, 0.9, 0.5, 0.7])
    results = rank_fixed(4, bernoulli_evaluator(p, 0), chunks=40)
    assert [r.index for r in order(results, "pfc")] == [1, 3, 2, 0]
    assert [r.index for r in order(results, "q_mean")] == [3, 2, 1, 0]
    assert all(r.trials == 40 * CHUNK for r in results)
    lcb = [r.index for r in order(results, "pfc_lcb")]
    assert lcb[0] == 1
    # weighted: P(FC) (1 + mean Q); candidate 3 (0.7 x 5) beats 1 (0.9 x 3)
    assert order(results, "weighted")[0].index == 3


def test_fixed_ranking_reuses_finished_candidates():
    p = np.array([0.2, 0.9, 0.5])
    full = rank_fixed(3, bernoulli_evaluator(p, 1), chunks=10)
    calls = []

    def counting(index, first, count):
        calls.append(index)
        return bernoulli_evaluator(p, 1)(index, first, count)

    resumed = rank_fixed(3, counting, chunks=10, done={0: full[0]})
    assert calls == [1, 2]
    assert [r.successes for r in resumed] == [r.successes for r in full]


def test_adaptive_finds_top_k_and_saves_draws():
    """Over 40 seeded repetitions the true top-2 is returned at least 95% of the time
    (the method's guarantee is 1 - delta = 95%) and fewer draws are used than fixed n."""
    p = np.array([0.95, 0.55, 0.85, 0.4, 0.6, 0.3])
    true_top = {0, 2}
    hits, saved = 0, []
    for seed in range(40):
        report = rank_adaptive(6, bernoulli_evaluator(p, seed), max_chunks=60, chunk_size=CHUNK,
                               top_k=2, delta=0.05)
        hits += set(report.top) == true_top
        saved.append(report.draws / report.fixed_draws)
        assert report.separated
    assert hits / 40 >= 0.95
    assert max(saved) < 1.0 and np.mean(saved) < 0.6


def test_adaptive_bad_arguments():
    ev = bernoulli_evaluator(np.array([0.5, 0.6]), 0)
    with pytest.raises(ValueError, match="top_k must be between 1 and 1"):
        rank_adaptive(2, ev, 10, CHUNK, top_k=2)
    with pytest.raises(ValueError, match="delta must be in"):
        rank_adaptive(2, ev, 10, CHUNK, delta=0.0)


def test_candidate_result_accumulates():
    r = CandidateResult(0)
    r.add(3, 10, StreamingMoments(1).update([1.0, 2.0, 3.0]), 1)
    r.add(1, 10, StreamingMoments(1).update([5.0]), 1)
    assert r.p_fc == pytest.approx(0.2)
    assert r.q_stats()[0] == pytest.approx(np.mean([1, 2, 3, 5]))


def test_adaptive_progress_advances_with_every_chunk():
    """The report after every chunk: draws grow by one chunk each time, the bound (draws by
    the end at the latest) never grows and is never below what is finally drawn, a round
    report closes each round, and the last report is the final count."""
    p = np.array([0.95, 0.55, 0.85, 0.4, 0.6, 0.3])
    seen: list[AdaptiveProgress] = []
    report = rank_adaptive(6, bernoulli_evaluator(p, 3), max_chunks=60, chunk_size=CHUNK,
                           top_k=2, progress=seen.append)
    chunks = [s for s in seen if not s.round_done]
    assert [s.draws for s in chunks] == [CHUNK * (i + 1) for i in range(len(chunks))]
    assert chunks[0].bound == 6 * 60 * CHUNK  # before any decision: the fixed-n budget
    bounds = [s.bound for s in seen]
    assert all(a >= b for a, b in itertools.pairwise(bounds))
    assert min(bounds) >= report.draws
    rounds = [s for s in seen if s.round_done]
    assert [s.rounds for s in rounds] == list(range(1, report.rounds + 1))
    assert seen[-1].round_done and seen[-1].draws == report.draws
    assert report.separated and seen[-1].bound == report.draws and seen[-1].undecided == 0
    # undecided counts: the candidates that drew in the next round
    for before, after in itertools.pairwise(rounds):
        drawn = [s for s in chunks if s.rounds == before.rounds]
        assert len(drawn) == before.undecided
        assert after.undecided <= before.undecided


def _rank_cli(tmp_path, stderr):
    from kinegrasp_env.world.grasps import save_grasps, shipped_grasps

    path = tmp_path / "cube.json"
    save_grasps(shipped_grasps("cube")[:4], path)
    return subprocess.Popen(
        [sys.executable, "-m", "kinegrasp_env.cli", "rank", str(path), "--samples", "400",
         "--adaptive", "--top-k", "1", "--engine", "fast", "--out", str(tmp_path / "a.csv")],
        stdout=subprocess.PIPE, stderr=stderr, text=True)


def test_cli_adaptive_rank_off_a_terminal_prints_a_line_per_round(tmp_path):
    proc = _rank_cli(tmp_path, subprocess.PIPE)
    _, err = proc.communicate()
    assert proc.returncode == 0, err
    lines = err.splitlines()
    rounds = [line for line in lines if line.startswith("rank: round ")]
    assert rounds and rounds[0].startswith("rank: round 1/2 ")
    assert "candidates undecided" in rounds[0] and "draws/s" in rounds[0]
    assert lines[-1].startswith("adaptive: ") and "rounds" in lines[-1]


def test_cli_adaptive_rank_on_a_terminal_bar_then_summary_on_its_own_line(tmp_path):
    """stderr a terminal (a pty): the bar reaches 100% and the summary starts a new line
    (it used to be printed onto the bar's line)."""
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
    chunks: list[bytes] = []

    def drain() -> None:
        while True:
            try:
                data = os.read(leader, 4096)
            except OSError:
                return
            if not data:
                return
            chunks.append(data)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    proc = _rank_cli(tmp_path, follower)
    proc.communicate()
    os.close(follower)
    reader.join(timeout=10)
    os.close(leader)
    text = b"".join(chunks).decode(errors="replace").replace("\r\n", "\n")
    assert proc.returncode == 0, text
    assert "rank: round" in text and "100%" in text and "draws/s" in text
    before, summary = text.split("adaptive: ", 1)
    assert before.endswith("\n"), repr(before[-200:])
    assert "rounds" in summary.splitlines()[0]
