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
``kinegrasp elbow`` follows for its best angle too, for every robot (a description robot's
run by rows: :func:`report_rows`). The two sets of draws never overlap, the
same seed gives the same numbers, and the chosen pair shares its fresh draws (common random
numbers), so their difference is a paired one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import (
    DEFAULT_CHUNK,
    GraspStats,
    chunk_sizes,
    run_chunks,
    summarize,
    validate_request,
)
from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.montecarlo.nominal import nominal_quality
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import STREAM_CHUNK
from kinegrasp_env.sampling.stats import paired_interval
from kinegrasp_env.world.grasps import Grasp

#: ``evaluate(candidate, first_chunk) -> GraspStats`` (with its draws): the candidate's
#: statistics on ``samples`` draws starting at chunk ``first_chunk`` of the run seed.
Evaluator = Callable[[Grasp, int], GraspStats]


def report_chunks(samples: int, chunk: int = DEFAULT_CHUNK) -> tuple[int, int]:
    """(first, count) of the chunks that hold the fresh draws of a ``samples``-draw
    selection: the selection uses chunks ``0..count-1``, the report ``first..first+count-1``
    with ``first = count``."""
    count = len(chunk_sizes(samples, chunk))
    return count, count


def report_rows(samples: int) -> int:
    """The first row of the fresh draws of a ``samples``-draw selection in a run's rows (row
    r: row r % STREAM_CHUNK of chunk r // STREAM_CHUNK's stream, as a description robot's
    runs draw them: :func:`~kinegrasp_env.sampling.noise_model.stream_rows`): the first
    row of :func:`report_chunks`' first chunk, so that rows ``report_rows(samples) ..`` +
    samples are the report chunks' draws."""
    first, _ = report_chunks(samples, STREAM_CHUNK)
    return first * STREAM_CHUNK


def stats_from_chunk(grasp: Grasp, noise: JointNoise, samples: int, seed: int,
                     first_chunk: int, *, engine: str = "fast",
                     executor: Executor | None = None, chunk: int = DEFAULT_CHUNK,
                     return_draws: bool = True, progress=False,
                     friction: float = 0.5) -> GraspStats:
    """:func:`evaluate_grasp`'s statistics of ``grasp`` on ``samples`` draws that start at
    chunk ``first_chunk`` of ``seed`` (``first_chunk = 0``: exactly ``evaluate_grasp``'s
    draws; :func:`report_chunks`' first: the fresh draws)."""
    validate_request(samples, 1, chunk)
    counts, moments, draws = run_chunks(
        grasp, noise, seed, sizes=chunk_sizes(samples, chunk), first_chunk=first_chunk,
        engine=engine, return_draws=return_draws, executor=executor, progress=progress,
        friction=friction)
    return summarize(grasp, noise, seed, engine, counts, moments, draws,
                     q_nominal=nominal_quality(grasp, friction))


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


def _fc(stats: GraspStats) -> np.ndarray:
    return (stats.draws.outcome == FORCE_CLOSURE).astype(float)


def robust_fragile(name: str, candidates: Sequence[Grasp], selection: Sequence[GraspStats],
                   evaluate: Evaluator, samples: int, seed: int,
                   chunk: int = DEFAULT_CHUNK) -> tuple[list[dict], list[GraspStats]]:
    """The most and the least robust of ``candidates`` by their P(FC) on the selection
    draws (``selection[i]`` of ``candidates[i]``, chunks ``0..K-1``), reported on fresh
    draws (``evaluate(candidate, K)``).

    Returns:
        Two rows (``config`` robust, then fragile): ``p_fc``, its Wilson 95% interval
        ``p_fc_lo``/``p_fc_hi``, the moments of Q (``q_mean``, ``q_var``, ``q_skew``, over the
        force-closure draws) and ``samples``, all on the fresh draws; ``selection_p_fc`` and
        ``selection_samples`` (the estimate the choice used); ``gap``, ``gap_lo``, ``gap_hi``:
        robust minus fragile P(FC) on the shared fresh draws with its paired Student-t 95%
        interval; ``selection_gap`` the same difference on the selection draws (biased up).
        And the two fresh :class:`GraspStats` (with their draws).
    """
    if len(candidates) != len(selection):
        raise ValueError(f"{len(candidates)} candidates but {len(selection)} evaluations")
    best, worst = extremes([s.p_fc for s in selection])
    first, _ = report_chunks(samples, chunk)
    fresh = [evaluate(candidates[i], first) for i in (best, worst)]
    gap, lo, hi = paired_interval(_fc(fresh[0]) - _fc(fresh[1]))
    rows = []
    for label, i, stats in (("robust", best, fresh[0]), ("fragile", worst, fresh[1])):
        grasp = candidates[i]
        rows.append({
            "object": name, "config": label, "id": grasp.id,
            "elbow_angle": grasp.meta.get("elbow_angle"), "p_fc": stats.p_fc,
            "p_fc_lo": stats.p_fc_ci[0], "p_fc_hi": stats.p_fc_ci[1],
            "q_mean": stats.q_mean, "q_var": stats.q_var, "q_skew": stats.q_skew,
            "q_nominal": stats.q_nominal, "samples": stats.samples,
            "selection_p_fc": selection[i].p_fc, "selection_samples": selection[i].samples,
            "gap": gap, "gap_lo": lo, "gap_hi": hi,
            "selection_gap": selection[best].p_fc - selection[worst].p_fc})
    return rows, fresh


def provenance(samples: int, seed: int, chunk: int = DEFAULT_CHUNK,
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


def format_gap(row: dict) -> str:
    """``+0.057 (95% CI +0.040 .. +0.074)`` of a robust/fragile row's paired gap
    (``+0.000 (no discordant draw)`` where the two agree on every fresh draw)."""
    if math.isnan(row["gap"]):
        return "n/a"
    if row["gap_lo"] == row["gap_hi"]:  # every pair of fresh draws agrees: no spread to use
        return f"{row['gap']:+.3f} (no discordant draw)"
    return f"{row['gap']:+.3f} (95% CI {row['gap_lo']:+.3f} .. {row['gap_hi']:+.3f})"
