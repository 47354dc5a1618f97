"""The statistics of ``benchmarks/physics_agreement.py``: its AUC against the definition
counted pair by pair (a held draw above a dropped one, ties half), its paired comparison
with the geometry baseline on cases with a known answer (a score equal to the baseline
differs by exactly 0; a score that separates the classes beats a baseline that does not),
and its resampling by grasp (a grasp whose draws are copies of one draw counts as that one
draw: the interval is that of the draws without copies)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from physics_agreement import (
    BASELINE,
    SCORES,
    auc,
    auc_interval,
    grasp_resamples,
    paired_differences,
)


def _pairwise(score: np.ndarray, label: np.ndarray) -> float:
    held, dropped = score[label], score[~label]
    above = (held[:, None] > dropped[None, :]).sum() + 0.5 * (
        held[:, None] == dropped[None, :]).sum()
    return float(above / (held.size * dropped.size))


def test_auc_is_the_pairwise_count():
    rng = np.random.default_rng(0)
    for _ in range(20):
        label = rng.random(60) < 0.3
        score = rng.integers(0, 5, 60).astype(float)  # many ties
        assert abs(auc(score, label) - _pairwise(score, label)) <= 1e-12
    assert np.isnan(auc(np.arange(5.0), np.ones(5, dtype=bool)))


def test_paired_differences_known_answers():
    rng = np.random.default_rng(1)
    label = rng.random(80) < 0.4
    baseline = rng.random(80)
    scores = {name: baseline.copy() for name in SCORES}
    scores["p_hold_static"] = label + 0.1 * rng.random(80)  # separates the classes
    pairs = [(name, BASELINE) for name in SCORES if name != BASELINE]
    result = paired_differences(scores, label, grasp_resamples(np.arange(80)), pairs)
    assert set(result) == set(SCORES) - {BASELINE}
    assert {r["reference"] for r in result.values()} == {BASELINE}
    same = result["q"]
    assert same["difference"] == 0.0 and same["ci95_simultaneous"] == [0.0, 0.0]
    better = result["p_hold_static"]
    assert abs(better["difference"] - (1.0 - auc(baseline, label))) <= 1e-12
    low, high = better["ci95_simultaneous"]
    assert 0.0 < low <= better["difference"] <= high


def test_paired_differences_of_any_pairs_are_simultaneous_over_them():
    """Pairs with their own references (the margin-against-verdict family): each difference
    is its score's AUC less its own reference's, and the interval's ends are the
    2.5 / k and 100 - 2.5 / k percentiles of the resampled differences for k pairs
    (Bonferroni), computed here from the same resamples."""
    rng = np.random.default_rng(4)
    label = rng.random(120) < 0.4
    scores = {"a": label + rng.normal(0, 0.8, 120), "b": rng.random(120),
              "c": label + rng.normal(0, 1.5, 120), "d": rng.random(120)}
    resamples = grasp_resamples(np.arange(120))
    pairs = [("a", "b"), ("c", "d")]
    result = paired_differences(scores, label, resamples, pairs)
    for name, reference in pairs:
        record = result[name]
        assert record["reference"] == reference
        assert record["difference"] == pytest.approx(
            auc(scores[name], label) - auc(scores[reference], label), abs=1e-12)
        values = [auc(scores[name][p], label[p]) - auc(scores[reference][p], label[p])
                  for p in resamples]
        expected = np.percentile(values, [2.5 / len(pairs), 100 - 2.5 / len(pairs)])
        np.testing.assert_allclose(record["ci95_simultaneous"], expected, atol=1e-12)


def test_a_grasps_draws_resampled_together():
    rng = np.random.default_rng(3)
    label = rng.random(30) < 0.5
    score = label + rng.normal(0.0, 0.8, 30)
    alone = auc_interval(score, label, grasp_resamples(np.arange(30)))
    copies = 5  # each grasp: five copies of one draw
    grouped = auc_interval(np.repeat(score, copies), np.repeat(label, copies),
                           grasp_resamples(np.repeat(np.arange(30), copies)))
    np.testing.assert_allclose(grouped, alone, rtol=0, atol=1e-12)
    by_draw = auc_interval(np.repeat(score, copies), np.repeat(label, copies),
                           grasp_resamples(np.arange(30 * copies)))
    assert by_draw[1] - by_draw[0] < 0.6 * (alone[1] - alone[0])  # too narrow
