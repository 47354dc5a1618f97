"""What the re-weighted elbow search keeps of its batch: each angle's estimate with the
weights' evidence (:class:`CurvePoint`), and the run's (:class:`ReweightEvidence`: the
selection batch and the covariances the fragility picture draws)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.montecarlo.palm_batch import PalmBatch, fragile_directions
from kinegrasp_env.toolkit.elbow import ElbowPoint


@dataclass
class CurvePoint:
    """One angle's re-weighted estimate (:class:`ElbowPoint` plus the weights' evidence)."""

    point: ElbowPoint
    se: float
    ess: float
    slope: float
    slope_se: float
    fallback: bool


@dataclass
class ReweightEvidence:
    """What the batch method adds to an :class:`ElbowResult` (the selection batch and the
    nominal and chosen angles' covariances of delta (6, 6) kept for the picture)."""

    batch: int
    curve: list[CurvePoint]
    chosen_estimate: float
    chosen_agrees: bool
    selection: PalmBatch | None = field(default=None, repr=False)
    nominal_cov: np.ndarray | None = field(default=None, repr=False)
    best_cov: np.ndarray | None = field(default=None, repr=False)
    _pictures: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def picture(self, points: int = 3000) -> dict | None:
        """What :func:`~kinegrasp_env.toolkit.elbow_plots.plot_elbow_fragility` draws: ``points``
        of the batch's deviations in the two most fragile directions under the nominal
        elbow's distribution, their outcomes, and both elbows' covariances seen there (None
        where no draw of the batch loses force closure). Computed once per ``points``: the
        plot and the report draw the same picture."""
        if points not in self._pictures:
            self._pictures[points] = self._picture(points)
        return self._pictures[points]

    def _picture(self, points: int) -> dict | None:
        if self.selection.fc.all():
            return None  # no draw loses force closure: nothing is fragile
        frag = fragile_directions(self.selection, self.nominal_cov)
        rows = np.unique(np.linspace(0, len(self.selection) - 1, points).astype(int))
        return {"points": frag.coordinates(self.selection.deltas[rows]),
                "fc": self.selection.fc[rows],
                "ellipses": {"nominal": frag.projected(self.nominal_cov),
                             "best": frag.projected(self.best_cov)},
                "labels": [frag.label(0), frag.label(1)], "spread": frag.spread.tolist()}

    def to_json(self) -> dict:
        return {"batch": self.batch, "chosen_reweighted_p_fc": self.chosen_estimate,
                "chosen_agrees_with_fresh_draws": self.chosen_agrees,
                "fallback_angles": [c.point.psi for c in self.curve if c.fallback],
                "points": [{"psi": c.point.psi, "se": _finite(c.se), "ess": _finite(c.ess),
                            "slope": _finite(c.slope), "slope_se": _finite(c.slope_se),
                            "direct": c.fallback} for c in self.curve]}


def _finite(value: float) -> float | None:
    """A JSON number, or None for NaN (strict JSON has no NaN)."""
    return None if not math.isfinite(value) else float(value)
