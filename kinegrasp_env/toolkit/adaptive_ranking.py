"""Adaptive ranking of grasp candidates: a certified top k on paired draws.

The method (:func:`rank_adaptive`): PAC top-k identification on paired draws, with an
indifference zone epsilon (as LUCB, Kalyanakrishnan et al. 2012: a set of k candidates each
of whose P(FC) is within epsilon of the true k-th best; epsilon 0: exactly the top k). Every
candidate draws chunk c of the same seed, that is the same joint-noise draws (common random
numbers), so two candidates are compared draw by draw (:mod:`~kinegrasp_env.toolkit.
certificates`): their noise is the pair's discordance, not the variance of each estimate (at
sigma 0.0133 rad neighbouring elbow angles of one grasp disagree on 3-4% of the draws,
different grasps on 25-55%). Claims about an ordered pair (i, j): strict, P_i > P_j (exact
sign test); within, P_i > P_j - epsilon (exact bounds on the win and discordance rates).
Strict claims close under transitivity; a candidate strictly above n - k others is *in*
the top k, one strictly below k others *out*; one within-above n - k others (strict chains
included, :func:`~kinegrasp_env.toolkit.certificates.close_within`) is *within epsilon* of
the k-th best. The run stops when k candidates are in or within (or n - k out), or after the
fixed-n budget's number of rounds; round r draws, up to r chunks each, the candidates of the
uncertified pairs across the current top-k boundary (every candidate in round 1).

Guarantee. Each test is run at alpha = delta / (n (n - 1) x chunks), one per ordered pair
and chunk mark (a pair's number of common chunks). Proof: fix the seed; then chunk c of every
candidate is determined whether drawn or not, and within a candidate the draws are
independent (the ``mc`` sampler), so the test of (i, j) at mark c sees a sample of N_c
i.i.d. draw pairs, N_c fixed by the chunk layout. Let F(i, j, c) be the event that this test
certifies a false claim about (i, j). With epsilon 0, P(F) <= alpha: given the M discordant
draws, i's wins are Binomial(M, theta) with theta <= 1/2 when P_i <= P_j, and the sign test
is exact. With epsilon > 0, F implies theta_lo > theta or pi_hi < pi (otherwise a strict
claim means theta >= theta_lo > 1/2, P_i > P_j, and a within claim P_i - P_j >= L >
-epsilon), each of probability <= alpha / 2 (exact one-sided Clopper-Pearson bounds;
theta_lo's holds given M, hence unconditionally). A union bound over the n (n - 1) ordered
pairs and the chunks marks: P(any F) <= delta. A run reads only tests among these (in
whatever order and round; a second look at a mark sees the same draws), so with probability
>= 1 - delta every claim it makes is true. Then so is every consequence: strict claims are
transitive, and strict-within-strict chains give P_i > P_j - epsilon. A candidate strictly
above n - k others has at most k - 1 others at or above it: it is in every top k; strictly
below k others: in none. k candidates in: the n - k below the least of them are not among
them, so they are all the others, each below every one of the k (likewise n - k out). A
candidate i within-above n - k others: if i is not in a true top k T, T lies among the
other n - 1, of which only k - 1 are not within-below i, so P_i > P_t - epsilon >= P_(k) -
epsilon for some t in T. Hence P(a row's certified label is false) <= delta, in a separated
run (its top k) or not (the candidates certified in or out so far). An evaluator without
per-draw outcomes falls back to unpaired bounds (each candidate's exact Clopper-Pearson
bounds, one-sided at delta / (2 n chunks) each), with the same guarantee.

Cost: a boundary pair with P(FC) gap g, discordant on a fraction d of the draws, is certified
after about d (z / (g + epsilon))^2 paired draws, z the normal quantile of alpha (about 4
for 12 candidates, 8 chunks, delta 0.05): epsilon bounds the cost of a near tie, which
without it grows without bound as g -> 0 (``separated`` False at the budget).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.sampling.stats import StreamingMoments
from kinegrasp_env.toolkit.certificates import (
    PairedDraws,
    check_levels,
    close_certificates,
    close_within,
    linear_extension,
    paired_certificates,
    sign_test_level,
    unpaired_certificates,
)
from kinegrasp_env.toolkit.ranking import (
    CRITERIA,
    MEAN_CRITERIA,
    CandidateResult,
    Evaluator,
    PairedEvaluator,
    score,
)

#: The indifference zone of :func:`rank_adaptive` (and ``kinegrasp rank --epsilon``): a
#: certified top k whose members are each within 0.01 of the k-th best P(FC).
DEFAULT_EPSILON = 0.01
#: Labels of the ``certified`` column: in the certified top k; certified out of it (or, once
#: separated, not in it); neither yet.
TOP, REST, UNRESOLVED = "top-k", "rest", "unresolved"


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
        undecided: candidates neither certified in (or within epsilon) nor out of the top k
            (0 once separated); in a chunk's report (``round_done`` False): the candidates
            drawing this round.
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
        results: every candidate's draws in the order to show them: the certified top k
            (``certified`` "top-k"), then the unresolved, then the rest; within each, an
            order that lists every strictly certified pair the right way round, otherwise
            by the criterion.
        certified: (n,) label of each entry of ``results``: :data:`TOP`, :data:`REST` or
            :data:`UNRESOLVED` (see :data:`TOP`).
        top: the indices of the first k entries of ``results``: the certified top k when
            ``separated`` (each within ``epsilon`` of the true k-th best P(FC), wrong with
            probability <= ``delta``), else the certified ones and the best estimates.
        separated: the top k is certified.
        rounds, draws: rounds run and draws made (all candidates); fixed_draws: the fixed-n
            run's draws (candidates x chunks x chunk size).
        paired: certified on paired draws (sign tests) rather than unpaired intervals.
        alpha: the level of each test (delta over ordered pairs and chunk marks).
        delta, epsilon: the run's error probability and indifference zone.
        strict: (n, n) bool by candidate index, [i, j]: certified P(FC)_i > P(FC)_j
            (closed under transitivity); ``results`` lists no such j before its i.
        measure: what was certified, in words: ``P(FC)``, or a hold score's probability
            (:data:`CERTIFIED_HOLDS`; then read P(FC) above as it).
    """

    results: list[CandidateResult]
    top: list[int]
    separated: bool
    rounds: int
    draws: int
    fixed_draws: int
    paired: bool = True
    alpha: float = math.nan
    certified: list[str] = field(default_factory=list)
    delta: float = math.nan
    epsilon: float = 0.0
    strict: np.ndarray | None = None
    measure: str = "P(FC)"


def boundary(relation: np.ndarray, inside: np.ndarray, outside: np.ndarray,
             p_hat: np.ndarray, top_k: int, done_inside: bool = False
             ) -> tuple[np.ndarray, np.ndarray]:
    """The current top k (certified in first, then the undecided by estimated P(FC), then the
    certified out; (top_k,) indices) and the candidates of the pairs across it whose claim
    ``relation[top, rest]`` is not certified ((n,) bool): the ones whose draws can still
    separate it. ``done_inside``: a certified-in member needs no more claims (epsilon > 0:
    being within-above n - k others is all it needs)."""
    p = np.where(np.isnan(p_hat), -1.0, p_hat)
    rank = np.lexsort((np.arange(len(p)), -p, outside, ~inside))
    top, rest = rank[:top_k], rank[top_k:]
    open_pairs = ~relation[np.ix_(top, rest)]
    if done_inside:
        open_pairs &= ~inside[top, None]
    needed = np.zeros(len(p), dtype=bool)
    needed[top] = open_pairs.any(axis=1)
    needed[rest] = open_pairs.any(axis=0)
    return top, needed


def may_draw(relation: np.ndarray, inside: np.ndarray, outside: np.ndarray,
             directed: bool = False) -> np.ndarray:
    """(n,) bool, the candidates that can be needed again: the undecided and those with an
    uncertified pair with one of them (pairs between decided ones are settled); ``directed``
    (epsilon > 0, where ``relation`` is not an order): uncertified from an undecided one to
    them."""
    undecided = ~(inside | outside)
    if directed:
        return undecided | (undecided[:, None] & ~relation).any(axis=0)
    related = relation | relation.T
    return undecided | (~related & undecided[None, :]).any(axis=1)


class AdaptiveRun:
    """The state of an adaptive ranking: every candidate's draws, the paired counts and the
    certificates so far (see the module docstring)."""

    def __init__(self, n_candidates: int, evaluator: Evaluator, max_chunks: int,
                 top_k: int, delta: float, epsilon: float = 0.0) -> None:
        self.evaluator, self.max_chunks, self.top_k = evaluator, max_chunks, top_k
        self.results = [CandidateResult(i) for i in range(n_candidates)]
        self.pairs = PairedDraws(n_candidates)
        self.paired: bool | None = None  # known after the first draw
        self.delta, self.epsilon = delta, epsilon
        empty = np.zeros((n_candidates, n_candidates), dtype=bool)
        self.certified, self.within = empty.copy(), empty.copy()
        self.closed, self.close_within = empty.copy(), empty.copy()
        self.inside = np.zeros(n_candidates, dtype=bool)
        self.outside = np.zeros(n_candidates, dtype=bool)

    @property
    def alpha(self) -> float:
        """The level of each test (ordered pairs and chunk marks, or candidates, sides and
        marks)."""
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
            strict, within = paired_certificates(self.pairs.wins, self.pairs.draws,
                                                 self.alpha, self.epsilon)
        else:
            strict, within = unpaired_certificates(
                np.array([r.successes for r in self.results]),
                np.array([r.trials for r in self.results]), self.alpha, self.epsilon)
        self.certified |= strict
        self.within |= within
        self.closed, inside, self.outside = close_certificates(self.certified, self.top_k)
        if self.epsilon > 0:
            self.close_within = close_within(self.closed, self.within)
            inside = self.close_within.sum(axis=1) >= len(self.results) - self.top_k
        else:
            self.close_within = self.closed
        self.inside = inside

    @property
    def separated(self) -> bool:
        n = len(self.results)
        return bool(self.inside.sum() >= self.top_k or self.outside.sum() >= n - self.top_k)

    def boundary(self) -> tuple[np.ndarray, np.ndarray]:
        """(top k indices, candidates needed to separate it): :func:`boundary`."""
        p_hat = np.array([r.p_fc for r in self.results])
        return boundary(self.close_within, self.inside, self.outside, p_hat, self.top_k,
                        done_inside=self.epsilon > 0)

    def owed(self) -> int:
        """Chunks that may still be drawn (candidates that may be needed again)."""
        chunks = np.array([r.chunks for r in self.results])
        left = self.max_chunks - chunks
        drawing = may_draw(self.close_within, self.inside, self.outside,
                           directed=self.epsilon > 0)
        return int(left[drawing].sum())

    def table(self, criterion: str) -> tuple[list[CandidateResult], list[str]]:
        """(results, labels) in the order to show them (:class:`AdaptiveReport`)."""
        n = len(self.results)
        p = np.array([r.p_fc for r in self.results])
        p = np.where(np.isnan(p), -1.0, p)
        # an order no strict certificate contradicts, the certified in first, the out last
        ranked = linear_extension(self.closed, [(not self.inside[i], bool(self.outside[i]),
                                                 -p[i], i) for i in range(n)])
        if self.separated:  # the first k in, or else the complement of n - k out
            first = [i for i in ranked if self.inside[i]][:self.top_k]
            if len(first) < self.top_k:
                first = ranked[:self.top_k]
            label = np.full(n, REST, dtype=object)
            label[first] = TOP
        else:
            label = np.where(self.inside, TOP, np.where(self.outside, REST, UNRESOLVED))
        group = {TOP: 0, UNRESOLVED: 1, REST: 2}

        def key(i: int) -> tuple:
            s = score(self.results[i], criterion)
            return (group[label[i]], *((1, 0.0) if math.isnan(s) else (0, -s)), i)

        shown = linear_extension(self.closed, [key(i) for i in range(n)])
        return [self.results[i] for i in shown], [str(label[i]) for i in shown]


#: The hold criteria an adaptive ranking certifies, and what it certifies, in words.
CERTIFIED_HOLDS = {"hold_static": "P(hold, static)", "hold": "P(hold)"}


def certified_successes(criterion: str, fc: np.ndarray, held: dict[str, np.ndarray],
                        moments: StreamingMoments
                        ) -> tuple[int, int, StreamingMoments, np.ndarray]:
    """A paired evaluator's (successes, trials, moments, per-draw successes (n,) bool) of a
    candidate's chunks: force closure ``fc`` (n,) bool, or with a hold criterion
    (:data:`CERTIFIED_HOLDS`) the draws its score held (``held``: ``static`` and ``test``
    -> (n,) bool)."""
    success = fc
    if criterion in CERTIFIED_HOLDS:
        success = held["static" if criterion == "hold_static" else "test"]
    success = np.asarray(success, dtype=bool)
    return int(success.sum()), int(success.size), moments, success


def rank_adaptive(n_candidates: int, evaluator: Evaluator | PairedEvaluator, max_chunks: int,
                  chunk_size: int, *, top_k: int = 1, delta: float = 0.05,
                  epsilon: float = DEFAULT_EPSILON, criterion: str = "pfc",
                  progress: Callable[[AdaptiveProgress], None] | None = None,
                  measure: str = "P(FC)", budget: int | None = None) -> AdaptiveReport:
    """A top ``top_k`` of the candidates by P(FC) (or by what the evaluator's successes
    estimate: ``measure``), each member within ``epsilon`` of the true k-th best, certified
    at confidence 1 - ``delta`` on paired draws (module docstring: method and proof).

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
        budget: draws per candidate of the fixed-n run, for the report (default
            ``max_chunks * chunk_size``; less where the last chunk is smaller).
        top_k: size of the set to separate.
        delta: allowed probability of a certified label being wrong.
        epsilon: indifference zone in P(FC), >= 0 (0: exactly the top k, which a near tie
            at the boundary may keep from being certified within any budget).
        criterion: the order within each certified group (certificates are on the
            evaluator's successes).
        progress: called with an :class:`AdaptiveProgress` after every chunk drawn and after
            every round.
        measure: what the evaluator's successes estimate, in words (``P(FC)``; a hold
            score's, :data:`CERTIFIED_HOLDS`), for the report.
    """
    if not 1 <= top_k < n_candidates:
        raise ValueError(f"top_k must be between 1 and {n_candidates - 1}, got {top_k}")
    check_levels(epsilon, delta)
    if criterion not in CRITERIA:
        raise ValueError(f"unknown criterion {criterion!r}; choose from {CRITERIA}")
    if criterion in MEAN_CRITERIA:
        raise ValueError(f"criterion {criterion!r} ranks by a mean, which the adaptive run "
                         "cannot certify (its tests count successes); rank it at fixed n")
    if max_chunks < 1:
        raise ValueError(f"max_chunks must be at least 1, got {max_chunks}")
    run = AdaptiveRun(n_candidates, evaluator, max_chunks, top_k, delta, float(epsilon))
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
        _, needed = run.boundary()
        separated = run.separated
        owed = 0 if separated or rounds == max_chunks else run.owed()
        report(0 if separated else int((~(run.inside | run.outside)).sum()), True)
        if separated:
            break
    results, labels = run.table(criterion)
    return AdaptiveReport(results, [r.index for r in results[:top_k]], separated, rounds,
                          draws, n_candidates * (max_chunks * chunk_size if budget is None
                                                 else budget), bool(run.paired),
                          run.alpha, labels, delta, float(epsilon), run.closed.copy(),
                          measure)
