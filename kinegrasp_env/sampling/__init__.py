"""Noise and statistics: joint-noise models and samplers (plain Monte Carlo, antithetic,
scrambled Sobol), the composable noise model of every source of error (joints, hand, palm,
object, friction) and its specs, estimators (mean, covariance, skewness), the Wilson interval
for P(FC), mergeable streaming moments, and Sobol sensitivity indices. Depends on nothing
else in the package.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "noise": ("JointNoise", "DISTRIBUTIONS", "METHODS", "as_generator"),
    "noise_model": ("NoiseModel", "as_noise_model"),
    "noise_sources": ("NoiseSpecError", "JointsSource", "HandSource", "PoseSource",
                      "FrictionSource"),
    "noise_spec": ("noise_model_from_spec", "load_noise_model", "spec_of"),
    "sobol": ("sobol_indices",),
    "stats": ("wilson_interval", "skewness", "Moments", "moments", "StreamingMoments",
              "ConvergenceCurve", "convergence_curve"),
})
