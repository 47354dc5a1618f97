"""One layout of random streams for every robot (docs/conventions.md, "Random streams").

What each test proves:

* :func:`~kinegrasp_env.sampling.noise_model.stream_rows` gives row r of a run from chunk
  ``r // 250``'s own stream, row ``r % 250``: checked against numpy's generators seeded by
  hand (``SeedSequence(seed, spawn_key=(c,))``, ``(c, k)`` for source k), for spans that
  start and end inside chunks and cross them; a layout of one stream, or chunks of another
  size, fails it;
* the default robot run through its description (``kuka_sdh``: the description robots'
  evaluation, in one process and in chunks on two processes) closes the same draws as its
  own evaluation, draw for draw (outcome and Q), with joint noise and with a noise model of
  every source; the two share the fast closing, so this proves they draw the same rows and
  score them alike, and both report the closed hand alike (joint noise in one process; a
  noise model of every source in chunks on two processes).
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from kinegrasp_env.montecarlo import robot_chunks
from kinegrasp_env.montecarlo.draws import DrawBatch
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.montecarlo.robot_evaluate import evaluate_robot_grasp
from kinegrasp_env.sampling.noise import JointNoise
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
    robot_chunks.close_engines()


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


def _same_draws(default, described) -> None:
    # the same closing and scoring: equal Q (a few ulps allowed between code paths), and
    # every other per-draw field equal (one draw format: the closed hand where each
    # closing left it, NaN where none)
    np.testing.assert_allclose(described.draws.quality, default.draws.quality,
                               rtol=1e-12, atol=1e-15)
    slots = default.draws.points.shape[1]  # the default robot keeps MAX_CONTACTS
    for f in fields(DrawBatch):
        mine, own = getattr(described.draws, f.name), getattr(default.draws, f.name)
        if f.name in ("points", "normals", "finger", "link"):
            # a description keeps a slot per finger link; the SDH's closing touches with
            # its 6 phalanges only, so the slots past them stay empty
            padding = np.isnan(mine[:, slots:]) if mine.dtype.kind == "f" else (
                mine[:, slots:] == -1)
            assert padding.all(), f.name
            mine = mine[:, :slots]
        if f.name != "quality":
            np.testing.assert_array_equal(mine, own, err_msg=f.name)


@pytest.mark.parametrize("object_name", ["cube", "mug"])
def test_the_default_robots_description_draws_its_own_evaluation(object_name):
    grasp = shipped_grasps(object_name)[0]
    default = evaluate_grasp(grasp, JointNoise(0.0133), 530, seed=3, engine="fast",
                             return_draws=True)
    described = evaluate_robot_grasp(grasp, sigma=0.0133, n=530, seed=3, robot="kuka_sdh",
                                     engine="fast")
    _same_draws(default, described)
    assert described.p_fc == default.p_fc and 0 < default.p_fc < 1


def test_a_noise_model_of_every_source_draws_the_same_rows_in_chunks():
    grasp = shipped_grasps("cube")[1]
    model = noise_model_from_spec(EVERY_SOURCE)
    default = evaluate_grasp(grasp, model, 530, seed=5, engine="fast", return_draws=True)
    with LocalExecutor(2) as executor:
        described = evaluate_robot_grasp(grasp, sigma=0.0, n=530, seed=5, robot="kuka_sdh",
                                         engine="fast", noise_model=model, executor=executor)
    _same_draws(default, described)
    assert described.counts["start_collision"] > 0 and 0 < default.p_fc < 1
