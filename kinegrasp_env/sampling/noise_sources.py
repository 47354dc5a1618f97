"""The sources of error of a noise model, one class each, with their checks and samplers.

:class:`JointsSource` (arm joints, any number of them: independent per-joint sigma in
any of the three distributions of :class:`~kinegrasp_env.sampling.noise.JointNoise`, or a
covariance; a bias), :class:`HandSource` (pre-shape spread and per-finger closing offsets),
:class:`PoseSource` (a Gaussian rigid error: palm or object) and :class:`FrictionSource` (mu
per draw). Each validates its values on construction (:class:`NoiseSpecError`, one line
naming the bad value); the joints, pose and friction sources sample from a given generator
(the hand's offsets are laid out per robot: :mod:`kinegrasp_env.montecarlo.noise_rows`).
Units: radians, metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.sampling.noise import DISTRIBUTIONS, MAX_SIGMA, JointNoise, check_sigma_bound

FRICTION_DISTRIBUTIONS = ("gaussian", "uniform", "fixed")


class NoiseSpecError(ValueError):
    """A noise model that cannot be used (one line, naming the bad value)."""


# ----------------------------------------------------------------------------- value checks
def values(value, name: str, lengths: tuple[int, ...] | None = (1,),
           each: str = "arm joint") -> np.ndarray:
    """``value`` as a float vector of one of ``lengths`` (a scalar has length 1; None: any
    length from 1, one value per ``each``), finite."""
    if isinstance(value, bool) or isinstance(value, str):
        raise NoiseSpecError(f"{name} must be a number or a list of numbers, got {value!r}")
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise NoiseSpecError(f"{name} must be a number or a list of numbers, "
                             f"got {value!r}") from None
    if lengths is None and (arr.ndim != 1 or arr.size == 0):
        raise NoiseSpecError(f"{name} must be a scalar or one value per {each}, "
                             f"got {value!r}")
    if lengths is not None and (arr.ndim != 1 or arr.size not in lengths):
        wanted = " or ".join("a scalar" if n == 1 else f"{n} values" for n in lengths)
        raise NoiseSpecError(f"{name} must be {wanted}, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise NoiseSpecError(f"{name} must be finite, got {value!r}")
    return arr


def check_angles(arr: np.ndarray, name: str) -> None:
    """NoiseSpecError unless every standard deviation of ``arr`` (radians) is within the
    joint-noise bound (:func:`~kinegrasp_env.sampling.noise.check_sigma_bound`'s words)."""
    try:
        check_sigma_bound(arr, name)
    except ValueError as exc:
        raise NoiseSpecError(str(exc)) from None


def sigmas(value, name: str, lengths: tuple[int, ...] | None = (1, 3),
           angles: bool = False, each: str = "arm joint") -> float | tuple[float, ...]:
    """Standard deviations: finite and >= 0, ``angles`` (radians) at most pi
    (:func:`~kinegrasp_env.sampling.noise.check_sigma_bound`); a float or a tuple
    (``lengths``, ``each``: :func:`values`)."""
    arr = values(value, name, lengths, each)
    if np.any(arr < 0):
        raise NoiseSpecError(f"{name} must be >= 0, got {value!r}")
    if angles:
        check_angles(arr, name)
    return float(arr[0]) if arr.size == 1 and np.ndim(value) == 0 else tuple(arr.tolist())


def joints_text(n: int) -> str:
    """``n`` joints, in words ("1 joint", "7 joints")."""
    return f"{n} joint{'' if n == 1 else 's'}"


def broadcast(value: float | tuple[float, ...], size: int) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    return np.full(size, arr[0]) if arr.size == 1 else arr


def covariance_factor(cov: np.ndarray, name: str = "joints.covariance") -> np.ndarray:
    """L (d, d) with L L^T = cov for a symmetric positive semi-definite cov (d, d): the
    Cholesky factor of the joints with a nonzero variance (a diagonal cov gives diag(sqrt);
    a joint of zero variance stays exactly zero), or V sqrt(Lambda) of them when they are
    still singular. ValueError names an asymmetric entry or the negative eigenvalue."""
    cov = np.asarray(cov, dtype=float)
    scale = max(float(np.abs(cov).max()), 1e-300)
    asym = np.abs(cov - cov.T)
    if asym.max() > 1e-12 * scale:
        i, j = (int(k) for k in np.unravel_index(np.argmax(asym), asym.shape))
        raise NoiseSpecError(f"{name} is not symmetric: entry [{i}][{j}] = {cov[i, j]:g} but "
                             f"[{j}][{i}] = {cov[j, i]:g}")
    eig = np.linalg.eigvalsh(cov)
    if eig[0] < -1e-12 * scale:
        raise NoiseSpecError(f"{name} is not positive semi-definite: smallest eigenvalue "
                             f"{eig[0]:.3g}")
    active = np.ix_(np.diag(cov) > 0, np.diag(cov) > 0)
    factor = np.zeros_like(cov)
    try:
        factor[active] = np.linalg.cholesky(cov[active])
    except np.linalg.LinAlgError:  # singular: semi-definite
        lam, vec = np.linalg.eigh(cov[active])
        factor[active] = vec * np.sqrt(np.maximum(lam, 0.0))
    return factor


# ----------------------------------------------------------------------------- sources
#: What makes a joints source fit an arm: how its per-joint values may be given.
JOINTS_FIX = ("give sigma and bias as one value or one per arm joint, a covariance as one "
              "row and column per arm joint")


@dataclass(frozen=True)
class JointsSource:
    """Arm-joint error eps (d,) radians on an arm of d joints: independent (``sigma``,
    ``distribution``) or Gaussian with ``covariance`` (d x d, symmetric PSD); plus ``bias``
    added to every draw. Scalars fit an arm of any number of joints; per-joint values fix
    d (:attr:`count`), checked against a robot's arm where the source is used.

    Attributes:
        sigma: scalar or one standard deviation per arm joint (ignored when ``covariance``
            is given).
        distribution: ``gaussian``, ``uniform`` or ``triangular`` (independent case only).
        covariance: d x d (rad^2) as nested tuples, or None.
        bias: scalar or one constant offset per arm joint (rad), or None.
    """

    sigma: float | tuple[float, ...] = 0.0
    distribution: str = "gaussian"
    covariance: tuple[tuple[float, ...], ...] | None = None
    bias: float | tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.distribution not in DISTRIBUTIONS:
            raise NoiseSpecError(f"joints.distribution {self.distribution!r} is unknown; "
                                 f"choose from {', '.join(DISTRIBUTIONS)}")
        set_ = object.__setattr__
        set_(self, "sigma", sigmas(self.sigma, "joints.sigma", None, angles=True))
        if self.covariance is not None:
            if self.distribution != "gaussian":
                raise NoiseSpecError("joints.covariance needs distribution gaussian, got "
                                     f"{self.distribution!r}")
            rows = self._rows(self.covariance)
            cov = np.array([values(r, f"joints.covariance[{i}]", (len(rows),))
                            for i, r in enumerate(rows)])
            covariance_factor(cov)
            check_angles(np.sqrt(np.diag(cov)), "joints.covariance's largest standard "
                                                "deviation")
            set_(self, "covariance", tuple(tuple(r.tolist()) for r in cov))
        if self.bias is not None:
            bias = values(self.bias, "joints.bias", None)
            if np.any(np.abs(bias) > MAX_SIGMA):
                raise NoiseSpecError(f"joints.bias must be within +-pi, got {self.bias!r}")
            set_(self, "bias", float(bias[0]) if bias.size == 1 else tuple(bias.tolist()))
        counts = {name: len(value) for name, value in (
            ("covariance", self.covariance), ("sigma", self.sigma), ("bias", self.bias))
            if isinstance(value, tuple) and len(value) > 1}
        if len(set(counts.values())) > 1:
            raise NoiseSpecError("joints: " + " and ".join(
                f"{name} describes {joints_text(n)}" for name, n in counts.items()))

    @staticmethod
    def _rows(covariance) -> list:
        if isinstance(covariance, np.ndarray):
            covariance = covariance.tolist()
        if not isinstance(covariance, (list, tuple)):
            raise NoiseSpecError(f"joints.covariance must be rows of numbers (d rows of d, one "
                                 f"per arm joint), got {covariance!r}")
        rows = list(covariance)
        if not rows:
            raise NoiseSpecError("joints.covariance must be d rows of d numbers, got no rows")
        return rows

    @property
    def count(self) -> int | None:
        """The number of arm joints its per-joint values describe (None: scalars, or lists
        of one value, only: any arm)."""
        if self.covariance is not None:
            return len(self.covariance)
        for value in (self.sigma, self.bias):
            if isinstance(value, tuple) and len(value) > 1:
                return len(value)
        return None

    def fits(self, dim: int) -> bool:
        """Whether the source fits an arm of ``dim`` joints (its per-joint values, if any,
        describe ``dim``)."""
        return self.count in (None, dim)

    def check_count(self, dim: int) -> None:
        """ValueError (one line) unless the source fits an arm of ``dim`` joints."""
        if not self.fits(dim):
            raise ValueError(f"the noise spec's joints describe {joints_text(self.count)} but the "
                             f"noise acts on {dim} ({JOINTS_FIX})")

    def sigma_vector(self, dim: int) -> np.ndarray:
        """(dim,) standard deviations of an arm of ``dim`` joints (the square roots of the
        covariance's diagonal); ValueError where the source describes another arm."""
        self.check_count(dim)
        if self.covariance is not None:
            return np.sqrt(np.diag(np.array(self.covariance)))
        return broadcast(self.sigma, dim)

    def sample(self, rng: np.random.Generator, size: int, dim: int,
               method: str = "mc") -> np.ndarray:
        """eps (size, dim), radians, of an arm of ``dim`` joints. The independent case is
        ``JointNoise(sigma, distribution).sample(size, dim, rng, method)`` itself."""
        self.check_count(dim)
        if self.covariance is None:
            eps = JointNoise(self.sigma, self.distribution).sample(size, dim, rng,
                                                                   method=method)
        else:
            z = JointNoise(1.0).sample(size, dim, rng, method=method)
            eps = z @ covariance_factor(np.array(self.covariance)).T
        return eps if self.bias is None else eps + np.asarray(self.bias)

    @property
    def exact(self) -> bool:
        return not np.any(self.sigma_vector(self.count or 1)) and not np.any(self.bias or 0.0)


@dataclass(frozen=True)
class HandSource:
    """Hand pre-shape error: ``spread_sigma`` (rad) on the spread, ``closing_sigma`` (rad; a
    scalar, or one per finger of the robot, in the order its description lists the fingers:
    checked against the robot by :func:`~kinegrasp_env.montecarlo.noise_rows.check_hand`)
    added to the finger's closing joints."""

    spread_sigma: float = 0.0
    closing_sigma: float | tuple[float, ...] = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "spread_sigma",
                           sigmas(self.spread_sigma, "hand.spread_sigma", (1,), angles=True))
        object.__setattr__(self, "closing_sigma",
                           sigmas(self.closing_sigma, "hand.closing_sigma", None, True,
                                  "finger"))

    @property
    def exact(self) -> bool:
        return self.spread_sigma == 0 and not np.any(self.closing_sigma)


@dataclass(frozen=True)
class PoseSource:
    """A Gaussian rigid error: ``translation_sigma`` (metres) and ``rotation_sigma`` (radians,
    of the rotation vector), each a scalar or 3 (per axis)."""

    translation_sigma: float | tuple[float, ...] = 0.0
    rotation_sigma: float | tuple[float, ...] = 0.0
    #: the source's name in error messages (``palm`` or ``object``)
    name: str = field(default="pose", compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "translation_sigma", sigmas(
            self.translation_sigma, f"{self.name}.translation_sigma"))
        object.__setattr__(self, "rotation_sigma", sigmas(
            self.rotation_sigma, f"{self.name}.rotation_sigma", angles=True))

    def variances(self) -> np.ndarray:
        """(6,) variances: translation (3) m^2, rotation vector (3) rad^2."""
        return self._scale() ** 2

    def _scale(self) -> np.ndarray:
        return np.concatenate([broadcast(self.translation_sigma, 3),
                               broadcast(self.rotation_sigma, 3)])

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """(size, 6): translation (3) metres, rotation vector (3) radians."""
        return rng.standard_normal((size, 6)) * self._scale()

    @property
    def exact(self) -> bool:
        return not np.any(self.translation_sigma) and not np.any(self.rotation_sigma)


@dataclass(frozen=True)
class FrictionSource:
    """The friction coefficient mu of a draw (the same at every contact).

    ``gaussian``: N(mean, sigma^2) truncated to mu >= 0 (mean >= 0); ``uniform``: U(low,
    high), 0 <= low <= high; ``fixed``: ``value`` >= 0.
    """

    distribution: str = "gaussian"
    mean: float = 0.5
    sigma: float = 0.0
    low: float = 0.0
    high: float = 0.0
    value: float = 0.5

    def __post_init__(self) -> None:
        if self.distribution not in FRICTION_DISTRIBUTIONS:
            raise NoiseSpecError(f"friction.distribution {self.distribution!r} is unknown; "
                                 f"choose from {', '.join(FRICTION_DISTRIBUTIONS)}")
        for key in ("mean", "sigma", "low", "high", "value"):
            object.__setattr__(self, key, float(values(getattr(self, key),
                                                       f"friction.{key}")[0]))
        checks = {"gaussian": (("mean", self.mean), ("sigma", self.sigma)),
                  "uniform": (("low", self.low), ("high", self.high)),
                  "fixed": (("value", self.value),)}[self.distribution]
        for key, number in checks:
            if number < 0:
                raise NoiseSpecError(f"friction.{key} must be >= 0 (mu has no negative "
                                     f"values), got {number:g}")
        if self.distribution == "uniform" and self.high < self.low:
            raise NoiseSpecError(f"friction.high ({self.high:g}) is below friction.low "
                                 f"({self.low:g})")

    @property
    def nominal(self) -> float:
        """The mu of the noise-free grasp: ``value``, ``mean``, or the middle of
        [``low``, ``high``]."""
        return {"fixed": self.value, "gaussian": self.mean,
                "uniform": 0.5 * (self.low + self.high)}[self.distribution]

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """(size,) mu >= 0."""
        if self.distribution == "fixed":
            return np.full(size, self.value)
        if self.distribution == "uniform":
            return rng.uniform(self.low, self.high, size)
        u = rng.random(size)
        if self.sigma == 0:
            return np.full(size, self.mean)
        from scipy import stats

        return stats.truncnorm.ppf(u, -self.mean / self.sigma, np.inf, loc=self.mean,
                                   scale=self.sigma)

    @property
    def exact(self) -> bool:
        return False  # a friction source always sets mu
