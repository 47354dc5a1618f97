"""A grasp's Monte Carlo statistics from merged chunks -> :class:`GraspStats`.

A run's draws come in chunks (:func:`chunk_sizes`); each chunk contributes its outcome counts
and the streaming moments of Q over its force-closure draws (:func:`tally`), merged in chunk
order with exact streaming formulas, so memory stays flat for 10^6 draws and the numbers are
the same whatever the number of processes; :func:`summarize` turns the merged tallies into
the statistics (a sweep's cells).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES, DrawBatch
from kinegrasp_env.montecarlo.engines import ENGINES
from kinegrasp_env.sampling.noise import MAX_SIGMA, JointNoise
from kinegrasp_env.sampling.noise_model import STREAM_CHUNK, NoiseModel
from kinegrasp_env.sampling.noise_spec import spec_of
from kinegrasp_env.sampling.stats import StreamingMoments, wilson_interval
from kinegrasp_env.world.grasps import Grasp

__all__ = ["DEFAULT_CHUNK", "ENGINES", "MAX_SIGMA", "GraspStats", "Noise", "chunk_sizes",
           "summarize", "tally"]

#: Draws per chunk of a run (the random streams' layout: keep it fixed to reproduce numbers).
DEFAULT_CHUNK = STREAM_CHUNK
#: What a run takes as its noise.
Noise = JointNoise | NoiseModel


@dataclass
class GraspStats:
    """Monte Carlo statistics of one grasp.

    Attributes:
        p_fc: fraction of draws in force closure; p_fc_ci: Wilson 95% interval.
        q_mean, q_var, q_std, q_skew: moments of Q over the force-closure draws (NaN if
            fewer than 2 of them; skewness per docs/conventions.md).
        q_nominal: Q of the nominal grasp; error: q_nominal - q_mean (the paper's "Error").
        samples: number of draws; outcomes: counts by outcome name.
        sigma, noise, seed, engine: the settings (sigma and noise describe the joints).
        draws: per-draw results, when requested.
        noise_model: the spec of a :class:`NoiseModel` noise (None for ``JointNoise``).
    """

    p_fc: float
    p_fc_ci: tuple[float, float]
    q_mean: float
    q_var: float
    q_std: float
    q_skew: float
    q_nominal: float
    error: float
    samples: int
    outcomes: dict[str, int]
    sigma: float | list[float]
    noise: str
    seed: int
    engine: str = "pybullet"
    draws: DrawBatch | None = field(default=None, repr=False)
    noise_model: dict | None = None

    @property
    def ci(self) -> tuple[float, float]:
        """``p_fc_ci``, under the name a :class:`~kinegrasp_env.montecarlo.evaluate.
        GraspEvaluation` gives it (code that takes either reads ``ci``)."""
        return self.p_fc_ci

    def to_json(self) -> dict:
        """JSON-ready dict (NaN becomes None), without the draws (and without
        ``noise_model`` for joint noise)."""
        out = {k: v for k, v in asdict(self).items() if k != "draws"
               and not (k == "noise_model" and v is None)}
        out["p_fc_ci"] = list(self.p_fc_ci)
        for key, value in out.items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
        return out


def chunk_sizes(n_samples: int, chunk: int) -> list[int]:
    """The sizes of a run's chunks: ``n_samples`` draws in chunks of ``chunk`` (the last one
    shorter)."""
    return [min(chunk, n_samples - start) for start in range(0, n_samples, chunk)]


def tally(draws: DrawBatch) -> tuple[np.ndarray, StreamingMoments]:
    """(outcome counts (4,), streaming moments of Q over the force-closure draws) of
    ``draws``: what a chunk contributes to a run's statistics."""
    counts = np.bincount(draws.outcome, minlength=len(OUTCOMES))
    return counts, StreamingMoments(1).update(draws.quality[draws.outcome == FORCE_CLOSURE])


def summarize(grasp: Grasp, noise: Noise, seed: int, engine: str, counts: np.ndarray,
              moments: StreamingMoments, draws: DrawBatch | None, *,
              q_nominal: float | None = None) -> GraspStats:
    """The statistics of merged chunks; ``q_nominal``: the grasp's nominal Q at the run's
    friction (default: the grasp's recorded ``q_nominal``)."""
    q_nominal = grasp.q_nominal if q_nominal is None else float(q_nominal)
    n = int(counts.sum())
    fc = int(counts[FORCE_CLOSURE])
    result = moments.result()
    mean = float(result.mean[0]) if fc else math.nan
    var = float(result.cov[0, 0]) if fc > 1 else math.nan
    sigma = noise.sigma if isinstance(noise.sigma, float) else list(noise.sigma)
    return GraspStats(
        p_fc=fc / n, p_fc_ci=wilson_interval(fc, n), q_mean=mean, q_var=var,
        q_std=math.sqrt(var) if fc > 1 else math.nan,
        q_skew=float(result.skew[0]) if fc > 1 else math.nan, q_nominal=q_nominal,
        error=q_nominal - mean if fc else math.nan, samples=n,
        outcomes={name: int(c) for name, c in zip(OUTCOMES, counts, strict=True)},
        sigma=sigma, noise=noise.kind, seed=int(seed), engine=engine, draws=draws,
        noise_model=spec_of(noise) if isinstance(noise, NoiseModel) else None)

