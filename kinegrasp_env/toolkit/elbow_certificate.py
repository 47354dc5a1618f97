"""The elbow certificate: how much better than the chosen angle another evaluated angle can be.

The elbow optimizer chooses the angle b with the highest P(FC) on its selection draws. The
certificate is computed on **fresh draws** (independent of the selection, common random
numbers across the angles: draw i is the same joint noise at every angle), and says:

    with confidence 1 - delta, no evaluated angle j beats b by more than B in P(FC),
    i.e. max_j (p_j - p_b) <= B,

where B is the largest of the rivals' one-sided upper confidence bounds U_j on p_j - p_b,
each at level delta. It is *certified at epsilon* when B <= epsilon.

**The bound of one rival** (exact at every n). On the fresh draws, a rival j *wins* draw i when
it is in force closure and b is not, *loses* it in the opposite case. With n draws, wins ~
Binomial(n, p_win) and losses ~ Binomial(n, p_loss), and p_j - p_b = p_win - p_loss. The
bound is U_j = CP_up(wins; delta/2) - CP_low(losses; delta/2), the Clopper-Pearson one-sided
bounds: each fails with probability at most delta/2 whatever the true p (they are exact
binomial tail inversions, not normal approximations), so U_j < p_j - p_b with probability at
most delta. It uses the discordant pairs only, as McNemar's test does, so common random
numbers make it tight; a paired t-bound would be tighter still but is not valid for few
discordant pairs (with none it gives U = 0, whatever the true p_win).

**Why the largest bound needs no multiplicity correction.** The claim is about the maximum.
Let j* be the rival with the largest true p_j - p_b (a fixed angle: b is fixed by the
selection draws, which the fresh draws do not depend on). The claim max_j (p_j - p_b) <= B
can fail only if U_{j*} < p_{j*} - p_b, since B >= U_{j*}: one bound, probability at most
delta. (This is the intersection-union argument; a Holm or Bonferroni correction over the
rivals would be needed for angle-by-angle claims, which are not made.) Angles between the
evaluated ones are not covered.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.toolkit.certificates import check_levels

#: Default indifference margin in P(FC): "certified" when no evaluated angle can beat the
#: chosen one by more than this.
DEFAULT_EPSILON = 0.05
#: Default error level of the certificate (95% confidence).
DEFAULT_DELTA = 0.05
#: The method, in words (printed with the certificate).
METHOD = "one-sided exact Clopper-Pearson bounds on the wins and losses of each rival"


def rounded_up(x: float, digits: int = 3) -> float:
    """x rounded up to ``digits`` decimals (so a printed bound never claims more than the
    computed one)."""
    scale = 10.0 ** digits
    return math.ceil(round(x * scale, 6)) / scale


def clopper_pearson_upper(k: np.ndarray, n: int, alpha: float) -> np.ndarray:
    """One-sided exact upper (1 - alpha) bounds on a binomial p from k (any shape) of n."""
    from scipy import stats as sps  # imported when used: the CLI's parser reads this module

    k = np.asarray(k)
    return np.where(k >= n, 1.0, sps.beta.ppf(1 - alpha, k + 1, np.maximum(n - k, 1)))


def clopper_pearson_lower(k: np.ndarray, n: int, alpha: float) -> np.ndarray:
    """One-sided exact lower (1 - alpha) bounds on a binomial p from k (any shape) of n."""
    from scipy import stats as sps

    k = np.asarray(k)
    return np.where(k <= 0, 0.0, sps.beta.ppf(alpha, np.maximum(k, 1), n - k + 1))


def difference_upper_bound(wins: np.ndarray, losses: np.ndarray, n: int,
                           delta: float) -> np.ndarray:
    """One-sided (1 - delta) upper bounds on p_rival - p_chosen from paired draws: wins and
    losses (same shape) are each rival's discordant counts over n common draws."""
    return (clopper_pearson_upper(wins, n, delta / 2)
            - clopper_pearson_lower(losses, n, delta / 2))


@dataclass
class Rival:
    """One other evaluated angle on the fresh draws (psi in radians)."""

    psi: float
    p_fc: float        # its P(FC) on the fresh draws
    wins: int | None   # fresh draws in force closure here and not at the chosen angle
    losses: int | None  # the opposite (both None where the bound is not a binomial one)
    difference: float  # (wins - losses) / n: its estimated advantage over the chosen angle
    upper: float       # one-sided (1 - delta) upper bound on that advantage

    def to_json(self) -> dict:
        return {"psi": self.psi, "p_fc": self.p_fc, "wins": self.wins, "losses": self.losses,
                "difference": self.difference, "upper": self.upper}


@dataclass
class Certificate:
    """How much better than the chosen angle any evaluated angle can be (module docstring)."""

    chosen_psi: float
    epsilon: float
    delta: float
    draws: int                 # fresh draws per angle
    rivals: list[Rival]
    bound: float | None        # B = max of the rivals' upper bounds (None: no rival)
    worst_psi: float | None    # the rival attaining B
    certified: bool            # B <= epsilon (or no rival)
    method: str = METHOD       # how each rival's bound was computed, in words

    @property
    def confidence(self) -> str:
        """1 - delta in percent, e.g. ``95%``."""
        return f"{100 * (1 - self.delta):.4g}%"

    def statement(self) -> str:
        """The claim in words, exactly as it is meant (angles in radians)."""
        if self.bound is None:
            return f"psi = {self.chosen_psi:+.3f} rad is the only evaluated elbow angle"
        shown = rounded_up(self.bound)
        if shown < 0:
            return (f"with {self.confidence} confidence every other evaluated elbow angle has "
                    f"a P(FC) at least {-shown:.3f} below that of psi = "
                    f"{self.chosen_psi:+.3f} rad")
        return (f"with {self.confidence} confidence no evaluated elbow angle beats psi = "
                f"{self.chosen_psi:+.3f} rad by more than {shown:.3f} in P(FC)")

    def verdict(self) -> str:
        """Certified at epsilon or not, and on what evidence."""
        if self.bound is None:
            return "certified (nothing to compare)"
        evidence = (f"{len(self.rivals)} other angles, {self.draws} fresh draws each, "
                    f"{self.method}")
        if self.certified:
            return f"certified at epsilon {self.epsilon:g} ({evidence})"
        return (f"not certified at epsilon {self.epsilon:g}: psi = {self.worst_psi:+.3f} rad "
                f"may beat it by up to {rounded_up(self.bound):.3f} ({evidence})")

    def to_json(self) -> dict:
        return {"statement": self.statement(), "certified": self.certified,
                "epsilon": self.epsilon, "delta": self.delta, "bound": self.bound,
                "worst_psi": self.worst_psi, "chosen_psi": self.chosen_psi,
                "fresh_draws": self.draws, "method": self.method,
                "rivals": [r.to_json() for r in self.rivals]}


def certify(chosen_psi: float, chosen_fc: np.ndarray, rival_psis: list[float],
            rival_fc: np.ndarray, epsilon: float = DEFAULT_EPSILON,
            delta: float = DEFAULT_DELTA) -> Certificate:
    """The certificate of the chosen angle from fresh draws.

    Args:
        chosen_psi: the chosen elbow angle (radians).
        chosen_fc: (n,) bool, force closure of the chosen angle on each fresh draw.
        rival_psis: the other evaluated angles (m,), radians.
        rival_fc: (m, n) bool, their force closure on the same fresh draws.
        epsilon: the margin at which the certificate is certified.
        delta: its error level.
    """
    check_levels(epsilon, delta)
    chosen_fc = np.asarray(chosen_fc, dtype=bool)
    rival_fc = np.asarray(rival_fc, dtype=bool).reshape(len(rival_psis), chosen_fc.size)
    n = chosen_fc.size
    if n < 1:
        raise ValueError("the certificate needs at least one fresh draw")
    wins = (rival_fc & ~chosen_fc).sum(axis=1)
    losses = (~rival_fc & chosen_fc).sum(axis=1)
    upper = difference_upper_bound(wins, losses, n, delta)
    rivals = [Rival(float(psi), float(fc.mean()), int(w), int(lo), float((w - lo) / n),
                    float(u))
              for psi, fc, w, lo, u in zip(rival_psis, rival_fc, wins, losses, upper,
                                           strict=True)]
    if not rivals:
        return Certificate(float(chosen_psi), float(epsilon), float(delta), n, [], None,
                           None, True)
    worst = max(rivals, key=lambda r: r.upper)
    return Certificate(float(chosen_psi), float(epsilon), float(delta), n, rivals,
                       worst.upper, worst.psi, worst.upper <= epsilon)
