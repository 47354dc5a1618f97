"""Noise and statistics: joint-noise models and samplers (plain Monte Carlo, antithetic,
scrambled Sobol), the composable noise model of every source of error (joints, hand, palm,
object, friction) and its specs, estimators (mean, covariance, skewness), the Wilson interval
for P(FC), mergeable streaming moments, and Sobol sensitivity indices. Depends on nothing
else in the package.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "JointNoise": "noise",
    "DISTRIBUTIONS": "noise",
    "METHODS": "noise",
    "as_generator": "noise",
    "NoiseModel": "noise_model",
    "NoiseDraws": "noise_model",
    "NoiseSpecError": "noise_sources",
    "JointsSource": "noise_sources",
    "HandSource": "noise_sources",
    "PoseSource": "noise_sources",
    "FrictionSource": "noise_sources",
    "as_noise_model": "noise_model",
    "noise_model_from_spec": "noise_spec",
    "load_noise_model": "noise_spec",
    "spec_of": "noise_spec",
    "sobol_indices": "sobol",
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
