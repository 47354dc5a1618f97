"""The force-closure threshold and the contact checks: one rule, the same boundary on every
quality path (the one-call compiled path, the batch path and the step-by-step numpy path)."""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.quality import ferrari_canny, ferrari_canny_batch
from kinegrasp_env.quality.wrenches import (
    BARELY_CLOSED,
    CLOSED,
    NOT_CLOSED,
    closure_class,
    closure_classes,
)

#: A 4-contact grasp in force closure (a regular tetrahedron's face centres, normals inward).
TETRA = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])


def _paths(points, normals):
    """Q of one grasp through the three entry paths: (compiled one call, batch, lists)."""
    return (ferrari_canny(points, normals),
            float(ferrari_canny_batch(points[None], normals[None])[0]),
            ferrari_canny(points.tolist(), normals.tolist()))


def _raises_on_every_path(points, normals, match: str) -> None:
    """ValueError matching ``match`` from each of the three entry paths."""
    for call in (lambda: ferrari_canny(points, normals),
                 lambda: ferrari_canny_batch(points[None], normals[None]),
                 lambda: ferrari_canny(points.tolist(), normals.tolist())):
        with pytest.raises(ValueError, match=match):
            call()


def test_closure_class_is_the_documented_threshold():
    """The rule stated in docs/conventions.md and the quality module docstrings, with its
    constants written out here: Q counts as 0 unless Q > 1e-12 x the wrench scale (NaN: 0),
    is 'barely positive' (rank decides) below 1e-8 x the scale, else stands; the batched
    form gives the scalar one's class element by element."""
    scale = 3.7
    cases = [(np.nan, NOT_CLOSED), (0.0, NOT_CLOSED), (-1.0, NOT_CLOSED),
             (1e-12 * scale, NOT_CLOSED), (np.nextafter(1e-12 * scale, 1.0), BARELY_CLOSED),
             (np.nextafter(1e-8 * scale, 0.0), BARELY_CLOSED), (1e-8 * scale, CLOSED),
             (0.5, CLOSED), (np.inf, CLOSED)]
    for q, expected in cases:
        assert closure_class(q, scale) == expected, q
    q = np.array([c[0] for c in cases])
    np.testing.assert_array_equal(closure_classes(q, np.full(q.size, scale)),
                                  [c[1] for c in cases])


def test_short_normal_boundary_is_the_same_on_every_path():
    """A normal of length exactly 1e-12 is accepted and one a float below is rejected, with
    the same error, on the compiled one-call path, the batch path and the list (numpy) path:
    the three apply one rule."""
    points = TETRA * 0.05
    normals = -TETRA / np.sqrt(3.0)
    shortest = normals.copy()
    shortest[0] = [1e-12, 0.0, 0.0]  # sqrt(x * x) == x exactly: length 1e-12
    for q in _paths(points, shortest):
        assert q >= 0.0
    too_short = normals.copy()
    too_short[0] = [np.nextafter(1e-12, 0.0), 0.0, 0.0]
    _raises_on_every_path(points, too_short, "has zero length")


@pytest.mark.parametrize("bad", ["nan", "inf"])
def test_non_finite_entries_are_rejected_on_every_path(bad):
    """A NaN or infinite point or normal entry is a ValueError on all three paths."""
    points = TETRA * 0.05
    normals = -TETRA / np.sqrt(3.0)
    for which in ("points", "normals"):
        p, n = points.copy(), normals.copy()
        (p if which == "points" else n)[2, 1] = float(bad)
        _raises_on_every_path(p, n, f"{which} contains NaN or infinite")


def test_wrench_size_boundary_is_the_same_on_every_path():
    """Torques of ~1e99 are accepted (the same Q on the three paths) and of ~2e100
    rejected (MAX_WRENCH = 1e100) on all three paths."""
    normals = -TETRA / np.sqrt(3.0)
    fine = TETRA * 1e99 / np.linalg.norm(TETRA[0])
    results = _paths(fine, normals)
    assert results[0] >= 0.0 and results[0] == results[1] == results[2]
    _raises_on_every_path(TETRA * 2e100, normals, "the torques reach")
