"""One layout of random streams for every robot (docs/conventions.md, "Random streams").

What each test proves:

* :func:`~kinegrasp_env.sampling.noise_model.stream_rows` gives row r of a run from chunk
  ``r // 250``'s own stream, row ``r % 250``: checked against numpy's generators seeded by
  hand (``SeedSequence(seed, spawn_key=(c,))``, ``(c, k)`` for source k), for spans that
  start and end inside chunks and cross them; a layout of one stream, or chunks of another
  size, fails it;
* the default robot's evaluation (``kuka_sdh``: ``evaluate_grasp``, in one process and in
  chunks on two processes) draws the rows of those streams and closes them, draw for draw:
  its rows are recomputed here by hand from numpy's generators (joint noise: the chunk's
  own stream, standard normals times sigma on the 7 arm joints; a noise model of every
  source: the hand's standard normals on its spread and on both flexion joints of each
  finger, clipped to the limits, the palm's and object's rigid errors as rotation-vector
  rotations (scipy's) about the flange and the object's centre of mass, friction through
  scipy's truncated normal), equal to the rows the evaluation takes, and the evaluation's
  draws (every per-draw field) are those the engine gives on them in one call.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

from kinegrasp_env.montecarlo import chunks
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, DrawBatch
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp, evaluation_rows
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.sampling.noise_model import STREAM_CHUNK, stream_rows
from kinegrasp_env.sampling.noise_spec import noise_model_from_spec
from kinegrasp_env.world.grasps import shipped_grasps

EVERY_SOURCE = {"joints": {"sigma": 0.0133},
                "hand": {"spread_sigma": 0.02, "closing_sigma": 0.03},
                "palm": {"translation_sigma": 0.002, "rotation_sigma": 0.01},
                "object": {"translation_sigma": 0.003, "rotation_sigma": 0.02},
                "friction": {"distribution": "gaussian", "mean": 0.5, "sigma": 0.1}}


@pytest.fixture(autouse=True)
def _no_kept_engines():
    yield
    chunks.close_engines()


def _by_hand(seed: int, key: tuple[int, ...], rows: int, width: int) -> np.ndarray:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key)
                                 ).standard_normal((rows, width))


@pytest.mark.parametrize(("source", "k"), [("joints", ()), ("palm", (2,))])
@pytest.mark.parametrize(("offset", "size"), [(0, 3), (240, 20), (10, 600), (500, 250)])
def test_rows_of_a_run_are_rows_of_its_chunks_streams(source, k, offset, size):
    assert STREAM_CHUNK == 250
    rows = stream_rows(9, source, offset, size,
                       lambda generator, m: generator.standard_normal((m, 3)))
    chunks = np.concatenate([_by_hand(9, (c, *k), 250, 3) for c in range(4)])
    np.testing.assert_array_equal(rows, chunks[offset:offset + size])


@pytest.mark.parametrize(("offset", "size", "chunk", "name"),
                         [(-1, 3, 250, "offset"), (0, -2, 250, "size"), (0, 3, 0, "chunk")])
def test_a_bad_span_of_rows_is_one_line_naming_it(offset, size, chunk, name):
    with pytest.raises(ValueError, match=f"^stream rows: {name} must be >= "):
        stream_rows(9, "joints", offset, size, lambda g, m: g.standard_normal((m, 3)), chunk)


def _same_draws(evaluated, closed: DrawBatch) -> None:
    # the evaluation's draws are the engine's on the same rows: equal Q (a few ulps allowed
    # between the batches the rows are closed in) and every other per-draw field equal
    np.testing.assert_allclose(evaluated.draws.quality, closed.quality, rtol=1e-12,
                               atol=1e-15)
    for f in fields(DrawBatch):
        if f.name != "quality":
            np.testing.assert_array_equal(getattr(evaluated.draws, f.name),
                                          getattr(closed, f.name), err_msg=f.name)


#: The chunks (index, rows) of a run of 530 draws.
SPANS = ((0, 250), (1, 250), (2, 30))


def _stream(seed: int, key: tuple[int, ...]) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


def _joint_rows_by_hand(q0: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    eps = np.concatenate([_stream(seed, (c,)).standard_normal((rows, 7)) * sigma
                          for c, rows in SPANS])
    q = np.repeat(np.asarray(q0, dtype=float)[None], len(eps), axis=0)
    q[:, :7] += eps
    return q


def _pose_errors_by_hand(seed: int, k: int, translation: float, rotation: float,
                         center: np.ndarray) -> np.ndarray:
    """x -> R (x - c) + c + t, R the rotation of rotation vector r, (t, r) the source's
    standard normals times its sigmas."""
    offsets = np.concatenate([_stream(seed, (c, k)).standard_normal((rows, 6))
                              for c, rows in SPANS]) * ([translation] * 3 + [rotation] * 3)
    rot = Rotation.from_rotvec(offsets[:, 3:]).as_matrix()
    out = np.repeat(np.eye(4)[None], len(offsets), axis=0)
    out[:, :3, :3] = rot
    out[:, :3, 3] = center - rot @ center + offsets[:, :3]
    return out


@pytest.mark.parametrize("object_name", ["cube", "mug"])
def test_the_default_robots_evaluation_draws_the_rows_of_its_streams(object_name):
    grasp = shipped_grasps(object_name)[0]
    evaluated = evaluate_grasp(grasp, sigma=0.0133, n=530, seed=3, robot=DEFAULT_ROBOT,
                               engine="fast")
    q = _joint_rows_by_hand(grasp.q0, 0.0133, 3)
    with make_engine("fast", DEFAULT_ROBOT, object_name) as engine:
        rows, errors = evaluation_rows(grasp, engine, sigma=0.0133, n=530, seed=3)
        np.testing.assert_array_equal(rows, q)
        assert errors == {}
        closed = engine.run(q)
    _same_draws(evaluated, closed)
    assert evaluated.p_fc == np.mean(closed.outcome == FORCE_CLOSURE) and 0 < evaluated.p_fc < 1


def test_a_noise_model_of_every_source_draws_the_rows_of_its_streams_in_chunks():
    grasp = shipped_grasps("cube")[1]
    model = noise_model_from_spec(EVERY_SOURCE)
    with LocalExecutor(2) as executor:
        evaluated = evaluate_grasp(grasp, n=530, seed=5, robot=DEFAULT_ROBOT,
                                   engine="fast", noise_model=model, executor=executor)
    with make_engine("fast", DEFAULT_ROBOT, "cube") as engine:
        rows, errors = evaluation_rows(grasp, engine, sigma=0.0, n=530, seed=5,
                                       noise_model=model)
        # by hand: the joints, then the hand's spread (joint 7) and each finger's two
        # flexion joints (8-9, 10-11, 12-13), clipped to the limits
        q = _joint_rows_by_hand(grasp.q0, 0.0133, 5)
        z = np.concatenate([_stream(5, (c, 1)).standard_normal((n, 4)) for c, n in SPANS])
        offsets = np.column_stack([0.02 * z[:, 0]] + [0.03 * z[:, 1 + f] for f in (0, 0, 1,
                                                                                   1, 2, 2)])
        model_limits = engine.description.model
        q[:, 7:] = np.clip(q[:, 7:] + offsets, model_limits.lower[7:], model_limits.upper[7:])
        np.testing.assert_array_equal(rows, q)
        assert set(errors) == {"palm", "object_offset", "friction"}
        np.testing.assert_allclose(errors["palm"], _pose_errors_by_hand(
            5, 2, 0.002, 0.01, np.zeros(3)), rtol=0, atol=1e-15)
        np.testing.assert_allclose(errors["object_offset"], _pose_errors_by_hand(
            5, 3, 0.003, 0.02, engine.obj.center_of_mass), rtol=0, atol=1e-15)
        u = np.concatenate([_stream(5, (c, 4)).random(n) for c, n in SPANS])
        np.testing.assert_array_equal(errors["friction"],
                                      stats.truncnorm.ppf(u, -0.5 / 0.1, np.inf, loc=0.5,
                                                          scale=0.1))
        closed = engine.run(rows, **errors)
    _same_draws(evaluated, closed)
    assert evaluated.counts["start_collision"] > 0 and 0 < evaluated.p_fc < 1
