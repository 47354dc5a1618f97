"""Phase 1 of the expansion (:mod:`kinegrasp_env.quality.expansion`): a simplex of 7 wrenches
that contains the origin, or a certificate that none does.

A basic feasible solution of ``W^T lam = 0, sum(lam) = 1, lam >= 0`` for wrenches W (N, 6)
by the phase-1 simplex method (:func:`initial_simplex`): the most negative reduced cost
enters (~10 pivots for 5 contacts x 12 edges where Bland's rule took ~49), Bland's rule after
:data:`DANTZIG_PIVOTS` pivots, so that it cannot cycle. No solution: the origin is outside
conv(W) (Q = 0), certified by the final duals, a hyperplane every wrench lies strictly on one
side of (:func:`_separates`). A degenerate end (the origin on the hull, an equilibrium that
is not force closure) is certified Q = 0 when the duals give a hyperplane that every wrench
lies within FC_TOL / 2 of, on one side (Q is at most that; :func:`_on_boundary`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.quality.wrenches import FC_TOL

#: Phase-1 pivots by Dantzig's rule before Bland's takes over (measured: 5 contacts x 12
#: edges need ~49 pivots by Bland's rule alone).
DANTZIG_PIVOTS = 50


@jit.kernel
def _phase_one_tableau(w: np.ndarray) -> np.ndarray:
    """Phase-1 tableau (8, N + 8) of ``W^T lam = 0, sum(lam) = 1, lam >= 0`` for w (N, 6):
    rows 0-6 the constraints with one artificial column each (N..N+6), the last column the
    right-hand side, the last row the reduced costs of minimizing the sum of artificials."""
    n = w.shape[0]
    rows, cols = 7, n + 7
    tab = np.zeros((rows + 1, cols + 1))
    for i in range(6):
        for j in range(n):
            tab[i, j] = w[j, i]
    for j in range(n):
        tab[6, j] = 1.0
    tab[6, cols] = 1.0
    for i in range(rows):
        tab[i, n + i] = 1.0
    # objective row: minimize the sum of artificials -> reduced costs
    for j in range(cols + 1):
        s = 0.0
        for i in range(rows):
            s += tab[i, j]
        tab[rows, j] = -s
    for i in range(rows):
        tab[rows, n + i] = 0.0
    return tab


@jit.kernel(_nrt=False)
def leaving_row(tab: np.ndarray, basis: np.ndarray, enter: int, tol: float) -> int:
    """Ratio test for entering column ``enter``, ties to the smallest basic index (Bland);
    -1 if no row qualifies."""
    rows, cols = basis.shape[0], tab.shape[1] - 1
    leave = -1
    best = np.inf
    for i in range(rows):
        if tab[i, enter] > tol:
            ratio = tab[i, cols] / tab[i, enter]
            if ratio < best - 1e-15 or (abs(ratio - best) <= 1e-15 and leave >= 0
                                        and basis[i] < basis[leave]):
                best = ratio
                leave = i
    return leave


@jit.kernel(_nrt=False)
def entering_column(tab: np.ndarray, objective: int, dantzig: bool, tol: float) -> int:
    """The column to enter the basis, by the reduced costs in row ``objective`` of the
    tableau (last column the right-hand side): the most negative one (Dantzig's rule: few
    pivots) or the first negative one (Bland's rule, which cannot cycle); -1 when none is
    below -``tol`` (optimal)."""
    enter = -1
    lowest = -tol
    for j in range(tab.shape[1] - 1):
        if tab[objective, j] < lowest:
            if not dantzig:
                return j
            lowest = tab[objective, j]
            enter = j
    return enter


@jit.kernel(_nrt=False)
def pivot(tab: np.ndarray, leave: int, enter: int) -> None:
    """Gauss-Jordan pivot of the tableau on (leave, enter)."""
    piv = tab[leave, enter]
    for j in range(tab.shape[1]):
        tab[leave, j] /= piv
    for i in range(tab.shape[0]):
        if i != leave:
            f = tab[i, enter]
            if f != 0.0:
                for j in range(tab.shape[1]):
                    tab[i, j] -= f * tab[leave, j]


@jit.kernel
def _separates(w: np.ndarray, tab: np.ndarray) -> bool:
    """True when the final phase-1 tableau (8, N + 8) certifies that the origin is outside
    conv(W): its duals y_i = 1 - tab[7, N + i] give u = y[:6] with u . w_j < 0 for every
    wrench w_j (N, 6), by more than rounding (a separating hyperplane). False when rounding
    (a tiny pivot) has spoiled the tableau: the answer is then left undecided."""
    support, size = _dual_support(w, tab)
    return support < -1e-9 * size * wrench_scale(w)


@jit.kernel
def _dual_support(w: np.ndarray, tab: np.ndarray) -> tuple[float, float]:
    """(max_j u . w_j, |u|) for the duals u (6,) of the phase-1 tableau (8, N + 8) (see
    :func:`_separates`) and the wrenches w (N, 6); NaN products are skipped."""
    n = w.shape[0]
    u = np.empty(6)
    size = 0.0
    for c in range(6):
        u[c] = 1.0 - tab[7, n + c]
        size += u[c] * u[c]
    support = -np.inf
    for j in range(n):
        d = 0.0
        for c in range(6):
            d += u[c] * w[j, c]
        if d > support:
            support = d
    return support, np.sqrt(size)


@jit.kernel
def _on_boundary(w: np.ndarray, tab: np.ndarray) -> bool:
    """True when the phase-1 duals u (see :func:`_dual_support`) bound Q: every wrench
    within FC_TOL / 2 of the wrench scale of the hyperplane u . x = 0 on one side, so the
    origin is outside conv(W) or at most that far inside it (Q <= max_j u . w_j / |u|):
    Q = 0 under the force-closure threshold. Typical of an equilibrium that is not force
    closure (a degenerate phase-1 basis, the origin on the hull)."""
    support, size = _dual_support(w, tab)
    return size > 0.0 and support <= 0.5 * FC_TOL * size * wrench_scale(w)


@jit.kernel(_nrt=False)
def wrench_scale(w: np.ndarray) -> float:
    """Largest |entry| of the wrenches w (N, 6)."""
    scale = 0.0
    for i in range(w.shape[0]):
        for c in range(6):
            scale = max(scale, abs(w[i, c]))
    return scale


@jit.kernel
def initial_simplex(w: np.ndarray, tol: float) -> np.ndarray:
    """Indices (7,) of wrenches whose simplex contains the origin, [-1] if the origin is
    outside conv(W), [-3] if it is on the hull to FC_TOL (:func:`_on_boundary`: Q = 0), [-2]
    if undecided (degenerate basis)."""
    n = w.shape[0]
    rows, cols = 7, n + 7
    tab = _phase_one_tableau(w)
    basis = np.empty(rows, np.int64)
    for i in range(rows):
        basis[i] = n + i
    for it in range(200):
        enter = entering_column(tab, rows, it < DANTZIG_PIVOTS, tol)
        if enter < 0:
            break
        leave = leaving_row(tab, basis, enter, tol)
        if leave < 0:
            return np.array([-2])
        pivot(tab, leave, enter)
        basis[leave] = enter
    else:
        return np.array([-2])
    if -tab[rows, cols] > 1e-9 and _separates(w, tab):  # infeasible: the duals certify it
        return np.array([-1])
    degenerate = -tab[rows, cols] > 1e-9
    for i in range(rows):
        degenerate = degenerate or basis[i] >= n
    if degenerate:
        return np.array([-3]) if _on_boundary(w, tab) else np.array([-2])
    return basis
