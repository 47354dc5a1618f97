"""The static hold check: the compiled feasibility LP against HiGHS, the verdict against hand
derivations of two-jaw pinches, the loads and the lift's acceleration against closed forms,
and a description robot's check at its shipped grasps."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import linprog

from kinegrasp_env.quality.soft_contacts import contact_wrenches, torsion_coefficient
from kinegrasp_env.quality.static_hold import feasible, gravity_loads, static_hold

MU, GRIP = 0.5, 20.0  # friction; each jaw's largest push, newtons


def test_feasibility_agrees_with_highs() -> None:
    """Proves the compiled phase-1 simplex decides feasibility as an independent LP solver
    (HiGHS) does, on random systems with both answers (equalities, inequalities, x >= 0)."""
    rng = np.random.default_rng(0)
    answers = []
    for _ in range(400):
        n, e, u = rng.integers(4, 40), rng.integers(1, 7), rng.integers(0, 6)
        a_eq = rng.normal(size=(e, n))
        b_eq = rng.normal(size=e) * rng.uniform(0.0, 3.0)
        a_ub, b_ub = rng.normal(size=(u, n)), rng.uniform(0.0, 2.0, size=u)
        highs = linprog(np.zeros(n), A_ub=a_ub if u else None, b_ub=b_ub if u else None,
                        A_eq=a_eq, b_eq=b_eq, bounds=[(0, None)] * n, method="highs")
        ours = feasible(a_eq, b_eq, a_ub.reshape(u, n), b_ub)
        assert ours == (highs.status == 0)
        answers.append(ours)
    assert 0 < sum(answers) < len(answers)  # both verdicts occur


def _pinch(contact_model: str, offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Two jaws pressing along x at x = -+0.03 on an object whose centre of mass is at
    (0, offset, 0) relative to the contacts' line: (primitives (P, 6), torque rows (2, P))."""
    points = np.array([[-0.03, -offset, 0.0], [0.03, -offset, 0.0]])
    normals = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])  # into the object
    w = contact_wrenches(points, normals, contact_model=contact_model, friction=MU,
                         num_edges=8, torque_scale=1.0, center=(0.0, 0.0, 0.0))
    per = w.shape[0] // 2
    rows = np.zeros((2, w.shape[0]))
    for jaw in range(2):  # a prismatic jaw closing along the contact normal: its push a . f
        rows[jaw, jaw * per:(jaw + 1) * per] = w[jaw * per:(jaw + 1) * per, :3] @ normals[jaw]
    return w, rows


def _held(contact_model: str, weight: float, direction, offset: float = 0.0) -> bool:
    w, rows = _pinch(contact_model, offset)
    load = np.zeros((1, 6))
    load[0, :3] = weight * np.asarray(direction, dtype=float)
    return bool(static_hold(w, rows, np.zeros(2), np.full(2, GRIP), load)[0])


@pytest.mark.parametrize("model", ["point", "soft"])
def test_pinch_carries_what_friction_allows(model: str) -> None:
    """Hand derivation: two jaws pushing with at most F each carry a weight across the
    closing axis up to 2 mu F (the cone's first edge is exactly along z here, the tangent
    basis of docs/conventions.md), and along the closing axis up to F (only the normal
    forces act there). 1% either side of each threshold."""
    for factor, expected in ((0.99, True), (1.01, False)):
        assert _held(model, factor * 2 * MU * GRIP, (0, 0, -1)) is expected
        assert _held(model, factor * GRIP, (1, 0, 0)) is expected


def test_soft_pinch_carries_an_offset_weight_within_its_torsion() -> None:
    """Hand derivation: a centre of mass d beside the contacts' line loads each contact with
    a force m g / 2 and a torsion m g d / 2 about its normal; the soft model's linearized limit
    f_t / mu + |tau| / gamma <= f_n <= F gives m g <= 2 F / (1 / mu + d / gamma). Point
    contacts carry no torque about the line: nothing."""
    d = 0.004
    gamma = torsion_coefficient(MU)
    limit = 2 * GRIP / (1 / MU + d / gamma)
    assert _held("soft", 0.99 * limit, (0, 0, -1), offset=d)
    assert not _held("soft", 1.01 * limit, (0, 0, -1), offset=d)
    assert not _held("point", 0.01 * limit, (0, 0, -1), offset=d)


def test_loads_turn_with_the_object() -> None:
    """The six loads are the world axes' gravity in the object frame (R^T d), in the order
    +x, -x, +y, -y, +z, -z, the lift's peak acceleration (minimum jerk, closed form
    10 h / (sqrt 3 T^2)) added to the downward one; no torque about the centre of mass."""
    from kinegrasp_env.montecarlo.hold_check import load_accelerations
    from kinegrasp_env.physics.protocol import HoldProtocol

    angle = 0.3
    rot = np.array([[math.cos(angle), -math.sin(angle), 0.0],
                    [math.sin(angle), math.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    protocol = HoldProtocol(gravity=9.81, lift_height=0.1, lift_time=1.0)
    lift = 10 * 0.1 / math.sqrt(3)
    loads = gravity_loads(2.0, load_accelerations(protocol), rot)
    world = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    for load, d in zip(loads, world, strict=True):
        size = 2.0 * (9.81 + (lift if d == (0, 0, -1) else 0.0))
        np.testing.assert_allclose(load[:3], size * (rot.T @ np.array(d, dtype=float)),
                                   rtol=1e-6, atol=1e-12)
        np.testing.assert_array_equal(load[3:], 0.0)


def test_peak_lift_acceleration_is_the_minimum_jerk_one() -> None:
    """A minimum-jerk rise of h in T peaks at 10 h / (sqrt(3) T^2) (closed form); the
    finite-difference value of the protocol's lift agrees to 1e-5 relative."""
    from kinegrasp_env.physics.motion import peak_lift_acceleration
    from kinegrasp_env.physics.protocol import HoldProtocol

    for height, duration in ((0.1, 1.0), (0.2, 0.5)):
        protocol = HoldProtocol(lift_height=height, lift_time=duration)
        exact = 10.0 * height / (math.sqrt(3.0) * duration ** 2)
        assert peak_lift_acceleration(protocol) == pytest.approx(exact, rel=1e-5)


def test_bad_input_is_refused_in_one_line() -> None:
    w, rows = _pinch("point")
    with pytest.raises(ValueError, match="NaN"):
        static_hold(w * np.nan, rows, np.zeros(2), np.full(2, GRIP), np.zeros((1, 6)))
    with pytest.raises(ValueError, match="contain 0"):
        static_hold(w, rows, np.ones(2), np.full(2, GRIP), np.zeros((1, 6)))
    with pytest.raises(ValueError, match="torque_rows"):
        static_hold(w, rows[:, :-1], np.zeros(2), np.full(2, GRIP), np.zeros((1, 6)))


@pytest.fixture(scope="module")
def panda_cube():
    from kinegrasp_env.montecarlo.evaluate import make_engine
    from kinegrasp_env.world.grasps import shipped_grasps

    engine = make_engine("fast", "panda", "cube", static_hold=True)
    yield engine, shipped_grasps("cube", robot="panda")
    engine.close()


def test_panda_jaw_rows_are_the_push_along_the_normal(panda_cube) -> None:
    """Sign and frame of a prismatic jaw's row: at the shipped cube grasps (jaws closing
    straight onto opposite faces) each contact's cone edges need exactly their normal
    component (1) of push from the jaw that carries them, and nothing from the other."""
    engine, grasps = panda_cube
    check = engine.hold_check
    q = np.array([g.q0 for g in grasps], dtype=float)
    batch = engine.close_batch(q)
    draws = engine.scored(q, batch)
    touched = draws.n_contacts >= 2
    assert touched.all()
    palm = engine.obj.pose_inverse @ check.kinematics.pose(q, engine.description.palm_link)
    values = engine.description.model.expand(q)
    values.update(batch.joints)
    present = draws.finger >= 0
    w = check.primitives(draws.points, draws.normals, present)
    rows = check.torque_rows(palm, values, draws.finger, draws.link, w)
    per = check.per_contact
    for b in range(len(grasps)):
        for slot in range(int(draws.n_contacts[b])):
            jaw = int(draws.finger[b, slot])
            edges = rows[b, :, slot * per:slot * per + engine.num_edges]
            np.testing.assert_allclose(edges[jaw], 1.0, atol=2e-3)
            np.testing.assert_allclose(np.delete(edges, jaw, axis=0), 0.0, atol=1e-12)


def test_panda_holds_the_cube_and_not_a_thousandfold_heavier_one(panda_cube) -> None:
    """At sigma 0 the shipped cube grasps hold the 0.108 kg cube in all six directions (its
    weight, ~1.1 N, is far inside 2 mu F = 20 N); the same grasps cannot carry 1000 times
    the mass (~1 kN against 20 N jaws)."""
    from dataclasses import replace

    from kinegrasp_env.montecarlo.hold_check import StaticHoldCheck

    engine, grasps = panda_cube
    q = np.array([g.q0 for g in grasps], dtype=float)
    assert engine.run(q).holds.all()
    heavy = StaticHoldCheck(engine.description, replace(engine.obj, density=5.0e5),
                            friction=engine.friction, num_edges=engine.num_edges,
                            finger_radius=engine.finger_radius)
    assert heavy.mass == pytest.approx(1000 * engine.hold_check.mass)
    batch = engine.close_batch(q)
    draws = engine.scored(q, batch)
    held = heavy.held(q, batch.joints, draws.points, draws.normals, draws.finger, draws.link)
    assert not held.any()


def test_capacity_is_the_edge_of_the_held_loads(panda_cube) -> None:
    """The bisection's capacity c is where the verdict turns: every load times 0.99 c held,
    some load times 1.01 c not (invariant of the check itself, on the shipped cube grasps)."""
    engine, grasps = panda_cube
    check = engine.hold_check
    q = np.array([g.q0 for g in grasps], dtype=float)
    batch = engine.close_batch(q)
    draws = engine.scored(q, batch)
    terms = (q, batch.joints, draws.points, draws.normals, draws.finger, draws.link)
    capacity = check.capacity(*terms, top=1e4, steps=30)
    assert (capacity > 1).all() and (capacity < 1e4).all()
    assert check.held(*terms, scale=0.99 * capacity).all()
    assert not check.held(*terms, scale=1.01 * capacity).all(axis=1).any()


def test_kuka_sdh_efforts_are_the_stated_assumptions() -> None:
    """The SDH's description states its finger motors' limits as the docs state the
    assumption (2.1 N m proximal, 1.4 N m distal), from the description, not the URDF."""
    from kinegrasp_env.physics.hand_motors import motor_efforts
    from kinegrasp_env.robot.catalog import load_robot

    motors = motor_efforts(load_robot("kuka_sdh"))
    assert {m.joint: m.effort for m in motors} == {
        f"f{i}_{link}": effort for i in (1, 2, 3)
        for link, effort in (("proximal", 2.1), ("distal", 1.4))}
    assert {m.source for m in motors} == {"description"}


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), float("inf")])
def test_motor_efforts_refuse_a_scale_that_is_not_positive(scale) -> None:
    """The efforts' multiple is the holding test's torque scale: a zero, negative or
    non-finite one is refused in one line (a zero once gave motors that cannot close), and
    a scale of 2 doubles the stated efforts (2.1 and 1.4 N m, above)."""
    from kinegrasp_env.physics.hand_motors import motor_efforts
    from kinegrasp_env.robot.catalog import load_robot

    with pytest.raises(ValueError, match=r"^scale must be a positive number, got"):
        motor_efforts(load_robot("kuka_sdh"), scale)
    doubled = {m.joint: m.effort for m in motor_efforts(load_robot("kuka_sdh"), 2.0)}
    assert doubled["f1_proximal"] == 4.2 and doubled["f3_distal"] == 2.8
