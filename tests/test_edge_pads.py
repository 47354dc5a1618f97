"""A flat pad along an edge of the object: the contact at the middle of the pressed segment.

A pad laid against an edge touches it along a segment, and a closest-point query returns
any point of it; two jaws on opposite edges of a cylinder's mesh then scored contacts at
different heights (out of force closure), while the same jaws on the mesh turned by half a
facet, on two faces, were in force closure.

Independent references: the pressed segment written out by hand for box pads placed by
hand against edges given by their end points (a vertical edge, one receding into the object,
a corner); the cylinder's two meshes, whose grasps must be scored alike (the same Q to the
difference of the faces' and the edges' distance from the axis, by construction).
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.closing.contact_patch import PATCH_DEPTH
from kinegrasp_env.closing.edge_contact import place_on_edges

#: A box pad of 2 x 1 x 8 cm (x, y, z), its own frame at its centre.
PAD = np.array([[sx, sy, sz] for sx in (-0.01, 0.01) for sy in (-0.005, 0.005)
                for sz in (-0.04, 0.04)])


def pad_pose(z: float) -> np.ndarray:
    """(1, 4, 4) the pad's pose: its -y face on the plane y = 0 (the tangent plane of an
    edge along z through the origin, the object on the +y side), its centre at height z."""
    pose = np.eye(4)
    pose[:3, 3] = [0.0, -0.005, z]
    return pose[None]


INTO = np.array([[0.0, 1.0, 0.0]])  # the contact's normal, into the object


@pytest.mark.parametrize("z, expected", [
    (0.05, 0.05),            # the pad within the edge's span: its own middle
    (0.02, (0.0 + 0.06) / 2),  # overhanging the edge's lower end: [0, z + 0.04]
    (0.09, (0.05 + 0.10) / 2),  # overhanging its upper end: [z - 0.04, 0.10]
])
def test_a_pad_along_an_edge_presses_the_overlap_and_the_contact_is_its_middle(z, expected):
    """A vertical edge from (0, 0, 0) to (0, 0, 0.1); the pad's span is [z - 0.04, z + 0.04]:
    the pressed segment is their overlap, the contact its midpoint, wherever along the edge
    the query's point was."""
    edges = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]])
    for found_at in (0.001, 0.05, 0.099):
        out, placed = place_on_edges(PAD, pad_pose(z), edges, INTO,
                                     np.array([[0.0, 0.0, found_at]]))
        assert placed[0]
        np.testing.assert_allclose(out[0], [0.0, 0.0, expected], atol=1e-12)


def test_an_edge_receding_into_the_object_is_pressed_to_the_pad_depth():
    """An edge from the origin turned by alpha away from the pad into the object: its points
    at parameter t lie t L sin(alpha) deep, so the pressed part is t <= PATCH_DEPTH /
    (L sin(alpha)), and the contact its middle."""
    alpha, length = 0.1, 0.1
    direction = np.array([0.0, np.sin(alpha), np.cos(alpha)])
    edges = np.array([[[0.0, 0.0, 0.0], length * direction]])
    out, placed = place_on_edges(PAD, pad_pose(0.0), edges, INTO, np.array([[0.0, 0.0, 0.0]]))
    pressed = PATCH_DEPTH / np.sin(alpha)  # the pressed length, by the construction
    assert placed[0]
    np.testing.assert_allclose(out[0], 0.5 * pressed * direction, atol=1e-12)


def test_at_a_corner_the_edge_along_the_pad_is_pressed():
    """The corner (0, 0, 0.1) of a vertical edge and a rim edge leaving it 0.3 rad into the
    object (a cylinder's side and top): the vertical edge lies along the pad, and the contact
    goes to the middle of the pad's overlap with it, [0.02, 0.1] for a pad centred at 0.06."""
    rim = np.array([0.01 * np.cos(0.3), 0.01 * np.sin(0.3), 0.1])
    edges = np.array([[[0.0, 0.0, 0.1], rim], [[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]])
    out, placed = place_on_edges(PAD, pad_pose(0.06), edges, INTO, np.array([[0.0, 0.0, 0.1]]))
    assert placed[0]
    np.testing.assert_allclose(out[0], [0.0, 0.0, 0.06], atol=1e-12)


def test_no_edge_or_a_pad_beside_it_leaves_the_point():
    """A point on no edge, or a pad whose footprint misses the edge (entirely above it),
    keeps the point found."""
    edges = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]])
    off = np.array([[0.0, 0.0, 0.2]])
    out, placed = place_on_edges(PAD, pad_pose(0.2), edges, INTO, off)
    assert not placed[0] and np.array_equal(out, off)
    point = np.array([[0.0, 0.0, 0.05]])
    out, placed = place_on_edges(PAD, pad_pose(0.2), edges, INTO, point)
    assert not placed[0] and np.array_equal(out, point)


def test_both_engines_agree_where_the_pandas_pads_meet_the_cubes_edges():
    """The Panda's shipped cube grasps under joint noise (sigma 0.0133, 400 draws each of
    grasps 0 and 3): draws whose pads lie along the cube's vertical edges get the same
    outcome from both engines, draw for draw. What it guards: the reference's normal there
    comes from the pair rule, and pybullet's link point lies off the finger's mesh by its
    collision margin; taken as it is, the pair's direction pointed out of the cube (5 of
    these 800 draws differed; the reference's P(FC) fell by 1-1.5%)."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.world.grasps import shipped_grasps

    grasps = shipped_grasps("cube", "panda")
    rng = np.random.default_rng(7)
    q = np.concatenate([np.repeat(np.asarray(grasps[i].q0)[None], 400, axis=0)
                        for i in (0, 3)])
    q[:, :7] += rng.normal(0.0, 0.0133, (len(q), 7))
    with make_engine("fast", "panda", "cube") as fast, \
            make_engine("pybullet", "panda", "cube") as reference:
        np.testing.assert_array_equal(fast.run(q).outcome, reference.run(q).outcome)
