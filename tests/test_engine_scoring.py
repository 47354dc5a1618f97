"""Every engine scores its closings with one function: what that score is.

What the test proves: for the default robot's engines (its description's pybullet reference,
physics closing and fast engine), a draw's Q is the
Ferrari-Canny measure of the draw's own recorded contacts at the draw's mu, computed again
here by the exact qhull path (:func:`~kinegrasp_env.quality.epsilon.ferrari_canny`, not the
batched expansion the engines use), and its outcome is force closure exactly where Q > 0.
A score at the engine's mu instead of the draw's, another torque scale or centre, or
fewer contacts scored than recorded break it.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, NO_FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.quality.epsilon import ferrari_canny
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.world.grasps import shipped_grasps


@pytest.mark.parametrize("engine_name", ["pybullet", "fast", "physics"])
def test_an_engines_q_is_the_ferrari_canny_measure_of_its_own_contacts(engine_name):
    grasp = shipped_grasps("drill")[0]
    engine = make_engine(engine_name, DEFAULT_ROBOT, "drill")
    n = 40
    q = chunk_configurations(grasp.q0, 7, 0.02, "gaussian", 2, 0, n)
    mu = np.random.default_rng(8).uniform(0.2, 1.0, n)
    try:
        if engine_name == "physics":  # it simulates at one mu: no per-draw friction
            mu[:] = engine.friction
            draws = engine.run(q)
        else:
            draws = engine.run(q, friction=mu)
    finally:
        engine.close()
    scored = np.flatnonzero((draws.outcome == FORCE_CLOSURE)
                            | (draws.outcome == NO_FORCE_CLOSURE))
    assert scored.size >= n // 2 and np.any(draws.outcome == FORCE_CLOSURE)
    settings = {"torque_scale": engine.obj.torque_scale, "center": engine.obj.center_of_mass,
                "num_edges": engine.num_edges, "method": "qhull"}
    for i in scored:
        k = int(draws.n_contacts[i])
        exact = ferrari_canny(draws.points[i, :k], draws.normals[i, :k], friction=mu[i],
                              **settings)
        # the batched expansion against qhull: equal to rounding (tolerance as the quality
        # tests measure it)
        np.testing.assert_allclose(draws.quality[i], exact, rtol=1e-9, atol=1e-15)
        assert (draws.outcome[i] == FORCE_CLOSURE) == (exact > 0)
