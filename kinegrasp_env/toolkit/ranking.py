"""Ranking grasp candidates by robustness under joint noise: fixed n or adaptive.

Criteria: ``pfc`` (P(FC)), ``q_mean`` (mean Q over force-closure draws), ``pfc_lcb`` (the
lower end of the Wilson 95% interval of P(FC)), ``weighted`` (P(FC) x (1 + w mean Q),
w = :data:`WEIGHT`: P(FC) with a bonus for quality; Q is dimensionless).

Adaptive mode (successive elimination, as in bandit-based robust grasp selection): every
undecided candidate gets one more chunk of draws per round; with Wilson intervals at the
Bonferroni-corrected confidence 1 - delta / (candidates x rounds), a candidate is *in* the
top k once its lower bound exceeds the upper bound of every candidate outside the current
top k, and *out* once its upper bound falls below the lower bound of the k-th best. Decided
candidates stop drawing; the run stops when the top k is separated or every candidate has
reached the fixed-n budget. Every candidate draws from the same chunk streams (common random
numbers), so adaptive and fixed runs see the same noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.sampling.stats import StreamingMoments, wilson_interval

CRITERIA = ("pfc", "q_mean", "pfc_lcb", "weighted")
#: Weight of mean Q in the ``weighted`` criterion.
WEIGHT = 1.0
#: evaluator(candidate index, first chunk, number of chunks) -> (successes, trials, moments)
Evaluator = Callable[[int, int, int], tuple[int, int, StreamingMoments]]


@dataclass
class CandidateResult:
    """Accumulated draws of one candidate."""

    index: int
    successes: int = 0
    trials: int = 0
    chunks: int = 0
    moments: StreamingMoments | None = None

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


@dataclass(frozen=True)
class AdaptiveProgress:
    """Where an adaptive ranking stands; reported after every chunk drawn.

    Attributes:
        draws: draws made so far (all candidates).
        bound: draws made by the end of the run at the latest (``draws`` plus a chunk per
            undecided candidate per round left), for progress bars and ETAs.
        rounds: rounds finished; max_rounds: the per-candidate chunk budget.
        undecided: candidates still drawing.
        round_done: this report closes a round (its decisions are made).
    """

    draws: int
    bound: int
    rounds: int
    max_rounds: int
    undecided: int
    round_done: bool


@dataclass
class AdaptiveReport:
    """Outcome of an adaptive ranking."""

    results: list[CandidateResult]
    top: list[int]
    separated: bool
    rounds: int
    draws: int
    fixed_draws: int


def eliminate(results: list[CandidateResult], state: np.ndarray, top_k: int,
              confidence: float) -> bool:
    """One round's decisions at ``confidence``: mark candidates in (1) or out (-1) of the
    top ``top_k`` in ``state`` (n,) (0 undecided, updated in place); True when the top k is
    separated from the rest."""
    lo = np.array([r.interval(confidence)[0] for r in results])
    hi = np.array([r.interval(confidence)[1] for r in results])
    p = np.array([r.p_fc for r in results])
    ranked = np.argsort(-p, kind="stable")
    inside, outside = ranked[:top_k], ranked[top_k:]
    kth_lo = lo[inside].min()
    best_out_hi = hi[outside].max()
    for i in range(len(results)):
        if state[i] != 0:
            continue
        others = outside if i in inside else np.setdiff1d(inside, [i])
        if i in inside and lo[i] > hi[others].max():
            state[i] = 1
        elif i in outside and hi[i] < kth_lo:
            state[i] = -1
    return bool((state == 1).sum() == top_k or kth_lo > best_out_hi)


def rank_adaptive(n_candidates: int, evaluator: Evaluator, max_chunks: int, chunk_size: int, *,
                  top_k: int = 1, delta: float = 0.05, criterion: str = "pfc",
                  progress: Callable[[AdaptiveProgress], None] | None = None
                  ) -> AdaptiveReport:
    """Successive elimination for the top ``top_k`` by P(FC) at confidence 1 - delta.

    Args:
        n_candidates: number of candidates.
        evaluator: draws chunks of a candidate (see :data:`Evaluator`).
        max_chunks: per-candidate budget (the fixed-n run uses exactly this many chunks).
        chunk_size: draws per chunk (for the report).
        top_k: size of the set to separate.
        delta: allowed probability of a wrong top-k.
        criterion: the final ordering (separation is always decided on P(FC)).
        progress: called with an :class:`AdaptiveProgress` after every chunk drawn.
    """
    if not 1 <= top_k < n_candidates:
        raise ValueError(f"top_k must be between 1 and {n_candidates - 1}, got {top_k}")
    if not 0 < delta < 1:
        raise ValueError(f"delta must be in (0, 1), got {delta}")
    results = [CandidateResult(i) for i in range(n_candidates)]
    state = np.zeros(n_candidates, dtype=int)  # 0 undecided, 1 in, -1 out
    confidence = 1 - delta / (n_candidates * max_chunks)
    rounds = 0
    separated = False

    def report(undecided: int, owed: int, round_done: bool) -> None:
        """Tell ``progress``; ``owed``: chunks still to draw at most."""
        if progress is not None:
            draws = sum(r.trials for r in results)
            progress(AdaptiveProgress(draws, draws + owed * chunk_size, rounds, max_chunks,
                                      undecided, round_done))

    while rounds < max_chunks:
        active = np.flatnonzero(state == 0)
        later = len(active) * (max_chunks - rounds - 1)  # every active one, each round left
        for j, i in enumerate(active, 1):
            results[i].add(*evaluator(int(i), results[i].chunks, 1), 1)
            report(len(active), len(active) - j + later, False)
        rounds += 1
        separated = eliminate(results, state, top_k, confidence)
        undecided = 0 if separated else int((state == 0).sum())
        report(undecided, undecided * (max_chunks - rounds), True)
        if separated or undecided == 0:
            break
    ordered = order(results, criterion)
    top = [int(i) for i in np.argsort(-np.array([r.p_fc for r in results]), kind="stable")[:top_k]]
    draws = sum(r.trials for r in results)
    return AdaptiveReport(ordered, top, separated, rounds, draws,
                          n_candidates * max_chunks * chunk_size)

