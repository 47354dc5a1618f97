"""Noise and statistics: joint-noise models and samplers (plain Monte Carlo, antithetic,
scrambled Sobol), estimators (mean, covariance, skewness), the Wilson interval for P(FC), and
mergeable streaming moments. Depends on nothing else in the package.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "JointNoise": "noise",
    "DISTRIBUTIONS": "noise",
    "METHODS": "noise",
    "as_generator": "noise",
    "wilson_interval": "stats",
    "skewness": "stats",
    "Moments": "stats",
    "moments": "stats",
    "StreamingMoments": "stats",
    "ConvergenceCurve": "stats",
    "convergence_curve": "stats",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
