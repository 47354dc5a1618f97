"""Static hold: can a closed grasp carry the object's weight with the hand's limited forces?

Force closure asks whether the contacts can resist *some* wrench in every direction with
unbounded forces; whether a hand carries an object depends on how hard it can press. The
static hold check asks, for each load the holding test applies (gravity of the object's mass
along each of the six world axes, the lift's acceleration added to the downward one), whether
contact forces exist that

* lie in the contacts' friction cones (the contact model's primitive wrenches, each of unit
  normal force: :func:`~kinegrasp_env.quality.soft_contacts.contact_wrenches` with torques in
  newton metres about the centre of mass, weights x >= 0);
* balance the load: W^T x = -load (the load a wrench (force m a d, torque 0) at the centre
  of mass, newtons);
* need joint torques within the hand's limits: lower_j <= T_j x <= upper_j, T the map from
  primitive weights to joint torques (or forces, for prismatic joints).

One feasibility linear programme per load, solved by the phase-1 simplex method in one
compiled kernel (:func:`feasible`, the pivots of :mod:`~kinegrasp_env.quality.phase_one`):
small programmes for a two- or three-finger grasp, solved without leaving compiled code.
Rigid bodies and static equilibrium are
assumed: the check says the forces *exist*, not that a simulator's solver finds them.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.quality.phase_one import entering_column, leaving_row, pivot

__all__ = ["feasible", "gravity_loads", "static_hold"]

#: Pivots by Dantzig's rule before Bland's rule takes over (it cannot cycle).
DANTZIG_PIVOTS = 60
#: Most pivots of one programme before it is called infeasible (never reached in tests).
MAX_PIVOTS = 500
#: Phase-1 optimum (sum of artificials, rows scaled to unit size) below which the programme
#: is feasible.
FEASIBLE_TOL = 1e-9
#: Pivot tolerance of the ratio test and the reduced costs.
PIVOT_TOL = 1e-12


@jit.kernel
def feasible(a_eq: np.ndarray, b_eq: np.ndarray, a_ub: np.ndarray, b_ub: np.ndarray) -> bool:
    """True when x >= 0 exists with a_eq x = b_eq and a_ub x <= b_ub.

    Args:
        a_eq: (E, N), b_eq: (E,); a_ub: (U, N), b_ub: (U,) with b_ub >= 0 (the slacks start
            the basis: x = 0 satisfies the inequalities).

    Each row is scaled to unit largest entry; the phase-1 simplex method minimises the sum of
    one artificial variable per equality (Dantzig's rule, then Bland's).
    """
    e, n = a_eq.shape
    u = a_ub.shape[0]
    rows = e + u
    cols = n + u + e  # variables, slacks, artificials
    tab = np.zeros((rows + 1, cols + 1))
    basis = np.empty(rows, np.int64)
    for i in range(e):
        size = abs(b_eq[i])
        for j in range(n):
            size = max(size, abs(a_eq[i, j]))
        size = size if size > 0.0 else 1.0
        sign = -1.0 if b_eq[i] < 0.0 else 1.0
        for j in range(n):
            tab[i, j] = sign * a_eq[i, j] / size
        tab[i, cols] = sign * b_eq[i] / size
        tab[i, n + u + i] = 1.0
        basis[i] = n + u + i
    for i in range(u):
        size = b_ub[i]
        for j in range(n):
            size = max(size, abs(a_ub[i, j]))
        size = size if size > 0.0 else 1.0
        for j in range(n):
            tab[e + i, j] = a_ub[i, j] / size
        tab[e + i, cols] = b_ub[i] / size
        tab[e + i, n + i] = 1.0
        basis[e + i] = n + i
    for j in range(n + u):  # reduced costs of minimising the artificials' sum
        s = 0.0
        for i in range(e):
            s += tab[i, j]
        tab[rows, j] = -s
    s = 0.0
    for i in range(e):
        s += tab[i, cols]
    tab[rows, cols] = -s
    for it in range(MAX_PIVOTS):
        enter = entering_column(tab, rows, it < DANTZIG_PIVOTS, PIVOT_TOL)
        if enter < 0:
            break
        leave = leaving_row(tab, basis, enter, PIVOT_TOL)
        if leave < 0:  # unbounded below: impossible for a sum of artificials
            return False
        pivot(tab, leave, enter)
        basis[leave] = enter
    else:
        return False
    return -tab[rows, cols] <= FEASIBLE_TOL


@jit.kernel
def _hold_batch(primitives, torque_rows, lower, upper, loads, out):
    """out[b, d] = load d held by grasp b (see :func:`static_hold`)."""
    batch, count = primitives.shape[0], primitives.shape[1]
    joints = torque_rows.shape[1]
    a_eq = np.empty((6, count))
    a_ub = np.empty((2 * joints, count))
    b_ub = np.empty(2 * joints)
    b_eq = np.empty(6)
    for b in range(batch):
        for c in range(6):
            for j in range(count):
                a_eq[c, j] = primitives[b, j, c]
        for i in range(joints):
            for j in range(count):
                a_ub[i, j] = torque_rows[b, i, j]
                a_ub[joints + i, j] = -torque_rows[b, i, j]
            b_ub[i] = upper[b, i]
            b_ub[joints + i] = -lower[b, i]
        for d in range(loads.shape[0]):
            for c in range(6):
                b_eq[c] = -loads[d, c]
            out[b, d] = feasible(a_eq, b_eq, a_ub, b_ub)


def static_hold(primitives: np.ndarray, torque_rows: np.ndarray, lower: np.ndarray,
                upper: np.ndarray, loads: np.ndarray) -> np.ndarray:
    """Which loads each grasp holds (module docstring).

    Args:
        primitives: (B, P, 6) or (P, 6) primitive wrenches (force N, torque N m about the
            centre of mass, per unit normal force; rows of zeros for absent contacts).
        torque_rows: (B, J, P) or (J, P) joint torque (N m) or force (N) per unit weight of
            each primitive.
        lower, upper: (B, J) or (J,) the joints' bounds, lower <= 0 <= upper.
        loads: (D, 6) the load wrenches on the object (force N, torque N m).

    Returns:
        (B, D) or (D,) bool.

    Raises:
        ValueError: non-finite input, mismatched shapes, or bounds that exclude 0.
    """
    single = np.ndim(primitives) == 2
    prim, rows = (np.asarray(a, dtype=float) for a in (primitives, torque_rows))
    if single:
        prim, rows = prim[None], rows[None]
    low = np.asarray(lower, dtype=float).reshape(rows.shape[:2])
    high = np.asarray(upper, dtype=float).reshape(rows.shape[:2])
    loads = np.atleast_2d(np.asarray(loads, dtype=float))
    if prim.ndim != 3 or prim.shape[2] != 6 or loads.shape[1] != 6:
        raise ValueError(f"primitives must be (B, P, 6) and loads (D, 6), got {prim.shape} "
                         f"and {loads.shape}")
    if rows.shape[0] != prim.shape[0] or rows.shape[2] != prim.shape[1]:
        raise ValueError(f"torque_rows must be (B, J, P) = ({prim.shape[0]}, J, "
                         f"{prim.shape[1]}), got {rows.shape}")
    for name, value in (("primitives", prim), ("torque_rows", rows), ("lower", low),
                        ("upper", high), ("loads", loads)):
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} has NaN or infinite entries")
    if (low > 0).any() or (high < 0).any():
        raise ValueError("joint bounds must contain 0 (lower <= 0 <= upper)")
    out = np.zeros((prim.shape[0], loads.shape[0]), dtype=np.bool_)
    _hold_batch(np.ascontiguousarray(prim), np.ascontiguousarray(rows),
                np.ascontiguousarray(low), np.ascontiguousarray(high),
                np.ascontiguousarray(loads), out)
    return out[0] if single else out


def gravity_loads(mass: float, accelerations: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(D, 6) the load wrenches (object frame: force N, torque N m about the centre of mass)
    of an object of ``mass`` kg under accelerations (D, 3) of gravity (world frame, m/s^2),
    the object oriented by ``rotation`` (3, 3) in the world: forces m R^T a, no torque."""
    accelerations = np.atleast_2d(np.asarray(accelerations, dtype=float))
    loads = np.zeros((accelerations.shape[0], 6))
    loads[:, :3] = mass * accelerations @ np.asarray(rotation, dtype=float)
    return loads
