"""One grasp's L1 Ferrari-Canny Q in one compiled call (the path ``ferrari_canny`` takes).

A user's planner calls ``ferrari_canny`` once per grasp, in a loop. Done step by step from
Python (check and normalize the contacts, build the wrenches, check their size, phase 1, the
expansion, the threshold) each step paid numpy's and numba's call overhead, a large share
of a one-grasp call, the more so the fewer the contacts (benchmarks/bench_quality.py).
:func:`single_epsilon` does those steps in one kernel with the same arithmetic (the same
kernels, called from compiled code), so its Q is the step-by-step one, bit for bit (tested);
it hands back to Python only what needs Python: an input its checks reject (the caller's
full checks word the error), a set the expansion cannot certify (qhull), and a barely
positive Q whose rank must be checked (an SVD).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.quality.expansion import MAX_POINTS, expand_from, screen
from kinegrasp_env.quality.torsion import torsion_into
from kinegrasp_env.quality.wrenches import (
    BARELY_CLOSED,
    NOT_CLOSED,
    closure_class,
    unit_normals_into,
    wrench_size_ok,
    wrenches_into,
)

#: :func:`single_epsilon`'s status codes: Q is final (thresholded as the reference
#: thresholds it) ...
DONE = 0
#: ... Q is barely positive (``wrenches.closure_class``): 0 if the set is
#: rank-deficient (the caller's SVD), else Q ...
CHECK_RANK = 1
#: ... the expansion did not certify the set: the caller asks qhull (the wrenches are in
#: ``w[:k m]``) ...
NOT_CERTIFIED = 2
#: ... the input fails a check (a non-finite entry, a normal too short, a torque too large:
#: the rules of ``wrenches``): the caller's full checks raise the error.
REJECTED = 3


def new_wrench_buffer() -> np.ndarray:
    """Scratch (:data:`~kinegrasp_env.quality.expansion.MAX_POINTS`, 6) for the wrenches of
    one grasp (:func:`single_epsilon`'s ``w``)."""
    return np.empty((MAX_POINTS, 6))


@jit.kernel
def single_epsilon(points, normals, friction, cos_t, sin_t, torque_scale, center_x, center_y,
                   center_z, gamma, w, poly, ridges) -> tuple[int, float]:
    """(status, Q) of one grasp, L1 norm: point contacts (``gamma`` 0), or soft fingers
    (``gamma`` > 0, metres: the torsional coefficient of
    :mod:`~kinegrasp_env.quality.soft_contacts`, whose primitives are the k m cone edges
    followed by each contact's two torsional ones, (n, s (p - c) x n +- s gamma n)).

    Args:
        points: (k, 3) contact points (metres), k m <= MAX_POINTS; normals (k, 3) inward
            contact normals of any nonzero length (normalized here as ``check_contacts``
            does).
        friction: mu >= 0; cos_t, sin_t (m,) the cone's edge angles
            (:func:`~kinegrasp_env.quality.wrenches.cone_angles`).
        torque_scale: s > 0 (1 / metres); center_x, center_y, center_z: the centre of mass
            (metres).
        w: (MAX_POINTS, 6) scratch: the k m edge wrenches (and with gamma > 0 the 2 k
            torsional ones after them) are left in its first rows.
        poly, ridges: the expansion's tables (``expansion.new_polytope``, ``new_ridges``).

    Returns:
        (status, Q): see :data:`DONE`, :data:`CHECK_RANK`, :data:`NOT_CERTIFIED`,
        :data:`REJECTED`; Q is meaningful for the first two.
    """
    if not (np.isfinite(friction) and friction >= 0.0 and np.isfinite(torque_scale)
            and torque_scale > 0.0 and np.isfinite(center_x) and np.isfinite(center_y)
            and np.isfinite(center_z) and np.isfinite(gamma) and gamma >= 0.0):
        return REJECTED, 0.0
    k = points.shape[0]
    unit = np.empty((k, 3))
    if not unit_normals_into(points, normals, unit):
        return REJECTED, 0.0
    edges = k * cos_t.shape[0]
    n = edges + (2 * k if gamma > 0.0 else 0)
    wrenches = w[:n]
    center = np.empty((1, 3))
    center[0, 0], center[0, 1], center[0, 2] = center_x, center_y, center_z
    wrenches_into(points.reshape(1, k, 3), unit.reshape(1, k, 3), np.full(1, friction),
                  cos_t, sin_t, np.full(1, torque_scale), center,
                  w[:edges].reshape(1, edges, 6))
    if gamma > 0.0:
        torsion_into(points, unit, torque_scale, center_x, center_y, center_z, gamma,
                     w[edges:n])
    scale = 0.0
    for i in range(n):
        for c in range(6):
            size = abs(wrenches[i, c])
            if not wrench_size_ok(size):
                return REJECTED, 0.0
            scale = max(scale, size)
    if k <= 2 and gamma == 0.0:  # every point wrench has zero moment about that line
        return DONE, 0.0
    start, q, certified = screen(wrenches)
    if start[0] >= 0:
        q, certified = expand_from(wrenches, start, poly, ridges)
    if not certified:
        return NOT_CERTIFIED, 0.0
    closure = closure_class(q, scale)
    if closure == NOT_CLOSED:
        return DONE, 0.0
    if closure == BARELY_CLOSED:
        return CHECK_RANK, q
    return DONE, q
