"""Ranking grasp candidates by robustness under joint noise: fixed n or adaptive.

Criteria: ``pfc`` (P(FC)), ``q_mean`` (mean Q over force-closure draws), ``pfc_lcb`` (the
lower end of the Wilson 95% interval of P(FC)), ``weighted`` (P(FC) x (1 + w mean Q),
w = :data:`WEIGHT`: P(FC) with a bonus for quality; Q is dimensionless).

Adaptive mode (:func:`rank_adaptive`): top-k identification on paired draws. Every candidate
draws chunk c of the same seed, that is the same joint-noise draws (common random numbers),
so two candidates i and j are compared draw by draw. Of the draws on which exactly one of
the two holds (m discordant draws), the number b on which i holds is Binomial(m, theta)
given m, and theta > 1/2 exactly when P(FC)_i > P(FC)_j: the exact one-sided sign test
(McNemar's) certifies "i is more robust than j" when P(Bin(m, 1/2) >= b) <= alpha. Its
noise is the discordance of the pair, not the variance of each estimate, which is what
common random numbers buy (at sigma 0.0133 rad neighbouring elbow angles of one grasp
disagree on 3-4% of the draws, different grasps on 25-55%).
Certificates are closed under transitivity; a candidate certified above n - k others is *in*
the top k, one certified below k others is *out* (then every *in* is above every *out*).
Round r draws, up to r chunks each, the candidates of the pairs across the current top-k
boundary that are not yet certified (every candidate in round 1); the run stops when k
candidates are in (or n - k out), or after the fixed-n budget's number of rounds.

Guarantee: every test is run at alpha = delta / (n (n - 1) / 2 x chunks), one per candidate
pair and chunk mark (the number of common chunks the pair is tested on), so with probability
at least 1 - delta no certificate of the whole run is wrong (union bound; exact tests, no
normal approximation). Hence P(a run reports ``separated`` and its top k is wrong) <= delta.
A run that reaches the budget unseparated returns its best estimate of the top k (certified
candidates first, then by P(FC)) without that guarantee, and says so (``separated`` False).
An evaluator without per-draw outcomes falls back to unpaired bounds (each candidate's exact
Clopper-Pearson interval at delta / (2 n chunks) per side), with the same guarantee.

Cost: a pair with P(FC) gap g, discordant on a fraction d of the draws, is certified after
about d (z / g)^2 paired draws, z the normal quantile of alpha (about 4 for 10 candidates,
8 chunks, delta 0.05). Candidates far from the top-k boundary stop after a chunk or two; a
boundary pair closer than the budget can certify draws to the end (``separated`` False).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import special
from scipy import stats as sps

from kinegrasp_env.sampling.stats import StreamingMoments, wilson_interval

CRITERIA = ("pfc", "q_mean", "pfc_lcb", "weighted")
#: Weight of mean Q in the ``weighted`` criterion.
WEIGHT = 1.0
#: evaluator(candidate index, first chunk, number of chunks) -> (successes, trials, moments)
Evaluator = Callable[[int, int, int], tuple[int, int, StreamingMoments]]
#: The same with each draw's force-closure outcome, (trials,) bool in draw order: what
#: :func:`rank_adaptive` pairs across candidates.
PairedEvaluator = Callable[[int, int, int], tuple[int, int, StreamingMoments, np.ndarray]]


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
        bound: draws made by the end of the run at the latest (``draws`` plus the chunks
            left to every candidate that may still draw), for progress bars and ETAs; it
            never grows.
        rounds: rounds finished; max_rounds: the per-candidate chunk budget (round r draws
            every drawing candidate up to r chunks, so there are at most that many rounds).
        undecided: candidates neither certified in nor out of the top k (0 once separated);
            in a chunk's report (``round_done`` False): the candidates drawing this round.
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
    """Outcome of an adaptive ranking.

    Attributes:
        results: every candidate's draws, ordered by the criterion.
        top: the top k by P(FC), best first: certified when ``separated``.
        separated: the top k is certified at confidence 1 - ``delta``.
        rounds, draws: rounds run and draws made (all candidates); fixed_draws: the fixed-n
            run's draws (candidates x chunks x chunk size).
        paired: certified on paired draws (sign tests) rather than unpaired intervals.
        alpha: the level of each test (delta over pairs and chunk marks).
    """

    results: list[CandidateResult]
    top: list[int]
    separated: bool
    rounds: int
    draws: int
    fixed_draws: int
    paired: bool = True
    alpha: float = math.nan


def sign_test_level(n_candidates: int, max_chunks: int, delta: float) -> float:
    """Level alpha of each paired test: ``delta`` shared by every pair of candidates and
    every chunk mark a pair can be tested at (union bound)."""
    return delta / (n_candidates * (n_candidates - 1) / 2 * max_chunks)


def sign_test_certifies(wins: np.ndarray, losses: np.ndarray, alpha: float) -> np.ndarray:
    """Exact one-sided sign test (McNemar) of "i holds more often than j" on paired draws.

    Args:
        wins, losses: draws on which i holds and j fails, and the reverse (same shape).
        alpha: level of each test.

    Returns:
        bool array: P(Binomial(wins + losses, 1/2) >= wins) <= alpha. Under P(FC)_i <=
        P(FC)_j, True with probability at most alpha (given the number of discordant draws,
        wins is Binomial(m, theta) with theta <= 1/2).
    """
    wins = np.asarray(wins)
    m = wins + np.asarray(losses)
    # P(Bin(m, 1/2) >= b) = I_{1/2}(b, m - b + 1) (regularized incomplete beta), b >= 1
    tail = special.betainc(np.maximum(wins, 1), m - wins + 1, 0.5)
    return (wins > 0) & (tail <= alpha)


def win_rate_bounds(wins: int, losses: int, alpha: float) -> tuple[float, float]:
    """Exact (Clopper-Pearson) one-sided bounds at level ``alpha`` each on theta = P(i holds
    | exactly one of i, j holds): theta > 1/2 iff P(FC)_i > P(FC)_j; the lower bound
    exceeds 1/2 exactly when :func:`sign_test_certifies` does. (0, 1) without discordance."""
    lo = float(sps.beta.ppf(alpha, wins, losses + 1)) if wins else 0.0
    hi = float(sps.beta.isf(alpha, wins + 1, losses)) if losses else 1.0
    return lo, hi


def difference_interval(wins: int, losses: int, n: int,
                        confidence: float = 0.95) -> tuple[float, float]:
    """Interval on P(FC)_i - P(FC)_j from ``n`` paired draws (``wins``: i holds, j fails;
    ``losses``: the reverse), covering with probability >= ``confidence``.

    The difference is pi (2 theta - 1), pi = P(discordant draw), theta as in
    :func:`win_rate_bounds`; exact two-sided Clopper-Pearson intervals on both, at half of
    1 - confidence each, and the extremes of the product over the box (union bound).
    """
    alpha = (1.0 - confidence) / 4  # per side, two quantities
    m = wins + losses
    pi_lo = float(sps.beta.ppf(alpha, m, n - m + 1)) if m else 0.0
    pi_hi = float(sps.beta.isf(alpha, m + 1, n - m)) if m < n else 1.0
    th_lo, th_hi = win_rate_bounds(wins, losses, alpha)
    lo, hi = 2 * th_lo - 1, 2 * th_hi - 1
    return (lo * (pi_lo if lo >= 0 else pi_hi), hi * (pi_hi if hi >= 0 else pi_lo))


class PairedDraws:
    """Per-draw force-closure outcomes of every candidate, chunk by chunk (chunk c is the
    same noise for all), and per ordered pair the discordant counts on their common chunks.

    Attributes:
        wins: (n, n) int, draws of the common chunks on which i holds and j fails.
        marks: (n, n) int, common chunks of i and j (the number the pair is tested on).
    """

    def __init__(self, n_candidates: int) -> None:
        self.chunks: list[list[np.ndarray]] = [[] for _ in range(n_candidates)]
        self.wins = np.zeros((n_candidates, n_candidates), dtype=np.int64)
        self.marks = np.zeros((n_candidates, n_candidates), dtype=np.int64)

    def add(self, index: int, outcomes: np.ndarray) -> None:
        """Candidate ``index``'s next chunk: (size,) bool, True where it holds."""
        c = len(self.chunks[index])
        self.chunks[index].append(outcomes)
        for j, theirs in enumerate(self.chunks):
            if j == index or len(theirs) <= c:
                continue
            if theirs[c].shape != outcomes.shape:
                raise ValueError(f"chunk {c} has {outcomes.size} draws for candidate {index}"
                                 f" but {theirs[c].size} for candidate {j}")
            self.wins[index, j] += int(np.count_nonzero(outcomes & ~theirs[c]))
            self.wins[j, index] += int(np.count_nonzero(theirs[c] & ~outcomes))
            self.marks[index, j] = self.marks[j, index] = c + 1


def unpaired_certifies(results: list[CandidateResult], alpha: float) -> np.ndarray:
    """(n, n) bool: i's exact lower bound above j's upper bound (Clopper-Pearson, one-sided
    at ``alpha`` each), for evaluators without per-draw outcomes."""
    s = np.array([r.successes for r in results])
    t = np.array([r.trials for r in results])
    lo = np.where(s > 0, sps.beta.ppf(alpha, np.maximum(s, 1), t - s + 1), 0.0)
    hi = np.where(s < t, sps.beta.isf(alpha, s + 1, np.maximum(t - s, 1)), 1.0)
    return (t[:, None] > 0) & (t[None, :] > 0) & (lo[:, None] > hi[None, :])


def close_certificates(certified: np.ndarray, top_k: int
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Consequences of the certificates ``certified`` (n, n) bool, [i, j]: i above j.

    Returns (closed, inside, outside): the transitive closure, with every candidate in the
    top k placed above every candidate out of it; inside (n,) bool: certified above
    n - top_k others; outside: certified below top_k others.
    """
    n = len(certified)
    closed = certified.copy()
    while True:
        for k in range(n):  # Warshall
            closed |= closed[:, k, None] & closed[None, k, :]
        np.fill_diagonal(closed, False)  # a cycle (only after a wrong certificate)
        inside = closed.sum(axis=1) >= n - top_k
        outside = closed.sum(axis=0) >= top_k
        grown = closed | (inside[:, None] & outside[None, :])
        np.fill_diagonal(grown, False)
        if (grown == closed).all():
            return closed, inside, outside
        closed = grown


def boundary(closed: np.ndarray, inside: np.ndarray, outside: np.ndarray,
             p_hat: np.ndarray, top_k: int) -> tuple[np.ndarray, np.ndarray]:
    """The current top k (certified in first, then the undecided by estimated P(FC), then the
    certified out; (top_k,) indices) and the candidates of the uncertified pairs across it
    ((n,) bool): the ones whose draws can still separate it."""
    p = np.where(np.isnan(p_hat), -1.0, p_hat)
    rank = np.lexsort((np.arange(len(p)), -p, outside, ~inside))
    top, rest = rank[:top_k], rank[top_k:]
    open_pairs = ~closed[np.ix_(top, rest)]
    needed = np.zeros(len(p), dtype=bool)
    needed[top] = open_pairs.any(axis=1)
    needed[rest] = open_pairs.any(axis=0)
    return top, needed


def may_draw(closed: np.ndarray, inside: np.ndarray, outside: np.ndarray) -> np.ndarray:
    """(n,) bool, the candidates that can be needed again: the undecided and those with an
    uncertified pair with one of them (pairs between decided ones are settled)."""
    undecided = ~(inside | outside)
    related = closed | closed.T
    return undecided | (~related & undecided[None, :]).any(axis=1)


class AdaptiveRun:
    """The state of an adaptive ranking: every candidate's draws, the paired counts and the
    certificates so far (see the module docstring)."""

    def __init__(self, n_candidates: int, evaluator: Evaluator, max_chunks: int,
                 top_k: int, delta: float) -> None:
        self.evaluator, self.max_chunks, self.top_k = evaluator, max_chunks, top_k
        self.results = [CandidateResult(i) for i in range(n_candidates)]
        self.pairs = PairedDraws(n_candidates)
        self.paired: bool | None = None  # known after the first draw
        self.delta = delta
        self.certified = np.zeros((n_candidates, n_candidates), dtype=bool)
        self.closed = self.certified.copy()
        self.inside = np.zeros(n_candidates, dtype=bool)
        self.outside = np.zeros(n_candidates, dtype=bool)

    @property
    def alpha(self) -> float:
        """The level of each test (pairs and chunk marks, or candidates, sides and marks)."""
        n = len(self.results)
        if self.paired is False:
            return self.delta / (2 * n * self.max_chunks)
        return sign_test_level(n, self.max_chunks, self.delta)

    def draw(self, index: int) -> int:
        """Candidate ``index``'s next chunk; returns its draws."""
        result = self.results[index]
        value = self.evaluator(index, result.chunks, 1)
        paired = len(value) == 4
        if len(value) not in (3, 4) or self.paired not in (None, paired):
            raise ValueError("the evaluator must return (successes, trials, moments) or "
                             "(successes, trials, moments, outcomes), the same for every "
                             f"chunk; got {len(value)} values")
        self.paired = paired
        successes, trials = int(value[0]), int(value[1])
        result.add(successes, trials, value[2], 1)
        if paired:
            outcomes = np.asarray(value[3], dtype=bool)
            if outcomes.shape != (trials,) or int(outcomes.sum()) != successes:
                raise ValueError(f"candidate {index}: {outcomes.shape} per-draw outcomes with "
                                 f"{int(outcomes.sum())} successes for {successes} successes "
                                 f"in {trials} draws")
            self.pairs.add(index, outcomes)
        return trials

    def decide(self) -> None:
        """New certificates from the draws so far, and their consequences."""
        if self.paired:
            new = sign_test_certifies(self.pairs.wins, self.pairs.wins.T, self.alpha)
        else:
            new = unpaired_certifies(self.results, self.alpha)
        self.certified |= new
        self.closed, self.inside, self.outside = close_certificates(self.certified,
                                                                    self.top_k)

    @property
    def separated(self) -> bool:
        n = len(self.results)
        return bool(self.inside.sum() >= self.top_k or self.outside.sum() >= n - self.top_k)

    def boundary(self) -> tuple[np.ndarray, np.ndarray]:
        """(top k indices, candidates needed to separate it): :func:`boundary`."""
        p_hat = np.array([r.p_fc for r in self.results])
        return boundary(self.closed, self.inside, self.outside, p_hat, self.top_k)

    def owed(self) -> int:
        """Chunks that may still be drawn (candidates that may be needed again)."""
        chunks = np.array([r.chunks for r in self.results])
        left = self.max_chunks - chunks
        return int(left[may_draw(self.closed, self.inside, self.outside)].sum())


def rank_adaptive(n_candidates: int, evaluator: Evaluator | PairedEvaluator, max_chunks: int,
                  chunk_size: int, *, top_k: int = 1, delta: float = 0.05,
                  criterion: str = "pfc",
                  progress: Callable[[AdaptiveProgress], None] | None = None
                  ) -> AdaptiveReport:
    """The top ``top_k`` candidates by P(FC), certified at confidence 1 - ``delta`` on paired
    draws (module docstring: method and guarantee).

    Round r draws every candidate of an uncertified pair across the current top-k boundary
    up to r chunks (all candidates in round 1), then certifies; the run stops when the top k
    is separated or after ``max_chunks`` rounds. Chunk c is the same noise for every
    candidate and whichever process draws it, so the result depends only on the evaluator's
    draws, not on where they run. The tests are exact for independent draws (the ``mc``
    sampler that ``kinegrasp rank`` uses), not for antithetic or Sobol chunks.

    Args:
        n_candidates: number of candidates.
        evaluator: draws chunks of a candidate; with per-draw outcomes
            (:data:`PairedEvaluator`) the tests are paired, without (:data:`Evaluator`) they
            compare unpaired intervals (valid, more draws).
        max_chunks: per-candidate budget (the fixed-n run uses exactly this many chunks).
        chunk_size: draws per chunk (for the report and the progress bound).
        top_k: size of the set to separate.
        delta: allowed probability of a certified (``separated``) top k being wrong.
        criterion: the final ordering (separation is always decided on P(FC)).
        progress: called with an :class:`AdaptiveProgress` after every chunk drawn and after
            every round.
    """
    if not 1 <= top_k < n_candidates:
        raise ValueError(f"top_k must be between 1 and {n_candidates - 1}, got {top_k}")
    if not 0 < delta < 1:
        raise ValueError(f"delta must be in (0, 1), got {delta}")
    if criterion not in CRITERIA:
        raise ValueError(f"unknown criterion {criterion!r}; choose from {CRITERIA}")
    if max_chunks < 1:
        raise ValueError(f"max_chunks must be at least 1, got {max_chunks}")
    run = AdaptiveRun(n_candidates, evaluator, max_chunks, top_k, delta)
    draws, rounds, owed = 0, 0, n_candidates * max_chunks
    needed = np.ones(n_candidates, dtype=bool)

    def report(undecided: int, round_done: bool) -> None:
        if progress is not None:
            progress(AdaptiveProgress(draws, draws + owed * chunk_size, rounds, max_chunks,
                                      undecided, round_done))

    while rounds < max_chunks:
        drawing = [int(i) for i in np.flatnonzero(needed)]
        for i in drawing:
            while run.results[i].chunks <= rounds:  # catch up to rounds + 1 chunks
                draws += run.draw(i)
                owed -= 1
                report(len(drawing), False)
        rounds += 1
        run.decide()
        top, needed = run.boundary()
        separated = run.separated
        owed = 0 if separated or rounds == max_chunks else run.owed()
        report(0 if separated else int((~(run.inside | run.outside)).sum()), True)
        if separated:
            break
    return AdaptiveReport(order(run.results, criterion), [int(i) for i in top], separated,
                          rounds, draws, n_candidates * max_chunks * chunk_size,
                          bool(run.paired), run.alpha)
