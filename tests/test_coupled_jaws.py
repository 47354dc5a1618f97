"""Coupled jaws: the push a one-actuator pair would give the object, by hand and from two
independent closings (pybullet's closest points, the fast engine's own distances)."""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.closing.coupled_jaws import jaw_push, jaw_speeds
from kinegrasp_env.robot.catalog import load_robot


def test_push_by_hand() -> None:
    """Jaws that touch after 10 and 20 mm meet the pushed object after 15 mm each: a 5 mm
    push; a missed jaw or a start collision gives none."""
    speeds = np.array([1.0, 1.0])
    travel = np.array([[0.01, 0.02], [0.02, 0.01], [0.01, 0.03], [0.0, 0.0]])
    missed = np.array([[False, False], [False, False], [False, True], [False, False]])
    start = np.array([False, False, False, True])
    push = jaw_push(speeds, travel, missed, start)
    np.testing.assert_allclose(push[:2], 0.005, atol=1e-15)
    assert np.isnan(push[2:]).all()
    np.testing.assert_allclose(jaw_push(np.array([2.0, 0.5]), travel[:1], missed[:1],
                                        start[:1]), 0.5 * abs(0.02 - 0.01), atol=1e-15)


def test_which_hands_have_coupled_jaws() -> None:
    """The Panda's jaws (panda_finger_joint2 mimics joint1, both prismatic) move 1 m per unit
    of the closing parameter; the three-finger SDH has none."""
    np.testing.assert_array_equal(jaw_speeds(load_robot("panda")), [1.0, 1.0])
    assert jaw_speeds(load_robot("kuka_sdh")) is None


def test_two_closings_give_the_same_push() -> None:
    """The fast engine and the reference engine (pybullet's closest points) find the same
    push on the same noisy draws of a shipped cube grasp (within 5e-6 m: each closing stops
    its jaw a little inside the contact tolerance, measured up to 1.3e-6 m apart), and about
    none at
    the planned grasps, whose jaws are centred on the pair (below 0.5 mm)."""
    from kinegrasp_env.montecarlo.evaluate import make_engine
    from kinegrasp_env.world.grasps import shipped_grasps

    grasps = shipped_grasps("cube", robot="panda")
    rng = np.random.default_rng(5)
    q = np.repeat(np.asarray(grasps[0].q0, dtype=float)[None], 60, axis=0)
    q[:, :7] += rng.normal(0.0, 0.0133, (60, 7))
    nominal = np.array([g.q0 for g in grasps], dtype=float)
    pushes = {}
    for name in ("fast", "pybullet"):
        with make_engine(name, "panda", "cube") as engine:
            pushes[name] = engine.run(q).push
            assert (engine.run(nominal).push < 5e-4).all()
    fast, reference = pushes["fast"], pushes["pybullet"]
    both = np.isfinite(fast) & np.isfinite(reference)
    assert both.sum() > 30 and (np.isfinite(fast) == np.isfinite(reference)).all()
    np.testing.assert_allclose(fast[both], reference[both], rtol=0, atol=5e-6)
    assert fast[both].max() > 1e-3  # the noise does push
    assert pytest.approx(0.0) != float(np.median(fast[both]))


def test_the_physics_engine_reports_no_push() -> None:
    """The push is what a kinematic closing of coupled jaws leaves out (the object pushed
    until the other jaw meets it); the physics engine's closing on the free object does the
    pushing, so its draws carry none (NaN), where the fast engine's carry one."""
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.world.grasps import shipped_grasps

    q = np.array([g.q0 for g in shipped_grasps("cube", robot="panda")[:2]])
    with make_engine("physics", "panda", "cube") as physics, \
            make_engine("fast", "panda", "cube") as fast:
        assert np.isnan(physics.run(q).push).all()
        assert np.isfinite(fast.run(q).push).any()
