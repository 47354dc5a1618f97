"""The expansion's second try at the wrench sets it cannot certify: the sets moved by a hair.

Two flat pads facing each other put their corners' cone-edge wrenches by fours on common
planes; the certified expansion fails on about 1% of such sets (a thin facet it cannot cone,
or a polytope it cannot certify convex), and each then cost a qhull call (~20 ms for 64
wrenches, a hundred times the expansion).
:func:`~kinegrasp_env.quality.epsilon.joggled_quality` runs the expansion on the set with
every wrench moved by at most JOGGLE x its scale per coordinate; the two hulls lie within
sqrt(6) x JOGGLE x scale of each other, so the moved set's certified Q is the set's to within
that. Independent reference: qhull on the set itself.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.quality import epsilon
from kinegrasp_env.quality.epsilon import JOGGLE, joggled_quality
from kinegrasp_env.quality.expansion import epsilon_epa_batch
from kinegrasp_env.quality.qhull_quality import qhull_epsilon
from kinegrasp_env.quality.wrenches import edge_wrenches

HALF_PAD = 0.0075  # metres: 1.5 cm square pads
SCALE = 20.0  # torque scale, 1 / metres


def facing_pads(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(points, normals) (count, 8, 3): two square pads' corners on opposite faces of a 6 cm
    cube, each pad shifted a few millimetres and its normal tilted by about 0.02 rad."""
    rng = np.random.default_rng(seed)
    corners = np.array([[1, 1, 0], [1, -1, 0], [-1, -1, 0], [-1, 1, 0]]) * HALF_PAD
    points, normals = [], []
    for sign in (1.0, -1.0):
        centre = np.column_stack([rng.normal(0, 0.004, (count, 2)), np.full(count, 0.03 * sign)])
        points.append(centre[:, None, :] + corners[None])
        normal = np.array([0.0, 0.0, -sign]) + rng.normal(0, 0.02, (count, 1, 3))
        normals.append(np.repeat(normal / np.linalg.norm(normal, axis=2, keepdims=True), 4,
                                 axis=1))
    return np.concatenate(points, axis=1), np.concatenate(normals, axis=1)


#: Facing-pad sets the expansion may leave uncertified, of 3,000 (seed 0): it leaves 33
#: (1.1%), where testing every facet's visibility at each step, not only the facets around
#: those that see the new wrench, left 59 (a regression bound, with a margin).
MOST_UNCERTIFIED = 48


@pytest.fixture(scope="module")
def uncertified():
    """Facing-pad sets the expansion does not certify: (points, normals, wrenches)."""
    points, normals = facing_pads(3000, 0)
    w = edge_wrenches(points, normals, 0.5, 8, np.full(len(points), SCALE),
                      np.zeros((len(points), 3)))
    _, certified = epsilon_epa_batch(np.ascontiguousarray(w))
    bad = np.flatnonzero(~certified)
    assert 10 <= bad.size <= MOST_UNCERTIFIED, bad.size  # about 1% of such sets
    return points[bad], normals[bad], w[bad]


def test_the_moved_sets_q_is_the_sets_within_the_bound(uncertified):
    """Where the moved set's Q is taken (most of these sets), it lies within sqrt(6) x
    JOGGLE x the wrench scale of qhull's Q of the set itself."""
    w = uncertified[2]
    q, taken = joggled_quality(w)
    assert taken.mean() > 0.5, taken.mean()
    scale = np.abs(w).max(axis=(1, 2))
    for i in np.flatnonzero(taken):
        reference = qhull_epsilon(w[i], 8, "l1")
        assert abs(q[i] - reference) <= np.sqrt(6) * JOGGLE * scale[i], (i, q[i], reference)


def test_qhull_is_left_with_what_the_second_try_does_not_take(uncertified, monkeypatch):
    """The exact paths (``exact_quality``, as ``ferrari_canny_batch`` runs them) on these
    wrench sets call qhull only for the sets the second try does not take, and give the
    second try's Q for the others."""
    w = uncertified[2]
    q, taken = joggled_quality(w)
    calls = []

    def counted(*args):
        calls.append(1)
        return qhull_epsilon(*args)

    monkeypatch.setattr(epsilon, "qhull_epsilon", counted)
    got = epsilon.exact_quality(w, 8, 8, 0.5, "l1", "auto")
    assert len(calls) == int((~taken).sum())
    np.testing.assert_array_equal(got[taken], q[taken])
