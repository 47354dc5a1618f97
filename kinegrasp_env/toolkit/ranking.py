"""Ranking grasp candidates by robustness under joint noise: the criteria, each candidate's
draws (:class:`CandidateResult`) and the fixed-n run (:func:`rank_fixed`).

Criteria: ``pfc`` (P(FC)), ``q_mean`` (mean Q over force-closure draws), ``pfc_lcb`` (the
lower end of the Wilson 95% interval of P(FC)), ``weighted`` (P(FC) x (1 + w mean Q),
w = :data:`WEIGHT`: P(FC) with a bonus for quality; Q is dimensionless), ``hold_static``
and ``hold`` (a hold score's P(hold), :data:`HOLD_SCORES`) and ``hold_margin`` (the mean over
the draws of how far each got through the quick holding test:
:func:`~kinegrasp_env.physics.protocol.hold_margin`).

Adaptive ranking with its certificate: :mod:`~kinegrasp_env.toolkit.adaptive_ranking`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.sampling.stats import StreamingMoments, wilson_interval

CRITERIA = ("pfc", "q_mean", "pfc_lcb", "weighted", "hold_static", "hold", "hold_margin")
#: The criteria that run the quick holding test on every draw.
HOLD_TEST_CRITERIA = ("hold", "hold_margin")
#: The criteria that rank by a mean (of Q, of Q with P(FC), of the holding test's margins),
#: not by a count of the draws that succeed: the adaptive run's tests cannot certify them.
MEAN_CRITERIA = ("q_mean", "weighted", "hold_margin")
#: The hold scores a candidate may carry: the static hold check, the (quick) holding test.
HOLD_SCORES = ("static", "test")
#: Weight of mean Q in the ``weighted`` criterion.
WEIGHT = 1.0
#: evaluator(candidate index, first chunk, number of chunks) -> (successes, trials, moments)
Evaluator = Callable[[int, int, int], tuple[int, int, StreamingMoments]]
#: The same with each draw's force-closure outcome, (trials,) bool in draw order: what
#: :func:`~kinegrasp_env.toolkit.adaptive_ranking.rank_adaptive` pairs across candidates.
PairedEvaluator = Callable[[int, int, int], tuple[int, int, StreamingMoments, np.ndarray]]


@dataclass
class CandidateResult:
    """Accumulated draws of one candidate."""

    index: int
    successes: int = 0
    trials: int = 0
    chunks: int = 0
    moments: StreamingMoments | None = None
    holds: dict[str, tuple[int, int]] = field(default_factory=dict)
    outcomes: dict[str, int] = field(default_factory=dict)
    #: (sum, count) of the quick holding test's margins over the draws it ran
    margins: tuple[float, int] = (0.0, 0)

    def add_outcomes(self, counts: dict[str, int]) -> None:
        """Count draws per outcome name (``montecarlo.draws.OUTCOMES``)."""
        for name, count in counts.items():
            self.outcomes[name] = self.outcomes.get(name, 0) + int(count)

    def add_holds(self, score: str, holds: int, trials: int) -> None:
        """Count ``holds`` held draws among ``trials`` of a hold score (:data:`HOLD_SCORES`)."""
        held, tried = self.holds.get(score, (0, 0))
        self.holds[score] = (held + holds, tried + trials)

    def p_hold(self, score: str) -> float:
        """The fraction of draws a hold score held (NaN where not run)."""
        held, tried = self.holds.get(score, (0, 0))
        return held / tried if tried else math.nan

    def add_margins(self, margins: np.ndarray) -> None:
        """Add the quick holding test's margins (k,) of k more draws."""
        total, count = self.margins
        self.margins = (total + float(np.sum(margins)), count + int(np.size(margins)))

    def hold_margin(self) -> float:
        """The mean margin of the draws the quick holding test ran (NaN where none)."""
        total, count = self.margins
        return total / count if count else math.nan

    def hold_interval(self, score: str, confidence: float = 0.95) -> tuple[float, float]:
        held, tried = self.holds.get(score, (0, 0))
        return wilson_interval(held, tried, confidence)

    def add(self, successes: int, trials: int, moments: StreamingMoments, chunks: int) -> None:
        self.successes += successes
        self.trials += trials
        self.chunks += chunks
        if self.moments is None:
            self.moments = StreamingMoments(1)
        self.moments.merge(moments)

    @property
    def p_fc(self) -> float:
        return self.successes / self.trials if self.trials else math.nan

    def interval(self, confidence: float = 0.95) -> tuple[float, float]:
        return wilson_interval(self.successes, self.trials, confidence)

    def q_stats(self) -> tuple[float, float, float]:
        """(mean, std, skewness) of Q over force-closure draws (NaN where undefined)."""
        if self.moments is None or self.moments.n == 0:
            return math.nan, math.nan, math.nan
        res = self.moments.result()
        if res.n < 2:
            return float(res.mean[0]), math.nan, math.nan
        return float(res.mean[0]), float(np.sqrt(res.cov[0, 0])), float(res.skew[0])


def score(result: CandidateResult, criterion: str) -> float:
    """Higher is better; NaN scores sort last."""
    if criterion == "pfc":
        return result.p_fc
    if criterion == "pfc_lcb":
        return result.interval()[0]
    if criterion == "q_mean":
        return result.q_stats()[0]
    if criterion == "weighted":
        mean = result.q_stats()[0]
        return result.p_fc * (1.0 + WEIGHT * (0.0 if math.isnan(mean) else mean))
    if criterion == "hold_static":
        return result.p_hold("static")
    if criterion == "hold":
        return result.p_hold("test")
    if criterion == "hold_margin":
        return result.hold_margin()
    raise ValueError(f"unknown criterion {criterion!r}; choose from {CRITERIA}")


def order(results: list[CandidateResult], criterion: str) -> list[CandidateResult]:
    """Best first; ties and NaN scores keep the candidates' input order (stable)."""
    def key(r: CandidateResult) -> tuple[int, float, int]:
        s = score(r, criterion)
        return (1, 0.0, r.index) if math.isnan(s) else (0, -s, r.index)

    return sorted(results, key=key)


def rank_fixed(n_candidates: int, evaluator: Evaluator, chunks: int,
               progress: Callable[[int], None] | None = None,
               done: dict[int, CandidateResult] | None = None) -> list[CandidateResult]:
    """Every candidate gets ``chunks`` chunks. ``done`` holds results to reuse (resume)."""
    results = []
    for index in range(n_candidates):
        if done is not None and index in done:
            results.append(done[index])
        else:
            result = CandidateResult(index)
            result.add(*evaluator(index, 0, chunks), chunks)
            results.append(result)
        if progress is not None:
            progress(index)
    return results
