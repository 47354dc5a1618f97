"""Contact models: point contacts (hard fingers with Coulomb friction) and soft fingers
(Coulomb friction plus torsional friction about the contact normal over a contact patch).

Two point contacts never resist a torque about the line through them (no friction force has
a moment about it), so no two-finger grasp is in force closure with point contacts. A finger
pad pressed on a surface touches it over a patch and resists a torque about the normal too:
the soft-finger model. Parallel-jaw grasps are scored with it (Dex-Net's ``soft_fingers``).

**The soft-finger model.** A contact i at point p (metres) with inward unit normal n, friction
coefficient mu and patch radius r (metres) transmits a normal force f_n >= 0, a tangential
force f_t and a torque tau n about the normal, with

    f_t in f_n * mu * (the m-gon of the linearized cone)  and  |tau| <= gamma f_n,

linearized as the cone spanned by its m + 2 primitive wrenches (all with normal force 1):

* the m friction-cone edges of the point contact, w_j = (f_j, s (p - c) x f_j),
  f_j = n + mu (cos(2 pi j / m) t1 + sin(2 pi j / m) t2) (``wrenches.wrench_matrix``: the
  same rows, bit for bit);
* two torsional primitives, w_+- = (n, s (p - c) x n +- s gamma n): a unit normal force with
  the largest torsion it carries, either way round.

So the friction the contact transmits lies in f_n times the convex hull of the m-gon (tau = 0)
and the two points (f_t = 0, tau = +-gamma): ||f_t||_cone / mu + |tau| / gamma <= f_n, an
inscribed linearization of the elliptic limit surface (f_t / mu)^2 + (tau / gamma)^2 <= f_n^2
(as the m-gon is of the circular cone), and sum_i f_n,i <= 1 stays the L1 budget of Q.

**The torsional coefficient** gamma (metres: torque per unit normal force) is by default that
of a uniform pressure f_n / (pi r^2) over a disc of radius r sliding about its centre:
tau_max = integral of mu (f_n / (pi r^2)) rho dA = (2 / 3) mu r f_n, so gamma = (2 / 3) mu r
(:func:`torsion_coefficient`); ``torsion=`` sets gamma directly. Torques are scaled as every
torque of Q is: s = torque_scale = 1 / r_max (1/metres), so a torsional primitive's torque is
s gamma n, dimensionless like the others. Dex-Net's ``soft_fingers`` adds, instead, two pure
torques (0, +-pi r^2 mu s f n) per contact (f <= 1 the normal part of the jaw's unit push):
torsion with no normal force behind it, and pi r^2 mu is an area, not a length; its
magnitude (f = 1) is ``torsion=pi * r**2 * mu`` here, in this model's primitives.

Q and force closure of a primitive set are the project's (docs/conventions.md): the
distance from the origin to the nearest facet of the convex hull of the primitives, through
:func:`~kinegrasp_env.quality.epsilon.exact_quality` (the certified expansion, else qhull;
one grasp in one compiled call, :func:`~kinegrasp_env.quality.epsilon.compiled_single`).
With ``contact_model="point"`` every function here returns what the point-contact functions
return, bit for bit (it calls them).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from kinegrasp_env.quality.epsilon import (
    Method,
    Norm,
    compiled_single,
    exact_quality,
    ferrari_canny,
    ferrari_canny_batch,
    uses_tables,
)
from kinegrasp_env.quality.torsion import torsion_wrenches
from kinegrasp_env.quality.wrenches import (
    check_contacts,
    check_parameters,
    check_wrenches,
    edge_wrenches,
    scale_center,
    wrench_matrix,
)

ContactModel = Literal["point", "soft"]
#: The contact models, the default first.
CONTACT_MODELS: tuple[str, ...] = ("point", "soft")
#: gamma / (mu r) of a uniform pressure over a disc of radius r (see the module docstring).
UNIFORM_DISC = 2.0 / 3.0
#: Default patch radius r (metres): Dex-Net's parallel-jaw grippers' ``finger_radius``.
FINGER_RADIUS = 0.01
#: Torsional primitives per soft contact (the torsion either way round).
TORSION_PRIMITIVES = 2


# ----------------------------------------------------------------------------- checks
def check_contact_model(contact_model) -> str:
    """The model's name; ValueError unless it is one of :data:`CONTACT_MODELS`."""
    if not isinstance(contact_model, str) or contact_model not in CONTACT_MODELS:
        raise ValueError(f"unknown contact_model {contact_model!r}; choose "
                         f"{' or '.join(CONTACT_MODELS)}")
    return contact_model


def _nonnegative(value, name: str, positive: bool) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        number = math.nan
    if not math.isfinite(number) or number < 0 or (positive and number == 0):
        raise ValueError(f"{name} must be finite and {'> 0' if positive else '>= 0'} "
                         f"(metres), got {value!r}")
    return number


def torsion_coefficient(friction: float = 0.5, finger_radius: float = FINGER_RADIUS) -> float:
    """gamma = (2 / 3) mu r (metres): the largest torsion per unit normal force of a disc of
    radius r (metres) under uniform pressure, friction mu (see the module docstring)."""
    mu, _ = check_parameters(friction, 3)
    return UNIFORM_DISC * mu * _nonnegative(finger_radius, "finger_radius", positive=True)


def soft_torsions(soft: np.ndarray, friction: float = 0.5,
                  finger_radius: float = FINGER_RADIUS) -> np.ndarray:
    """Per contact gamma (metres, ``soft``'s shape): :func:`torsion_coefficient` where
    ``soft`` (bool) marks a soft contact, 0 (a point contact) elsewhere: the ``torsion=`` of
    a set that mixes the two (the patch model's)."""
    return np.where(soft, torsion_coefficient(friction, finger_radius), 0.0)


# ----------------------------------------------------------------------------- primitives
def contact_wrenches(points, normals, *, contact_model: ContactModel = "point",
                     friction: float = 0.5, num_edges: int = 8, torque_scale=1.0,
                     center=(0.0, 0.0, 0.0), finger_radius: float = FINGER_RADIUS,
                     torsion: float | np.ndarray | None = None) -> np.ndarray:
    """Primitive wrenches of a contact set under a contact model.

    Args:
        points, normals: (k, 3) or (B, k, 3) contact points (metres, object frame) and inward
            normals (any nonzero length).
        contact_model: ``point`` (:func:`~kinegrasp_env.quality.wrenches.wrench_matrix`'s
            output, unchanged) or ``soft``.
        friction, num_edges, torque_scale, center: as for ``wrench_matrix`` (mu a scalar).
        finger_radius: patch radius r (metres, > 0) giving gamma = (2 / 3) mu r (soft only).
        torsion: gamma itself (metres, >= 0), instead of the one of ``finger_radius``: one
            number, or one per contact ((k,) or (B, k): a contact of gamma 0 carries no
            torsion, its torsional primitives a unit normal force inside its cone).

    Returns:
        point: (k m, 6) or (B, k m, 6). soft: (k (m + 2), 6) or (B, k (m + 2), 6), contact i's
        rows i (m + 2) .. i (m + 2) + m + 1: its m cone edges (``wrench_matrix``'s rows
        i m .. i m + m - 1) then (n, s (p - c) x n + s gamma n) and the same with - s gamma n.
    """
    model = check_contact_model(contact_model)
    if model == "point":
        return wrench_matrix(points, normals, friction=friction, num_edges=num_edges,
                             torque_scale=torque_scale, center=center)
    batched = np.ndim(points) == 3
    points, unit = check_contacts(points, normals, batched)
    if np.ndim(friction) > 0:
        raise ValueError("soft contacts take one friction coefficient (a scalar), got shape "
                         f"{np.shape(friction)}")
    mu, m = check_parameters(friction, num_edges)
    p, n = (points, unit) if batched else (points[None], unit[None])
    gamma = (torsion_coefficient(mu, finger_radius) if torsion is None
             else _torsions(torsion, p.shape[:2]))
    scale, ctr = scale_center(torque_scale, center, p.shape[0])
    w = check_wrenches(soft_primitives(p, n, mu, m, scale, ctr, gamma))
    return w if batched else w[0]


def _torsions(torsion, shape: tuple[int, int]) -> float | np.ndarray:
    """``torsion`` checked: one gamma (a float), or one per contact as a (B, k) array
    (metres, finite, >= 0); ValueError naming it otherwise."""
    if np.ndim(torsion) == 0:
        return _nonnegative(torsion, "torsion", positive=False)
    try:
        values = np.broadcast_to(np.asarray(torsion, dtype=float), shape)
    except ValueError:
        raise ValueError(f"torsion must be one number or one per contact {shape}, got shape "
                         f"{np.shape(torsion)}") from None
    if not (np.all(np.isfinite(values)) and np.all(values >= 0)):
        raise ValueError("torsion must be finite and >= 0 (metres) for every contact")
    return values


def soft_primitives(points: np.ndarray, normals: np.ndarray, friction: float, num_edges: int,
                    torque_scale: np.ndarray, center: np.ndarray,
                    gamma: float | np.ndarray) -> np.ndarray:
    """(B, k (m + 2), 6) soft-contact primitives of checked input (points, unit normals
    (B, k, 3), torque_scale (B,), center (B, 3); gamma in metres, one or (B, k) per
    contact), laid out as :func:`contact_wrenches` says: the cone edges are
    ``edge_wrenches``', the torsional primitives ``torsion_wrenches``' (the one compiled rule
    the single-grasp call uses too; per contact, its torsion term scaled by each gamma)."""
    batch, k = points.shape[:2]
    m = num_edges
    out = np.empty((batch, k, m + TORSION_PRIMITIVES, 6))
    out[:, :, :m] = edge_wrenches(points, normals, friction, m, torque_scale,
                                  center).reshape(batch, k, m, 6)
    if np.ndim(gamma) == 0:
        torsions = torsion_wrenches(points, normals, torque_scale, center, gamma)
    else:  # the primitives are affine in gamma: none, plus gamma times a unit one's twist
        none = torsion_wrenches(points, normals, torque_scale, center, 0.0)
        unit = torsion_wrenches(points, normals, torque_scale, center, 1.0)
        torsions = none + np.repeat(gamma, TORSION_PRIMITIVES, axis=1)[..., None] * (
            unit - none)
    out[:, :, m:] = torsions.reshape(batch, k, TORSION_PRIMITIVES, 6)
    return out.reshape(batch, k * (m + TORSION_PRIMITIVES), 6)


# ----------------------------------------------------------------------------- quality
def contact_quality_batch(points, normals, *, contact_model: ContactModel = "point",
                          friction: float = 0.5, num_edges: int = 8, torque_scale=1.0,
                          center=(0.0, 0.0, 0.0), finger_radius: float = FINGER_RADIUS,
                          torsion: float | np.ndarray | None = None, method: Method = "auto",
                          norm: Norm = "l1") -> np.ndarray:
    """(B,) Ferrari-Canny Q of B grasps (B, k, 3) under a contact model; 0 where not in force
    closure. ``point``: :func:`~kinegrasp_env.quality.epsilon.ferrari_canny_batch`'s value
    (every argument of it accepted). ``soft``: Q of :func:`contact_wrenches`' primitives
    (``method`` ``auto``: the certified expansion, else qhull; ``qhull``: qhull alone; the
    three-contact tables, which read their input as m-gons, never serve soft contacts)."""
    model = check_contact_model(contact_model)
    if model == "point":
        return ferrari_canny_batch(points, normals, friction=friction, num_edges=num_edges,
                                   torque_scale=torque_scale, center=center, method=method,
                                   norm=norm)
    _check_soft_method(method, norm)
    if np.ndim(points) != 3:
        raise ValueError(f"points must have shape (B, k, 3), got {np.shape(points)}")
    w = contact_wrenches(points, normals, contact_model=model, friction=friction,
                         num_edges=num_edges, torque_scale=torque_scale, center=center,
                         finger_radius=finger_radius, torsion=torsion)
    if w.shape[0] == 0:
        return np.empty(0)
    return _soft_quality(w, np.shape(points)[1], num_edges, friction, norm, method)


def _check_soft_method(method, norm) -> None:
    if method not in ("auto", "qhull"):
        raise ValueError(f"soft contacts take method auto or qhull, got {method!r}")
    if norm not in ("l1", "linf"):
        raise ValueError(f"unknown norm {norm!r}; choose l1 or linf")


def _soft_quality(w: np.ndarray, k: int, num_edges, friction, norm: Norm,
                  method: Method) -> np.ndarray:
    """(B,) Q of soft primitives w (B, k (m + 2), 6) through ``exact_quality`` (qhull where
    it would hand a 3-contact set to the three-contact tables)."""
    per_contact = int(num_edges) + TORSION_PRIMITIVES
    mu = float(friction)
    if uses_tables(k, per_contact, mu, norm):
        method = "qhull"
    return exact_quality(w, k, per_contact, mu, norm, method)


def contact_quality(points, normals, *, contact_model: ContactModel = "point",
                    friction: float = 0.5, num_edges: int = 8, torque_scale=1.0,
                    center=(0.0, 0.0, 0.0), finger_radius: float = FINGER_RADIUS,
                    torsion: float | np.ndarray | None = None, method: Method = "auto",
                    norm: Norm = "l1") -> float:
    """Q of one grasp (k, 3) under a contact model (:func:`contact_quality_batch`'s
    arguments); ``point``: :func:`~kinegrasp_env.quality.epsilon.ferrari_canny`'s value.
    ``soft`` with the defaults' method and norm and plain input: one compiled call, as the
    point model's (:func:`~kinegrasp_env.quality.epsilon.compiled_single`: the wrenches,
    the expansion, qhull where it cannot certify); its Q may differ from
    :func:`contact_quality_batch`'s in the last digits (the primitives in another order)."""
    model = check_contact_model(contact_model)
    if model == "point":
        return ferrari_canny(points, normals, friction=friction, num_edges=num_edges,
                             torque_scale=torque_scale, center=center, method=method,
                             norm=norm)
    if method == "auto" and norm == "l1" and (torsion is None or type(torsion) is float):
        try:
            gamma = (torsion_coefficient(friction, finger_radius) if torsion is None
                     else torsion)
        except (TypeError, ValueError):
            gamma = None  # the batch path's checks word the error
        if gamma is not None and gamma > 0.0:
            q = compiled_single(points, normals, friction, num_edges, torque_scale, center,
                                gamma)
            if q is not None:
                return q
    if np.ndim(points) != 2:
        raise ValueError(f"points must have shape (k, 3), got {np.shape(points)}")
    return float(contact_quality_batch(
        np.asarray(points)[None], np.asarray(normals)[None], contact_model=model,
        friction=friction, num_edges=num_edges, torque_scale=torque_scale, center=center,
        finger_radius=finger_radius, torsion=torsion, method=method, norm=norm)[0])


def contact_force_closure(points, normals, **kwargs) -> bool:
    """True when the grasp (k, 3) is in force closure under its contact model (Q > 0;
    :func:`contact_quality`'s arguments)."""
    return contact_quality(points, normals, **kwargs) > 0.0
