"""Coulomb consistency at a small size: the quality code's critical friction coefficient mu*
against hand derivations, and both simulators resisting at 1.5 mu* and slipping at 0.67 mu*
(``benchmarks/coulomb_consistency.py`` is the full table)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from coulomb import grasps as cg
from coulomb import scenes

GRASPS = {g.name: g for g in cg.coulomb_grasps()}
#: HiGHS's optimality tolerance is ~1e-9 on these O(1) problems; bisection to 1e-9.
LP_TOL = 1e-7


def test_pinch_mu_star_matches_the_hand_derivation():
    """Two fingers on opposite faces pressing with F, a tangential force D at the centre:
    each contact carries at most mu F, so mu* = D / (2 F) in Coulomb's model. The 8-edge cone
    (docs/conventions.md) reaches mu F along an edge direction (+y is one for both normals
    +-x: t1 = -+z, t2 = -y) and mu F cos(pi/8) midway between two edges, so the LP must give
    D / (2F) for the edge direction and D / (2F cos(pi/8)) for the 22.5-degree one, and
    D / (2F) again at 32 edges (22.5 degrees is an edge there). A torque T about z (across
    the pinch axis, contacts at +-a) needs tangential forces T / (2a): mu* = T / (2 a F).
    This proves the LP's wrench assembly (normal forces, tangential edges, torques about the
    centre) and its minimisation over mu; the references are closed-form."""
    force, a = cg.FORCE, cg.BOX_HALF[0]
    edge, mid, twist = GRASPS["pinch_edge"], GRASPS["pinch_mid"], GRASPS["pinch_twist"]
    d = np.linalg.norm(edge.wrench[:3])
    assert cg.resist_mu(edge, 8) == pytest.approx(d / (2 * force), abs=LP_TOL)
    d_mid = np.linalg.norm(mid.wrench[:3])
    assert cg.resist_mu(mid, 8) == pytest.approx(d_mid / (2 * force * math.cos(math.pi / 8)),
                                                 abs=LP_TOL)
    assert cg.resist_mu(mid, 32) == pytest.approx(d_mid / (2 * force), abs=LP_TOL)
    assert cg.resist_mu(twist, 8) == pytest.approx(twist.wrench[5] / (2 * a * force),
                                                   abs=LP_TOL)


def test_torque_about_the_pinch_axis_is_never_resisted():
    """Point contacts have no torsional friction: a torque about the line through two
    opposite contacts has no lever arm for any friction force, so no mu resists it (the LP
    is infeasible: inf)."""
    spin = cg.CoulombGrasp("spin", "", "box", GRASPS["pinch_edge"].vertices,
                           GRASPS["pinch_edge"].points, GRASPS["pinch_edge"].normals,
                           GRASPS["pinch_edge"].forces, np.array([0, 0, 0, 0.05, 0, 0.0]))
    assert cg.resist_mu(spin) == math.inf


def test_frustum_mu_star_is_the_tangent_of_the_slant():
    """Three fingers pressing F along the inward normals of faces that lean by alpha from
    the vertical: the normal forces' vertical parts, F sin(alpha) each, must be cancelled by
    friction along the faces, f cos(alpha) = F sin(alpha), so mu* = tan(alpha) (the
    horizontal parts cancel by symmetry); and force closure needs a cone that contains a
    horizontal direction, atan(mu) > alpha: mu*_FC = tan(alpha) too. The needed friction
    points straight down each face; at 8 edges that must be an edge direction for the LP's
    value to be exactly tan(alpha) -- it is for these normals (their smallest |n_i| is z, so
    t1 = n x z is horizontal and t2 is the face's slope direction). The FC bisection uses the
    project's ferrari_canny; the references are closed-form."""
    squeeze = GRASPS["frustum_squeeze"]
    slant = math.tan(cg.FRUSTUM_SLANT)
    assert cg.resist_mu(squeeze, 8) == pytest.approx(slant, abs=LP_TOL)
    assert cg.closure_mu(squeeze, 8) == pytest.approx(slant, abs=1e-6)


def test_balanced_normals_are_in_force_closure_at_any_friction():
    """The box tripod's normal forces balance by themselves (F, F on one face, 2F opposite,
    torques cancelling) and its wrenches span 6-D once mu > 0, so it is in force closure at
    every mu > 0: mu*_FC = 0 (bisection to 1e-9); and not at mu = 0 (forces along x only)."""
    tripod = GRASPS["tripod_box"]
    assert cg.closure_mu(tripod, 8) < 1e-8
    from kinegrasp_env.quality import ferrari_canny

    assert ferrari_canny(tripod.points, tripod.normals, friction=0.0) == 0.0


SIM_CASES = [(name, sim) for name in ("pinch_edge", "pinch_mid", "tripod_box", "frustum_squeeze")
             for sim in ("pybullet", "mujoco")]


@pytest.mark.parametrize(("name", "simulator"), SIM_CASES)
def test_simulators_resist_at_1_5_and_slip_at_0_67_mu_star(name, simulator):
    """In each simulator, with the fingers pressing F along the normals and the disturbance
    ramped in with the grip: at mu = 1.5 mu* (8-edge LP) the object moves less than 0.1 mm
    and turns less than 0.6 degrees in 1 s (measured on the benchmark's six grasps: at most
    0.068 mm and 0.41 degrees, pybullet's frustum; MuJoCo at impratio 100 0.013 mm and 0.09
    degrees), at 0.67 mu* it slips by more than 1 mm (measured: metres,
    except the squeeze at 0.67 mu*: hundreds of mm). The margins hold whatever the cone's
    shape: mu*(8 edges) is within [1, 1.082] of Coulomb's, and a simulator whose friction
    were, say, the product of two coefficients of mu each (pybullet's rule applied twice)
    would slip at 1.5 mu* < 1 / mu*. The simulators share no code with the quality LP."""
    if simulator == "mujoco":
        pytest.importorskip("mujoco")
    grasp = GRASPS[name]
    mu = cg.resist_mu(grasp, 8)
    simulate = scenes.SIMULATORS[simulator]
    high = simulate(grasp, 1.5 * mu)
    assert high.displacement < 1e-4 and high.rotation < math.radians(0.6), high
    assert not high.slipped
    low = simulate(grasp, 0.67 * mu)
    assert low.slipped and low.displacement > scenes.SLIP_DISTANCE, low
