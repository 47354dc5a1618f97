"""The antipodal sampler's partner search on a thin wall: a tube's wall pinches, checked
against the tube's own geometry (radii 26 and 30 mm)."""

from __future__ import annotations

import numpy as np
import trimesh

from kinegrasp_env.toolkit.grasp_planner import antipodal_pairs, ray_partners
from kinegrasp_env.toolkit.plan_checks import PlannerSettings


def tube() -> trimesh.Trimesh:
    ring = trimesh.creation.annulus(r_min=0.026, r_max=0.03, height=0.09, sections=128)
    ring.apply_translation((0.0, 0.0, 0.045))
    return ring


def test_partners_of_a_tube_wall_are_across_the_wall() -> None:
    """A sample on the outer wall (r = 30 mm) meets the inner wall (r = 26 mm, up to the
    polygon's chord) straight in along its normal: 4 mm apart, at the same height and angle,
    normals opposite. Samples on the ends pair across the 90 mm height when allowed."""
    mesh = tube()
    points, faces = trimesh.sample.sample_surface(mesh, 300, seed=3)
    normals = mesh.face_normals[faces]
    cos = np.cos(PlannerSettings().max_normal_angle)
    pairs, pair_normals = ray_partners(mesh, points, normals, cos, max_width=0.07)
    radius = np.linalg.norm(pairs[..., :2], axis=2)
    outer = radius[:, 0] > 0.0295
    assert outer.sum() > 50
    np.testing.assert_allclose(radius[outer, 1], 0.026, atol=2e-5)  # chord of 128 sides
    np.testing.assert_allclose(np.linalg.norm(pairs[outer, 1] - pairs[outer, 0], axis=1),
                               0.004, atol=5e-5)
    np.testing.assert_allclose(pairs[outer, 1, 2], pairs[outer, 0, 2], atol=1e-9)
    assert (np.einsum("ij,ij->i", pair_normals[outer, 0], pair_normals[outer, 1]) < -0.99).all()
    assert (np.linalg.norm(pairs[:, 1] - pairs[:, 0], axis=1) <= 0.07).all()


def test_the_sampler_offers_wall_pinches() -> None:
    """Among the sampler's pairs are pinches across the 4 mm wall (from the partner search:
    opposite samples of the two faces almost never line up within the cone)."""
    mesh = tube()
    pairs, _ = antipodal_pairs(mesh, PlannerSettings(), 0.07, np.random.default_rng(0))
    width = np.linalg.norm(pairs[:, 1] - pairs[:, 0], axis=1)
    assert (np.abs(width - 0.004) < 1e-4).sum() >= 20
