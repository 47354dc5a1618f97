"""Choose on one set of draws, report on another.

Picking the most and the least robust of several candidates by their P(FC) estimates and then
quoting those same estimates overstates the gap between them: the maximum of noisy estimates
is biased up, the minimum down (the winner's curse), even when every candidate has the same
true P(FC). So every "robust" / "fragile" choice of the paper's experiments (Fig. 7, Fig. 10)
is made on the **selection draws** and the numbers printed for the chosen candidates come
from **fresh draws** the choice never saw.

Seed streams: with ``samples`` draws in K chunks of ``chunk`` draws, the selection uses chunks
``0..K-1`` of the run seed (chunk c draws from ``SeedSequence(seed, spawn_key=(c,))``, as
every evaluation does) and the report chunks ``K..2K-1`` of the same seed, the rule
``kinegrasp elbow`` follows for its best angle too (a run by rows: :func:`report_rows`). The
two sets of draws never overlap, the
same seed gives the same numbers, and the chosen pair shares its fresh draws (common random
numbers), so their difference is a paired one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.sampling.noise_model import STREAM_CHUNK
from kinegrasp_env.sampling.stats import paired_interval


def report_chunks(samples: int, chunk: int = STREAM_CHUNK) -> tuple[int, int]:
    """(first, count) of the chunks that hold the fresh draws of a ``samples``-draw
    selection: the selection uses chunks ``0..count-1``, the report ``first..first+count-1``
    with ``first = count``."""
    count = math.ceil(samples / chunk)
    return count, count


def report_rows(samples: int) -> int:
    """The first row of the fresh draws of a ``samples``-draw selection in a run's rows (row
    r: row r % STREAM_CHUNK of chunk r // STREAM_CHUNK's stream, as a description robot's
    runs draw them: :func:`~kinegrasp_env.sampling.noise_model.stream_rows`): the first
    row of :func:`report_chunks`' first chunk, so that rows ``report_rows(samples) ..`` +
    samples are the report chunks' draws."""
    first, _ = report_chunks(samples, STREAM_CHUNK)
    return first * STREAM_CHUNK


def extremes(estimates: Sequence[float]) -> tuple[int, int]:
    """(index of the largest, index of the smallest) of ``estimates``: the first largest,
    and the first smallest among the others (two different candidates even when all tie)."""
    if len(estimates) < 2:
        raise ValueError(f"choosing a robust and a fragile candidate needs at least 2, got "
                         f"{len(estimates)}")
    values = list(estimates)
    best = values.index(max(values))
    worst = min((i for i in range(len(values)) if i != best), key=values.__getitem__)
    return best, worst


@dataclass(frozen=True)
class ChosenPair:
    """The robust and the fragile candidate of a selection, with their fresh evaluations.

    Attributes:
        robust, fragile: the candidates' indices (the largest and the smallest selection
            estimate: :func:`extremes`).
        fresh: the two fresh evaluations, robust first (each with ``draws.outcome``, shape
            (samples,)).
        gap, gap_lo, gap_hi: robust minus fragile P(FC) on the shared fresh draws and its
            paired Student-t 95% interval.
    """

    robust: int
    fragile: int
    fresh: tuple[Any, Any]
    gap: float
    gap_lo: float
    gap_hi: float


def robust_fragile(selection: Sequence[float], report: Callable[[int], Any]) -> ChosenPair:
    """The most and the least robust candidate by their P(FC) on the selection draws
    (``selection[i]``: candidate i's estimate), reported on fresh draws: ``report(i)`` is
    candidate i evaluated on the draws after the selection's (the same draws for both, so
    their difference is a paired one)."""
    best, worst = extremes(selection)
    fresh = (report(best), report(worst))
    fc = [(f.draws.outcome == FORCE_CLOSURE).astype(float) for f in fresh]
    gap, lo, hi = paired_interval(fc[0] - fc[1])
    return ChosenPair(best, worst, fresh, gap, lo, hi)


def provenance(samples: int, seed: int, chunk: int = STREAM_CHUNK,
               batch: int | None = None) -> str:
    """The one-line statement of where a chosen pair's numbers come from (``batch``: the
    closings of one re-weighted batch the choice was made on, instead of draws per
    candidate)."""
    first, count = report_chunks(samples, chunk)

    def span(start: int, n: int) -> str:
        return f"chunk {start}" if n == 1 else f"chunks {start}-{start + n - 1}"

    chosen = (f"chosen on {samples} draws per candidate (seed {seed}, {span(0, count)})"
              if batch is None else
              f"chosen on one batch of {batch} closings re-weighted to every candidate "
              f"(seed {seed})")
    return f"{chosen}, reported on {samples} fresh draws ({span(first, count)})"


def interval_words(gap: float, lo: float, hi: float) -> str:
    """What to print of a paired difference's t-interval (lo, hi): ``95% CI +0.040 ..
    +0.074``; where it is a point (no spread to use), ``no discordant draw`` (every pair
    agrees) or ``every pair of draws differs alike``; ``no interval from one draw`` (its ends
    infinite)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return "no interval from one draw"
    if lo == hi:
        return "no discordant draw" if gap == 0 else "every pair of draws differs alike"
    return f"95% CI {lo:+.3f} .. {hi:+.3f}"


def format_gap(row: dict) -> str:
    """``+0.057 (95% CI +0.040 .. +0.074)`` of a robust/fragile row's paired gap, its
    interval as :func:`interval_words` says it."""
    if math.isnan(row["gap"]):
        return "n/a"
    return f"{row['gap']:+.3f} ({interval_words(row['gap'], row['gap_lo'], row['gap_hi'])})"
