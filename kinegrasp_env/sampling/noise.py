"""Zero-mean joint noise: Gaussian, uniform and triangular with the same standard deviation.

A :class:`JointNoise` turns a seeded ``numpy.random.Generator`` into an (n, d) array of joint
offsets eps (radians). For every distribution the per-joint standard deviation is sigma:

* gaussian: N(0, sigma^2);
* uniform: U(-a, a) with a = sigma * sqrt(3);
* triangular: symmetric triangle on (-b, b) with b = sigma * sqrt(6).

Samplers (``method``): ``"mc"`` plain Monte Carlo; ``"antithetic"`` pairs (eps, -eps);
``"sobol"`` scrambled Sobol quasi-Monte Carlo (``scipy.stats.qmc``) mapped through the
inverse CDF. All are reproducible from the generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DISTRIBUTIONS = ("gaussian", "uniform", "triangular")
METHODS = ("mc", "antithetic", "sobol")
#: Largest joint-noise sigma accepted (radians). A standard deviation of half a turn already
#: spreads a joint over its whole circle, so the small-error model the evaluation stands for
#: has no meaning beyond it (and far beyond it, at 1e308, q0 + eps overflows to inf).
MAX_SIGMA = math.pi


SeedLike = int | np.random.Generator | np.random.SeedSequence | None


def is_integer_seed(seed) -> bool:
    """Whether ``seed`` is an integer >= 0 (not a bool)."""
    return (isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_))
            and seed >= 0)


def check_seed(seed, what: str = "seed") -> None:
    """ValueError (one line naming ``what`` and the value) unless ``seed`` is an integer >= 0,
    a ``numpy.random.SeedSequence`` or a ``numpy.random.Generator``."""
    if not (is_integer_seed(seed)
            or isinstance(seed, (np.random.SeedSequence, np.random.Generator))):
        raise ValueError(f"{what} must be an integer >= 0, a numpy SeedSequence or a numpy "
                         f"Generator, got {seed!r}")


def as_generator(seed: SeedLike) -> np.random.Generator:
    """A ``numpy.random.Generator`` from a seed, a SeedSequence or a Generator (returned as is)."""
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(seed)


def _inverse_cdf(kind: str, u: np.ndarray) -> np.ndarray:
    """Unit-variance quantiles of the distribution at probabilities u in (0, 1)."""
    if kind == "gaussian":
        from scipy import special

        return math.sqrt(2.0) * special.erfinv(2.0 * u - 1.0)
    if kind == "uniform":
        return math.sqrt(3.0) * (2.0 * u - 1.0)
    # symmetric triangular on (-b, b), b = sqrt(6)
    b = math.sqrt(6.0)
    return np.where(u < 0.5, b * (np.sqrt(2.0 * u) - 1.0), b * (1.0 - np.sqrt(2.0 * (1.0 - u))))


def check_sigma_bound(sigma, name: str = "sigma") -> None:
    """ValueError (one line naming ``name`` and the largest value) when a joint sigma, or one
    of several (radians), is above :data:`MAX_SIGMA`: the one rule of every layer (the
    library's noise, the commands' ``--sigma``, a sweep's grid, the env's reset option, a
    noise spec's angles)."""
    if np.size(sigma) == 0:
        return  # no value to bound (a count of values is its caller's rule)
    largest = float(np.max(sigma))
    if largest > MAX_SIGMA:
        raise ValueError(f"{name} must be <= pi ({MAX_SIGMA:.5f} rad), got {largest:g}")


@dataclass(frozen=True)
class JointNoise:
    """Independent zero-mean noise on d joints.

    Attributes:
        sigma: scalar or (d,) standard deviations (radians), all finite, >= 0 and at most
            :data:`MAX_SIGMA` (stored as a float or a tuple of floats).
        kind: one of ``gaussian``, ``uniform``, ``triangular``.
    """

    sigma: float | tuple[float, ...]
    kind: str = "gaussian"

    def __post_init__(self) -> None:
        if self.kind not in DISTRIBUTIONS:
            raise ValueError(f"unknown noise type {self.kind!r}; choose from "
                             f"{', '.join(DISTRIBUTIONS)}")
        values = self.sigma if isinstance(self.sigma, (list, tuple, np.ndarray)) else [self.sigma]
        if not all(isinstance(v, (int, float, np.integer, np.floating))
                   and not isinstance(v, (bool, np.bool_)) for v in np.ravel(values)):
            raise ValueError(f"sigma must be a number of radians or one per joint, got "
                             f"{self.sigma!r}")
        sig = np.atleast_1d(np.asarray(self.sigma, dtype=float))
        if sig.ndim != 1:
            raise ValueError(f"sigma must be a number of radians or one per joint, got "
                             f"{self.sigma!r}")
        if not np.all(np.isfinite(sig)) or np.any(sig < 0):
            raise ValueError(f"sigma must be finite and >= 0, got {self.sigma!r}")
        check_sigma_bound(sig)
        if np.ndim(self.sigma) == 0:
            object.__setattr__(self, "sigma", float(sig[0]))  # an int or numpy scalar too
        elif not isinstance(self.sigma, tuple) or not all(type(v) is float for v in self.sigma):
            object.__setattr__(self, "sigma", tuple(float(v) for v in sig))

    def sigma_vector(self, dim: int) -> np.ndarray:
        """(dim,) standard deviations."""
        sig = np.atleast_1d(np.asarray(self.sigma, dtype=float))
        if sig.size == 1:
            return np.full(dim, sig[0])
        if sig.size != dim:
            raise ValueError(f"sigma has {sig.size} entries but the noise acts on {dim} joints")
        return sig

    @property
    def half_width(self) -> float:
        """Support half-width per unit sigma (inf for gaussian)."""
        return {"gaussian": math.inf, "uniform": math.sqrt(3.0), "triangular": math.sqrt(6.0)}[
            self.kind]

    def sample(self, n: int, dim: int, rng: int | np.random.Generator | None = None,
               method: str = "mc") -> np.ndarray:
        """Draw eps of shape (n, dim), radians.

        Args:
            n: number of draws (>= 0).
            dim: number of joints.
            rng: seed or Generator.
            method: ``mc``, ``antithetic`` (rows 2i and 2i+1 are negatives; n odd drops the
                last partner) or ``sobol`` (scrambled Sobol points; n need not be a power of 2).
        """
        if n < 0:
            raise ValueError(f"number of draws must be >= 0, got {n}")
        if method not in METHODS:
            raise ValueError(f"unknown sampling method {method!r}; choose from {METHODS}")
        gen = as_generator(rng)
        sig = self.sigma_vector(dim)
        if method == "sobol":
            from scipy.stats import qmc

            sampler = qmc.Sobol(d=dim, scramble=True, seed=gen)
            m = max(0, math.ceil(math.log2(max(n, 1))))
            u = sampler.random_base2(m)[:n]
            u = np.clip(u, 1e-12, 1 - 1e-12)
            return _inverse_cdf(self.kind, u) * sig
        if method == "antithetic":
            half = self._standard(gen, (n + 1) // 2, dim)
            pairs = np.empty((2 * half.shape[0], dim))
            pairs[0::2], pairs[1::2] = half, -half
            return pairs[:n] * sig
        return self._standard(gen, n, dim) * sig

    def _standard(self, gen: np.random.Generator, n: int, dim: int) -> np.ndarray:
        if self.kind == "gaussian":
            return gen.standard_normal((n, dim))
        if self.kind == "uniform":
            a = math.sqrt(3.0)
            return gen.uniform(-a, a, size=(n, dim))
        b = math.sqrt(6.0)
        return gen.triangular(-b, 0.0, b, size=(n, dim))

    def characteristic(self, t: np.ndarray, dim_sigma: float) -> np.ndarray:
        """E[cos(t * eps)] for one joint of standard deviation ``dim_sigma`` (real, even)."""
        t = np.asarray(t, dtype=float) * dim_sigma
        if self.kind == "gaussian":
            return np.exp(-(t**2) / 2.0)
        if self.kind == "uniform":
            return np.sinc(math.sqrt(3.0) * t / np.pi)
        half = math.sqrt(6.0) * t / 2.0
        return np.sinc(half / np.pi) ** 2
