"""Certificates of adaptive ranking: exact tests on paired draws, their consequences, and an
order of the candidates that none of them contradicts.

Two candidates i, j drawn on the same noise (common random numbers) give n i.i.d. pairs of
force-closure outcomes (X_i, X_j). Of them, M are discordant (exactly one holds) and B of
those have i holding: M ~ Binomial(n, pi), B | M ~ Binomial(M, theta), with pi = P(X_i !=
X_j), theta = P(X_i = 1 | X_i != X_j), and P(FC)_i - P(FC)_j = pi (2 theta - 1). Two kinds
of claims about the ordered pair (i, j) are certified from (B, M, n):

* strict, "P(FC)_i > P(FC)_j": the exact one-sided sign test (McNemar), P(Bin(M, 1/2) >= B)
  <= a (:func:`sign_test_certifies`);
* within eps, "P(FC)_i > P(FC)_j - eps": the lower bound L = min(0, 2 theta_lo - 1) pi_hi
  exceeds -eps, with theta_lo, pi_hi exact (Clopper-Pearson) one-sided bounds at a / 2 each
  (:func:`difference_lower_bound`).

Each is false with probability at most a (proof in :mod:`kinegrasp_env.toolkit.ranking`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special
from scipy import stats as sps


def sign_test_level(n_candidates: int, max_chunks: int, delta: float) -> float:
    """Level alpha of each paired test: ``delta`` shared by every ordered pair of candidates
    and every chunk mark a pair can be tested at (union bound)."""
    return delta / (n_candidates * (n_candidates - 1) * max_chunks)


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


def difference_lower_bound(wins: np.ndarray, losses: np.ndarray, draws: np.ndarray,
                           alpha: float) -> np.ndarray:
    """One-sided lower bound on P(FC)_i - P(FC)_j from ``draws`` paired draws, below the truth
    with probability >= 1 - ``alpha`` (arrays of one shape; ``draws`` 0: no bound, -1).

    L = min(0, 2 theta_lo - 1) pi_hi, theta_lo the exact lower bound on the win rate
    (:func:`win_rate_bounds`) and pi_hi the exact upper bound on the discordance rate, at
    alpha / 2 each. Both hold with probability >= 1 - alpha, and then, as pi <= pi_hi and
    theta >= theta_lo: pi (2 theta - 1) >= pi (2 theta_lo - 1) >= L when 2 theta_lo < 1,
    and >= 0 = L otherwise.
    """
    wins, losses, draws = (np.asarray(a, dtype=np.int64) for a in (wins, losses, draws))
    m = wins + losses
    half = alpha / 2
    # Beta quantiles (Clopper-Pearson); the upper one as 1 - the Beta(b, a) lower quantile
    theta_lo = np.where(wins > 0, special.betaincinv(np.maximum(wins, 1), losses + 1, half),
                        0.0)
    pi_hi = np.where(m < draws,
                     1.0 - special.betaincinv(np.maximum(draws - m, 1), m + 1, half), 1.0)
    return np.minimum(0.0, 2 * theta_lo - 1) * pi_hi


def paired_certificates(wins: np.ndarray, draws: np.ndarray, alpha: float, epsilon: float
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(strict, within) (n, n) bool certificates of every ordered pair, each test at level
    ``alpha``; ``wins`` (n, n): draws on which i holds and j fails; ``draws`` (n, n): the
    pair's common draws. ``epsilon`` 0: the sign test at alpha, within = strict. Otherwise
    one bound per ordered pair at alpha (two halves): strict where theta_lo > 1/2 (the sign
    test at alpha / 2), within where :func:`difference_lower_bound` exceeds -epsilon."""
    losses = wins.T
    if epsilon == 0:
        strict = sign_test_certifies(wins, losses, alpha)
        return strict, strict.copy()
    strict = sign_test_certifies(wins, losses, alpha / 2)
    within = strict | (difference_lower_bound(wins, losses, draws, alpha) > -epsilon)
    np.fill_diagonal(within, False)
    return strict, within


class PairedDraws:
    """Per-draw force-closure outcomes of every candidate, chunk by chunk (chunk c is the
    same noise for all), and per ordered pair the discordant counts on their common chunks.

    Attributes:
        wins: (n, n) int, draws of the common chunks on which i holds and j fails.
        marks: (n, n) int, common chunks of i and j (the number the pair is tested on).
        draws: (n, n) int, the draws of those common chunks.
    """

    def __init__(self, n_candidates: int) -> None:
        self.chunks: list[list[np.ndarray]] = [[] for _ in range(n_candidates)]
        self.wins = np.zeros((n_candidates, n_candidates), dtype=np.int64)
        self.marks = np.zeros((n_candidates, n_candidates), dtype=np.int64)
        self.draws = np.zeros((n_candidates, n_candidates), dtype=np.int64)

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
            self.draws[index, j] += outcomes.size
            self.draws[j, index] = self.draws[index, j]


def unpaired_certificates(successes: np.ndarray, trials: np.ndarray, alpha: float,
                          epsilon: float) -> tuple[np.ndarray, np.ndarray]:
    """(strict, within) (n, n) bool for evaluators without per-draw outcomes: i's exact lower
    bound above j's upper bound (strict), or above it less ``epsilon`` (within); each bound
    one-sided Clopper-Pearson at ``alpha``; ``successes``, ``trials``: (n,) int."""
    s, t = np.asarray(successes), np.asarray(trials)
    lo = np.where(s > 0, special.betaincinv(np.maximum(s, 1), t - s + 1, alpha), 0.0)
    hi = np.where(s < t, 1.0 - special.betaincinv(np.maximum(t - s, 1), s + 1, alpha), 1.0)
    drawn = (t[:, None] > 0) & (t[None, :] > 0)
    strict = drawn & (lo[:, None] > hi[None, :])
    within = drawn & (lo[:, None] > hi[None, :] - epsilon)
    np.fill_diagonal(within, False)
    return strict, within


def close_certificates(certified: np.ndarray, top_k: int
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Consequences of the strict certificates ``certified`` (n, n) bool, [i, j]: i above j.

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


def close_within(closed: np.ndarray, within: np.ndarray) -> np.ndarray:
    """(n, n) bool, the within-epsilon claims implied by strict ``closed`` (transitive) and
    ``within`` ones: chains strict* within strict* (P_i > P_a > P_b - eps > P_j - eps)."""
    n = len(closed)
    step = (closed | np.eye(n, dtype=bool)).astype(np.int64)
    out = (step @ (within | closed).astype(np.int64) @ step) > 0
    np.fill_diagonal(out, False)
    return out


def linear_extension(closed: np.ndarray, keys: list) -> list[int]:
    """Indices in an order that lists every i before every j with ``closed[i, j]`` (strict
    certificates), otherwise by ascending ``keys`` (one sortable key per candidate); a
    cycle (only after a wrong certificate) is broken at its smallest key."""
    n = len(closed)
    left = set(range(n))
    out: list[int] = []
    while left:
        free = [i for i in left if not any(closed[j, i] for j in left if j != i)]
        best = min(free or left, key=lambda i: keys[i])
        out.append(best)
        left.remove(best)
    return out


def check_levels(epsilon: float, delta: float, names: tuple[str, str] = ("epsilon", "delta")
                 ) -> None:
    """ValueError (one line, naming the value as ``names`` name them: a command's
    ``--epsilon``) unless the certificate's margin is 0 <= epsilon < 1 (of P(FC), or of the
    score ranked) and its error level 0 < delta < 1: the rule of every certificate (adaptive
    ranking, elbow and branch searches)."""
    def shown(value) -> str:
        return f"{value:g}" if isinstance(value, int | float) else repr(value)

    if not (isinstance(epsilon, int | float) and math.isfinite(epsilon) and 0 <= epsilon < 1):
        raise ValueError(f"{names[0]} must be a margin in [0, 1), got {shown(epsilon)}")
    if not (isinstance(delta, int | float) and math.isfinite(delta) and 0 < delta < 1):
        raise ValueError(f"{names[1]} must be an error level in (0, 1), got {shown(delta)}")
