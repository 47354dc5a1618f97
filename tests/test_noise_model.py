"""The composable noise model: specs, streams, joint covariance, hand/palm/object/friction
errors through both engines, and per-row friction in the batched quality."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.noise_rows import joint_rows, model_rows
from kinegrasp_env.quality.epsilon import ferrari_canny, ferrari_canny_batch
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT, load_robot
from kinegrasp_env.robot.default_robot import default_description, default_hand_mount, kuka_sdh
from kinegrasp_env.robot.kinematics import Kinematics, rigid_inverse
from kinegrasp_env.sampling.noise import DISTRIBUTIONS, METHODS, JointNoise
from kinegrasp_env.sampling.noise_model import (
    FrictionSource,
    HandSource,
    JointsSource,
    NoiseModel,
    NoiseSpecError,
    PoseSource,
    as_noise_model,
    chunk_stream,
    offset_transforms,
    stream_rows,
)
from kinegrasp_env.sampling.noise_spec import (
    PRESETS,
    load_noise_model,
    noise_model_from_spec,
    spec_of,
)
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.world.grasps import shipped_grasps

DRAW_FIELDS = ("outcome", "quality", "n_contacts", "points", "normals", "finger", "link", "hand")
SDH = load_robot(DEFAULT_ROBOT)


def _same_draws(a, b) -> None:
    for name in DRAW_FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


# ----------------------------------------------------------------------------- JointNoise
@pytest.mark.parametrize("kind", DISTRIBUTIONS)
@pytest.mark.parametrize("method", METHODS)
def test_a_joints_only_model_draws_the_joint_noise_numbers(kind, method):
    """The model's rows (``joint_rows``, ``model_rows``) of chunk 0 and of 33 rows of chunk
    7 are the JointNoise's numbers of the chunk's stream, and the configurations its
    joint-noise path draws (``chunk_configurations``), bit for bit."""
    sigma = (0.01, 0.02, 0.005, 0.03, 0.0, 0.01, 0.02)
    noise = JointNoise(sigma, kind)
    model = as_noise_model(noise)
    q0 = np.arange(14) * 0.1
    for index, size in ((0, 250), (7, 33)):
        offset = index * 250
        np.testing.assert_array_equal(joint_rows(model, 7, 11, offset, size, method),
                                      noise.sample(size, 7, chunk_stream(11, index), method))
        q, errors = model_rows(model, q0, SDH, 11, offset, size, np.zeros(3), method)
        np.testing.assert_array_equal(
            q, chunk_configurations(q0, 7, sigma, kind, 11, offset, size, method))
        assert errors == {}


@pytest.mark.parametrize("engine, samples", [("fast", 300), ("pybullet", 24)])
def test_a_joints_only_spec_evaluates_bit_for_bit_as_joint_noise(engine, samples):
    grasp = shipped_grasps("spray_flask")[3]
    spec = noise_model_from_spec({"joints": {"sigma": 0.0233, "distribution": "uniform"}})
    a = evaluate_grasp(grasp, sigma=0.0233, noise="uniform", n=samples, seed=5,
                       engine=engine)
    b = evaluate_grasp(grasp, noise_model=spec, n=samples, seed=5, engine=engine)
    _same_draws(a.draws, b.draws)
    assert a.counts == b.counts and a.n == b.n
    for name in ("p_fc", "ci", "q_mean", "q_std", "q_skew", "q_nominal"):
        # every number, bit for bit (NaN where both are)
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert 0 < a.p_fc < 1  # the draws vary: the comparison says something


def test_every_source_draws_from_its_own_stream():
    """Rows 1000 .. 1049 (chunk 4) of a run: adding hand, palm and friction sources leaves
    the joints' and the object's draws as they were."""
    base = NoiseModel(joints=JointsSource(0.02), object=PoseSource(0.01, 0.01, name="object"))
    more = dataclasses.replace(base, friction=FrictionSource("gaussian", 0.5, 0.1),
                               hand=HandSource(0.01, 0.02), palm=PoseSource(0.005, 0.001))
    q0, center = shipped_grasps("cube")[0].q0, np.array([0.01, -0.02, 0.03])
    qa, a = model_rows(base, q0, SDH, 3, 1000, 50, center)
    qb, b = model_rows(more, q0, SDH, 3, 1000, 50, center)
    np.testing.assert_array_equal(qa[:, :7], qb[:, :7])
    np.testing.assert_array_equal(a["object_offset"], b["object_offset"])
    assert set(a) == {"object_offset"} and b["friction"].shape == (50,)
    assert not np.array_equal(qa[:, 7:], qb[:, 7:])  # the hand source drew
    # the joints keep the chunk's own stream (the JointNoise one); others their child streams
    np.testing.assert_array_equal(qa[:, :7], q0[:7] + JointNoise(0.02).sample(
        50, 7, chunk_stream(3, 4)))
    np.testing.assert_array_equal(b["friction"], FrictionSource("gaussian", 0.5, 0.1).sample(
        chunk_stream(3, 4, "friction"), 50))
    streams = [chunk_stream(3, 4, s).random(4) for s in ("joints", "hand", "palm", "object",
                                                           "friction")]
    assert len({tuple(s) for s in streams}) == 5


def test_adding_a_friction_source_leaves_the_joint_draws_identical():
    grasp = shipped_grasps("spray_flask")[0]
    joints = {"joints": {"sigma": 0.0233}}
    options = dict(n=200, seed=2, engine="fast")
    a = evaluate_grasp(grasp, noise_model=noise_model_from_spec(joints), **options)
    fixed = noise_model_from_spec({**joints, "friction": {"distribution": "fixed",
                                                          "value": 0.5}})
    b = evaluate_grasp(grasp, noise_model=fixed, **options)
    # mu fixed at the engine's 0.5: the same draws scored the same, bit for bit
    _same_draws(a.draws, b.draws)
    varied = noise_model_from_spec({**joints, "friction": {"distribution": "uniform",
                                                           "low": 0.2, "high": 0.8}})
    c = evaluate_grasp(grasp, noise_model=varied, **options)
    for name in ("n_contacts", "points", "normals", "hand"):  # the same geometry ...
        np.testing.assert_array_equal(getattr(a.draws, name), getattr(c.draws, name))
    assert not np.array_equal(a.draws.quality, c.draws.quality)  # ... scored with other mu


# ----------------------------------------------------------------------------- joints
def test_a_diagonal_covariance_equals_per_joint_sigmas_draw_by_draw():
    sigma = np.array([0.0133, 0.02, 0.005, 0.0433, 0.001, 0.03, 0.0233])
    per_joint = NoiseModel(joints=JointsSource(tuple(sigma)))
    covariance = NoiseModel(joints=JointsSource(covariance=np.diag(sigma**2).tolist()))
    np.testing.assert_array_equal(joint_rows(per_joint, 7, 9, 500, 500),
                                  joint_rows(covariance, 7, 9, 500, 500))


def test_a_correlated_covariance_reproduces_its_sample_covariance():
    rng = np.random.default_rng(0)
    root = rng.normal(size=(7, 7)) * 0.01
    cov = root @ root.T
    cov[:, 2] = cov[2, :] = 0.0  # a singular (semi-definite) covariance: joint 2 exact
    eps = joint_rows(NoiseModel(joints=JointsSource(covariance=cov.tolist())), 7, 1, 0,
                     200_000)
    # standard error of a sample covariance entry: sqrt((S_ii S_jj + S_ij^2) / n)
    se = np.sqrt((np.outer(np.diag(cov), np.diag(cov)) + cov**2) / eps.shape[0])
    assert np.all(np.abs(np.cov(eps.T) - cov) <= 5 * se + 1e-15)  # 5 standard errors
    assert np.all(eps[:, 2] == 0.0)
    bias = np.linspace(-0.01, 0.01, 7)
    shifted = NoiseModel(joints=JointsSource(covariance=cov.tolist(), bias=tuple(bias)))
    np.testing.assert_array_equal(joint_rows(shifted, 7, 1, 0, 100), eps[:100] + bias)


# ----------------------------------------------------------------------------- specs
BAD_SPECS = [
    ({"jionts": {"sigma": 0.1}}, "unknown source 'jionts'"),
    ({"joints": {"sigma": 0.1, "kind": "gaussian"}}, "unknown key joints.kind"),
    ({"joints": {"sigma": -0.01}}, "joints.sigma must be >= 0, got -0.01"),
    ({"joints": {"sigma": []}}, "joints.sigma must be a scalar or one value per arm joint"),
    ({"joints": {"sigma": [0.1, 0.2], "bias": [0.1] * 3}},
     "joints: sigma describes 2 joints and bias describes 3 joints"),
    ({"joints": {"sigma": 4.0}}, "joints.sigma must be <= pi (3.14159 rad), got 4"),
    ({"joints": {"sigma": "small"}}, "joints.sigma must be a number"),
    ({"joints": {"distribution": "cauchy"}}, "joints.distribution 'cauchy' is unknown"),
    ({"joints": {"covariance": (np.eye(7) + np.eye(7, k=1) * 1e-3).tolist()}},
     "joints.covariance is not symmetric: entry [0][1] = 0.001"),
    ({"joints": {"covariance": np.diag([1e-4] * 6 + [-1e-4]).tolist()}},
     "not positive semi-definite: smallest eigenvalue -0.0001"),
    ({"joints": {"covariance": np.zeros((6, 7)).tolist()}},
     "joints.covariance[0] must be 6 values"),
    ({"joints": {"covariance": []}}, "d rows of d numbers, got no rows"),
    ({"joints": {"covariance": [[1e-4, 0.0], [0.0]]}}, "joints.covariance[1] must be 2 values"),
    ({"joints": {"covariance": np.eye(7).tolist(), "distribution": "uniform"}},
     "covariance needs distribution gaussian"),
    ({"joints": {"covariance": np.eye(7).tolist(), "bias": [0.1] * 6}},
     "joints: covariance describes 7 joints and bias describes 6 joints"),
    ({"hand": {"closing_sigma": []}},
     "hand.closing_sigma must be a scalar or one value per finger"),
    ({"palm": {"translation_sigma": -0.005}}, "palm.translation_sigma must be >= 0"),
    ({"object": {"rotation_sigma": [0.01, 0.01, -0.01]}}, "object.rotation_sigma must be >= 0"),
    ({"object": {"position_sigma": 0.01}}, "unknown key object.position_sigma"),
    ({"friction": {"distribution": "uniform", "low": -0.1, "high": 0.5}},
     "friction.low must be >= 0 (mu has no negative values), got -0.1"),
    ({"friction": {"distribution": "gaussian", "mean": -0.2, "sigma": 0.1}},
     "friction.mean must be >= 0"),
    ({"friction": {"distribution": "fixed", "value": -1}}, "friction.value must be >= 0"),
    ({"friction": {"distribution": "uniform", "low": 0.6, "high": 0.4}},
     "friction.high (0.4) is below friction.low (0.6)"),
    ({"friction": {"distribution": "gaussian", "low": 0.1}},
     "friction.low is a key of distribution uniform, not of gaussian: give distribution: "
     "uniform"),
    ({"friction": {"distribution": "gaussian", "spread": 0.1}},
     "unknown key friction.spread (with distribution gaussian)"),
    # a missing key read as its default: uniform on [0, 0] (mu 0 on every draw)
    ({"friction": {"distribution": "uniform"}},
     "friction with distribution uniform needs low and high"),
    ({"friction": {"distribution": "fixed"}}, "friction with distribution fixed needs value"),
    ({"friction": {"mean": 0.5}},
     "friction with distribution gaussian, the default, needs sigma"),
    ({"friction": {"value": 0.2}}, "friction.value is a key of distribution fixed, not of "
     "gaussian, the default: give distribution: fixed"),
    ({"friction": {"distribution": "lognormal"}}, "friction.distribution 'lognormal'"),
    ({"preset": "graspit"}, "unknown preset 'graspit'"),
    ({"palm": 0.01}, "palm must be a mapping"),
    ([0.01], "expected a mapping of sources"),
]


@pytest.mark.parametrize("spec, needle", BAD_SPECS)
def test_bad_specs_are_one_line_errors_naming_the_value(spec, needle):
    with pytest.raises(NoiseSpecError) as info:
        noise_model_from_spec(spec, where="my.yaml")
    message = str(info.value)
    assert needle in message and message.startswith("my.yaml: ")
    assert "\n" not in message


def test_spec_files_presets_and_round_trip(tmp_path):
    path = tmp_path / "noise.yaml"
    path.write_text("preset: dexnet\njoints: {sigma: 1.33e-2, distribution: triangular, "
                    "bias: 1e-3}\nhand: {spread_sigma: 0.01, closing_sigma: [0.01, 0.02, 0.03]}\n")
    model = load_noise_model(path)
    assert model.joints == JointsSource(0.0133, "triangular", bias=0.001)
    assert model.joints.count is None  # scalars: any arm
    one = JointsSource([0.0133], bias=[0.001])  # lists of one value: scalars, any arm
    assert one.count is None and one.sigma_vector(6).tolist() == [0.0133] * 6
    with pytest.raises(NoiseSpecError, match="covariance describes 7 joints and sigma "
                                             "describes 6 joints"):
        JointsSource([0.01] * 6, covariance=np.eye(7).tolist())
    assert model.palm == PoseSource(0.005, 0.001)  # Dex-Net's gripper pose: 5 mm, 0.001 rad
    assert model.object == PoseSource(0.01, 0.01)  # object pose: 1 cm, 0.01 rad
    assert model.friction == FrictionSource("gaussian", mean=0.5, sigma=0.1)
    assert spec_of(model)["friction"] == PRESETS["dexnet"]["friction"]
    assert noise_model_from_spec(spec_of(model)) == model
    json_path = tmp_path / "noise.json"
    json_path.write_text('{"object": {"translation_sigma": [0.01, 0.01, 0.0]}}')
    assert load_noise_model(json_path).sources == ("object",)
    path.write_text("joints: {sigma: 0.01}\njoints: {sigma: 0.02}\n")
    with pytest.raises(NoiseSpecError, match="appears twice"):
        load_noise_model(path)
    # a YAML merge key is read as YAML reads it, an explicit key overriding a merged one
    path.write_text("palm: &pose {translation_sigma: 0.004, rotation_sigma: 0.002}\n"
                    "object:\n  <<: *pose\n  rotation_sigma: 0.001\n")
    merged = load_noise_model(path)
    assert merged.palm == PoseSource(0.004, 0.002) and merged.object == PoseSource(0.004, 0.001)
    with pytest.raises(NoiseSpecError, match=r"missing\.yaml: no such file$"):
        load_noise_model(tmp_path / "missing.yaml")


# ----------------------------------------------------------------------------- hand, poses
def test_hand_offsets_shift_both_joints_of_a_finger_within_the_limits():
    """The SDH's layout, hard-coded here: the hand stream's column 0 times the spread sigma
    on the spread (joint 7), column 1 + f times finger f's closing sigma on both of its
    flexion joints (8 + 2f, 9 + 2f), clipped to the joints' limits; the arm untouched."""
    q0 = shipped_grasps("spray_flask")[0].q0  # spread at its lower limit 0
    model = NoiseModel(hand=HandSource(0.05, (0.01, 0.02, 0.3)))
    q, errors = model_rows(model, q0, SDH, 0, 0, 400, np.zeros(3))
    hand = stream_rows(0, "hand", 0, 400, lambda g, m: g.standard_normal((m, 4))) * [
        0.05, 0.01, 0.02, 0.3]
    lower, upper = SDH.model.lower[7:], SDH.model.upper[7:]
    assert errors == {} and lower[0] == 0.0
    np.testing.assert_array_equal(q[:, :7], np.repeat(q0[None, :7], 400, 0))
    np.testing.assert_array_equal(q[:, 7], np.clip(q0[7] + hand[:, 0], 0.0, upper[0]))
    for f in range(3):
        shift = np.clip(q0[8 + 2 * f: 10 + 2 * f] + hand[:, [1 + f]],
                        lower[1 + 2 * f: 3 + 2 * f], upper[1 + 2 * f: 3 + 2 * f])
        np.testing.assert_array_equal(q[:, 8 + 2 * f: 10 + 2 * f], shift)
    assert 0.3 < np.mean(q[:, 7] == 0.0) < 0.7  # the clipping is compared too


def test_rotation_vectors_give_rotations_about_the_centre():
    offsets = np.random.default_rng(1).normal(size=(50, 6)) * np.array([0.01] * 3 + [0.8] * 3)
    offsets[0, 3:] = 0.0
    center = np.array([0.01, -0.02, 0.07])
    t = offset_transforms(offsets, center)
    rot = t[:, :3, :3]
    np.testing.assert_allclose(rot @ np.swapaxes(rot, 1, 2), np.broadcast_to(np.eye(3),
                                                                          rot.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-14)
    # the rotation vector is the axis (fixed by R) times the angle
    axis = offsets[1:, 3:] / np.linalg.norm(offsets[1:, 3:], axis=1, keepdims=True)
    np.testing.assert_allclose((rot[1:] @ axis[..., None])[..., 0], axis, atol=1e-14)
    angle = np.arccos(np.clip((np.trace(rot[1:], axis1=1, axis2=2) - 1) / 2, -1, 1))
    np.testing.assert_allclose(angle, np.linalg.norm(offsets[1:, 3:], axis=1), atol=1e-12)
    # the centre only moves by the translation
    np.testing.assert_allclose((t[:, :3, :3] @ center) + t[:, :3, 3], center + offsets[:, :3],
                               atol=1e-15)


def _flange(q):
    return Kinematics(kuka_sdh()).pose(q, default_hand_mount())


#: (points m, normals, Q) tolerances of the two ways round. The fast engine computes the
#: same relative poses either way: measured 5e-16 m, 3e-14, 8e-16 (Q ~ 1e-2), from the rounding
#: of the two transform products. The reference places the object body in pybullet either
#: way, at poses a rounding apart; pybullet's steps then differ and each touch is polished to
#: within POLISH_TOL (1e-9 m) of the gap's zero: measured 2.3e-9 m, 1.4e-7 (an edge's normal)
#: and 3.1e-9 on 48 draws.
SAME_DRAW_TOL = {"fast": (1e-12, 1e-12, 1e-14), "pybullet": (1e-8, 1e-6, 1e-8)}


@pytest.mark.parametrize("engine_name, n", [("fast", 40), ("pybullet", 16)])
def test_object_error_and_inverse_palm_error_give_the_same_draws(engine_name, n):
    """An object moved by T as seen from the flange is the hand moved by T^-1: contacts (in
    the object frame) and Q agree draw by draw, for the same stream of T (to
    :data:`SAME_DRAW_TOL`)."""
    grasp = shipped_grasps("spray_flask")[1]
    q = chunk_configurations(grasp.q0, 7, 0.01, "gaussian", 3, 0, n)
    offsets = chunk_stream(3, 0, "palm").standard_normal((n, 6)) * ([3e-3] * 3 + [0.02] * 3)
    motion = offset_transforms(offsets)  # T, in the flange frame
    with make_engine(engine_name, DEFAULT_ROBOT, "spray_flask") as engine:
        flange, pose = _flange(q), engine.obj.pose
        object_error = rigid_inverse(pose) @ flange @ motion @ rigid_inverse(flange) @ pose
        by_palm = engine.run(q, palm=rigid_inverse(motion))
        by_object = engine.run(q, object_offset=object_error)
        nominal = engine.run(q)
    np.testing.assert_array_equal(by_palm.outcome, by_object.outcome)
    np.testing.assert_array_equal(by_palm.n_contacts, by_object.n_contacts)
    points, normals, quality = SAME_DRAW_TOL[engine_name]
    np.testing.assert_allclose(by_palm.points, by_object.points, atol=points)
    np.testing.assert_allclose(by_palm.normals, by_object.normals, atol=normals)
    np.testing.assert_allclose(by_palm.quality, by_object.quality, rtol=0, atol=quality)
    assert len(set(by_palm.outcome.tolist())) > 1  # mixed outcomes: the test has teeth
    assert not np.array_equal(by_palm.outcome, nominal.outcome)  # the errors matter


def test_the_engines_take_a_palm_error_in_the_same_frame():
    """The fast engine (the batched closing: each link placed by the mount's pose times the
    error) and the reference (pybullet's scene: the object moved by the error's inverse
    relative to the hand) on the same palm errors about the description's ``hand_mount``:
    the same outcomes, the same contacts. Rotations of 0.05 rad about another
    frame move the fingertips by millimetres (measured with the last arm link as the
    frame: 4 of 24 outcomes differ, contacts 1.5 mm apart in the median)."""
    grasp = shipped_grasps("spray_flask")[1]
    n = 24
    q = chunk_configurations(grasp.q0, 7, 0.003, "gaussian", 5, 0, n)
    rng = np.random.default_rng(5)
    palm = offset_transforms(rng.normal(size=(n, 6)) * ([1e-3] * 3 + [0.05] * 3))
    with make_engine("fast", DEFAULT_ROBOT, "spray_flask") as fast, \
            make_engine("pybullet", DEFAULT_ROBOT, "spray_flask") as reference:
        a, b = fast.run(q, palm=palm), reference.run(q, palm=palm)
    np.testing.assert_array_equal(a.outcome, b.outcome)
    assert len(set(a.outcome.tolist())) > 2  # mixed outcomes
    # measured: 2.5e-9 m at most (the engines' own agreement); 1e-7 leaves 40x
    np.testing.assert_allclose(a.points, b.points, atol=1e-7)


def test_an_object_error_equals_moving_the_object_in_pybullet():
    """An object error (its true pose off the believed one) gives the contacts of a pybullet
    scene built with the object at its true pose and no error (contacts in the true
    object's frame both ways)."""
    grasp = shipped_grasps("spray_flask")[2]
    n = 8
    q = chunk_configurations(grasp.q0, 7, 0.005, "gaussian", 1, 0, n)
    with make_engine("pybullet", DEFAULT_ROBOT, "spray_flask") as engine:
        obj = engine.obj
        offsets = chunk_stream(1, 0, "object").standard_normal((n, 6)) * (
            [0.004] * 3 + [0.03] * 3)
        errors = offset_transforms(offsets, obj.center_of_mass)
        draws = engine.run(q, object_offset=errors)
    for i in range(n):
        moved = dataclasses.replace(obj, pose=obj.pose @ errors[i])
        with RobotWorld(default_description(), moved) as world:  # the object built there
            result = world.auto_close(q[i])
            if result.start_collision:
                assert draws.n_contacts[i] == 0
                continue
            k = draws.n_contacts[i]
            assert len(result.contacts) == k
            # measured up to 2.8e-8 m and 8.3e-7 (pybullet's distances, then the closing's
            # bisection and polish, see another path): 1e-7 and 5e-6
            np.testing.assert_allclose([c.point for c in result.contacts], draws.points[i, :k],
                                       atol=1e-7)
            np.testing.assert_allclose([c.normal for c in result.contacts],
                                       draws.normals[i, :k], atol=5e-6)
    assert np.sum(draws.n_contacts > 0) >= n // 2


# ----------------------------------------------------------------------------- friction
def test_per_row_friction_equals_one_call_per_row():
    grasp = shipped_grasps("drill")[0]
    engine = make_engine("fast", DEFAULT_ROBOT, "drill")
    draws = engine.run(chunk_configurations(grasp.q0, 7, 0.02, "gaussian", 0, 0, 120))
    rows = np.flatnonzero(draws.n_contacts == 3)
    mu = np.random.default_rng(4).uniform(0.05, 1.0, rows.size)
    mu[::7] = 0.0  # frictionless rows are never in force closure with 3 contacts
    settings = {"torque_scale": engine.obj.torque_scale, "center": engine.obj.center_of_mass}
    batch = ferrari_canny_batch(draws.points[rows, :3], draws.normals[rows, :3], friction=mu,
                                **settings)
    one_by_one = [ferrari_canny(draws.points[r, :3], draws.normals[r, :3], friction=m,
                                method="qhull", **settings) for r, m in zip(rows, mu, strict=True)]
    np.testing.assert_allclose(batch, one_by_one, rtol=1e-9, atol=1e-15)
    assert np.all(batch[::7] == 0) and np.any(batch > 0)
    with pytest.raises(ValueError, match=r"friction\[1\] = -0.1"):
        ferrari_canny_batch(draws.points[rows[:2], :3], draws.normals[rows[:2], :3],
                            friction=[0.5, -0.1])


def _mu_min(engine, grasp) -> tuple[float, int]:
    """(least mu for force closure by bisection on the exact (qhull) Q, the contacts)."""
    nominal = engine.run(grasp.q0[None])
    k = int(nominal.n_contacts[0])
    points, normals = nominal.points[0, :k], nominal.normals[0, :k]

    def closes(mu: float) -> bool:
        return ferrari_canny(points, normals, friction=mu, torque_scale=engine.obj.torque_scale,
                             center=engine.obj.center_of_mass, method="qhull") > 0

    lo, hi = 0.0, 2.0
    assert closes(hi) and not closes(lo)
    while hi - lo > 1e-10:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if closes(mid) else (mid, hi)
    return hi, k


def _p_at_least(spec: dict, mu_min: float) -> float:
    """Exact P(mu >= mu_min) of a friction distribution."""
    if spec["distribution"] == "uniform":
        return float(np.clip((spec["high"] - mu_min) / (spec["high"] - spec["low"]), 0, 1))
    mean, sigma = spec["mean"], spec["sigma"]
    return float(stats.norm.sf(mu_min, mean, sigma) / stats.norm.sf(0.0, mean, sigma))


FRICTION_CASES = [
    ("spray_flask", 0, {"distribution": "gaussian", "mean": 0.45, "sigma": 0.1}),
    ("cube", 2, {"distribution": "gaussian", "mean": 0.1, "sigma": 0.2}),  # truncation matters
    ("drill", 2, {"distribution": "uniform", "low": 0.3, "high": 0.7}),
    ("mug", 1, {"distribution": "gaussian", "mean": 0.3, "sigma": 0.15}),
    ("spray_flask", 3, {"distribution": "uniform", "low": 0.0, "high": 0.8}),
]


def _friction_only_agrees(name: str, index: int, spec: dict, samples: int) -> None:
    grasp = shipped_grasps(name)[index]
    with make_engine("fast", DEFAULT_ROBOT, name) as engine:
        mu_min, k = _mu_min(engine, grasp)
    exact = _p_at_least(spec, mu_min)
    model = noise_model_from_spec({"friction": spec})
    result = evaluate_grasp(grasp, noise_model=model, n=samples, seed=6,
                            engine="fast")
    # every draw keeps the nominal contacts; force closure is monotone in mu, so a draw is
    # in force closure exactly when its mu is at least mu_min (each draw's mu: the
    # friction source's rows of the run's streams)
    assert np.all(result.draws.n_contacts == k)
    mu = stream_rows(6, "friction", 0, samples, model.friction.sample)
    np.testing.assert_array_equal(result.draws.outcome == FORCE_CLOSURE, mu >= mu_min)
    # and the estimate's interval (99.9%) holds the exact probability
    fc = result.counts["force_closure"]
    lo, hi = wilson_interval(fc, samples, confidence=0.999)
    assert lo <= exact <= hi, (name, index, spec, mu_min, exact, fc / samples)
    assert 0.05 < exact < 0.95  # an informative case


@pytest.mark.parametrize("name, index, spec", FRICTION_CASES)
def test_friction_only_force_closure_is_the_exact_probability_of_mu_above_its_minimum(
        name, index, spec):
    _friction_only_agrees(name, index, spec, samples=2000)


def test_engine_errors_are_checked_and_refused_where_not_taken():
    """Bad errors are one line naming them; an engine that does not take errors (the physics
    engine: one simulated mu, the arm not split from the hand) refuses pose errors and a
    per-draw mu alike."""
    engine = make_engine("fast", DEFAULT_ROBOT, "cube")
    q0 = shipped_grasps("cube")[0].q0[None]
    with pytest.raises(ValueError, match=r"palm must have shape \(1, 4, 4\)"):
        engine.run(q0, palm=np.eye(4))
    with pytest.raises(ValueError, match="friction must be >= 0"):
        engine.run(q0, friction=[-0.5])
    engine.takes_errors = False
    for key, value in (("palm", np.eye(4)[None]), ("object_offset", np.eye(4)[None]),
                       ("friction", [0.5])):
        with pytest.raises(ValueError, match=f"takes joint and hand noise only, not {key} "
                                             "errors"):
            engine.run(q0, **{key: value})


def test_a_model_of_zeros_is_the_nominal_grasp():
    grasp = shipped_grasps("mug")[4]
    zeros = noise_model_from_spec({"joints": {"sigma": 0.0}, "hand": {},
                                   "palm": {"translation_sigma": 0.0},
                                   "object": {"rotation_sigma": [0.0, 0.0, 0.0]}})
    result = evaluate_grasp(grasp, noise_model=zeros, n=20, seed=1, engine="fast")
    # every draw is the nominal one: the draws of sigma = 0 joint noise, bit for bit
    _same_draws(result.draws, evaluate_grasp(grasp, sigma=0.0, n=20, seed=1,
                                             engine="fast").draws)
    assert result.p_fc == 1.0 and np.all(result.draws.quality == result.draws.quality[0])
    assert result.q_mean == pytest.approx(grasp.q_nominal, rel=1e-4)  # the reference's Q


# ----------------------------------------------------------------------------- env
def test_env_takes_a_noise_model_as_an_option():
    import gymnasium as gym

    import kinegrasp_env  # noqa: F401  (registers the env IDs)
    from kinegrasp_env.world.grasps import Grasp

    spec = {"joints": {"sigma": 0.02}, "object": {"translation_sigma": 0.004},
            "friction": {"distribution": "uniform", "low": 0.3, "high": 0.7}}
    env = gym.make("KineGrasp-v0", n_draws=32, engine="fast").unwrapped
    task = {"object": "spray_flask", "grasp": 1}
    plain, _ = env.reset(seed=5, options={**task, "sigma": 0.02})
    obs, info = env.reset(seed=5, options={**task, "noise_model": spec})
    np.testing.assert_array_equal(obs, plain)  # the observation shows the joint noise only
    assert info["noise_model"] == spec_of(noise_model_from_spec(spec))
    _, reward, _, _, info = env.step(np.array([0.5, -1.0], dtype=np.float32))
    g = env.grasp
    here = Grasp(g.object, env.q.copy(), g.palm_pose, g.points, g.normals, g.fingers, g.links,
                 g.q_nominal)
    stats = evaluate_grasp(here, noise_model=noise_model_from_spec(spec), n=32,
                           seed=info["draw_seed"], engine="fast")
    assert reward == stats.p_fc == info["p_fc"]
    with pytest.raises(ValueError, match="or the reset options sigma/noise, not both"):
        env.reset(options={**task, "noise_model": spec, "sigma": 0.01})
    with pytest.raises(ValueError, match=r"friction\.high"):
        env.reset(options={"noise_model": {"friction": {"distribution": "uniform",
                                                        "low": 0.5, "high": 0.1}}})
    env.close()
    fixed = gym.make("KineGraspSelect-v0", n_draws=8, engine="fast", noise_model=spec).unwrapped
    _, info = fixed.reset(seed=0)
    assert info["noise_model"]["object"] == {"translation_sigma": 0.004, "rotation_sigma": 0.0}
    fixed.close()


def test_the_documented_example_spec_loads():
    from pathlib import Path

    example = Path(__file__).resolve().parents[1] / "docs" / "noise_example.yaml"
    model = load_noise_model(example)
    assert model.sources == ("joints", "palm", "object", "friction")
    assert model.joints == JointsSource(0.0133)


@pytest.mark.parametrize("text", ["", "# only a comment\n", "{}\n", "joints:\n",
                                  "joints:\nfriction:\n"])
def test_a_spec_of_no_source_is_refused_alike_however_it_is_empty(tmp_path, text):
    """An empty file, a comment, an empty mapping and empty sections all name no source of
    error: one refusal in the same words (an evaluation of such a spec was noise-free
    without a word, or refused as "not a mapping", depending on how it was empty)."""
    path = tmp_path / "empty.yaml"
    path.write_text(text)
    with pytest.raises(NoiseSpecError) as info:
        load_noise_model(path)
    assert str(info.value) == (f"{path}: names no source of error (a section of joints, "
                               "hand, palm, object or friction, or a preset); an evaluation "
                               "without noise is sigma 0")
