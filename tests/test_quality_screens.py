"""The quality paths' shortcuts: each against an independent computation.

* the compiled edge wrenches equal the numpy formula (friction_cone_edges and np.cross), bit
  for bit, also where |n| ties pick the tangent axis;
* the phase-1 screen (``outside_batch``) only ever marks grasps qhull puts out of force
  closure, and most of them;
* an equilibrium on the hull (a degenerate phase-1 end) is certified Q = 0 by the expansion
  instead of being left to qhull, and qhull agrees.
"""

from __future__ import annotations

import numpy as np
from quality_cases import box_contacts, sphere_contacts

from kinegrasp_env.quality import (
    ferrari_canny,
    ferrari_canny_batch,
    friction_cone_edges,
    wrench_matrix,
)
from kinegrasp_env.quality.expansion import epsilon_epa_batch, outside_batch
from kinegrasp_env.quality.wrenches import edge_wrenches


def numpy_wrenches(points, normals, friction, num_edges, torque_scale, center):
    """(B, k m, 6): the documented formula, term by term in numpy."""
    edges = friction_cone_edges(normals, friction, num_edges)
    lever = (points - center[:, None, :]) * torque_scale[:, None, None]
    torques = np.cross(lever[:, :, None, :], edges)
    w = np.concatenate([edges, torques], axis=-1)
    return w.reshape(w.shape[0], -1, 6)


def test_compiled_wrenches_equal_the_numpy_formula():
    rng = np.random.default_rng(21)
    for points, normals in (sphere_contacts(rng, 50, 4, jitter=0.3), box_contacts(rng, 50, 3)):
        normals = normals / np.linalg.norm(normals, axis=-1, keepdims=True)
        scale, center = rng.uniform(1, 30, 50), 0.01 * rng.normal(size=(50, 3))
        for mu in (0.5, rng.uniform(0, 1, 50)[:, None, None, None]):
            for m in (3, 8):
                # two code paths (compiled kernel, numpy's cross products): a few ulps of
                # the largest wrench entry, not bit for bit
                w = numpy_wrenches(points, normals, mu, m, scale, center)
                np.testing.assert_allclose(
                    edge_wrenches(points, normals, mu, m, scale, center), w, rtol=0,
                    atol=4 * np.finfo(float).eps * np.abs(w).max())


def test_screen_marks_only_grasps_out_of_force_closure():
    rng = np.random.default_rng(5)
    points, normals = sphere_contacts(rng, 300, 3, jitter=0.3)
    kw = {"num_edges": 8, "torque_scale": 20.0}
    ref = ferrari_canny_batch(points, normals, method="qhull", **kw)
    w = np.ascontiguousarray(numpy_wrenches(points, normals, 0.5, 8, np.full(300, 20.0),
                                            np.zeros((300, 3))))
    outside = outside_batch(w)
    assert not np.any(outside & (ref > 0))
    assert outside.sum() >= 0.9 * (ref == 0).sum() and 0.1 < (ref > 0).mean() < 0.9


def test_equilibria_on_the_hull_are_certified_zero():
    """Grasps 49 and 116 of this batch end phase 1 with an artificial variable in the basis
    (the origin on the hull; qhull's Q is 0): they used to go to qhull."""
    points, normals = sphere_contacts(np.random.default_rng(0), 200, 4, jitter=0.3)
    kw = {"num_edges": 8, "torque_scale": 20.0}
    w = np.ascontiguousarray(wrench_matrix(points, normals, **kw))
    q, certified = epsilon_epa_batch(w)
    ref = ferrari_canny_batch(points, normals, method="qhull", **kw)
    assert certified.all()
    assert ref[49] == ref[116] == 0.0 and q[49] == q[116] == 0.0
    np.testing.assert_array_equal(q > 1e-12 * np.abs(w).max(axis=(1, 2)), ref > 0)
    np.testing.assert_allclose(q[ref > 0], ref[ref > 0], rtol=1e-9, atol=0)
    single = [ferrari_canny(points[b], normals[b], **kw) for b in (49, 116)]
    assert single == [0.0, 0.0]
