"""The holding test's graded score (:func:`~kinegrasp_env.physics.protocol.hold_margin`):
values derived by hand from phase records, and, on real quick holding tests in pybullet, the
property that makes it a refinement of the verdict (every held draw above every other)."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.physics.protocol import (
    HELD,
    PHASES,
    QUICK_PROTOCOL,
    HoldProtocol,
    hold_margin,
)

FULL = HoldProtocol()  # rest, six gravity directions, lift: 8 phases (no shake)


def records(rows: list[tuple[list[int], float, float]]):
    """Phase arrays (n, len(PHASES)) from (held per phase run, largest shift in m, largest
    turn in rad), the shift and turn put in the first phase run (only the maxima count)."""
    n, p = len(rows), len(PHASES)
    held = np.full((n, p), -1, np.int8)
    shift, turn = np.full((n, p), np.nan), np.full((n, p), np.nan)
    for i, (flags, s, t) in enumerate(rows):
        held[i, :len(flags)] = flags
        if flags:
            shift[i, :len(flags)], turn[i, :len(flags)] = 0.0, 0.0
            shift[i, 0], turn[i, 0] = s, t
    return held, shift, turn


def test_margins_derived_by_hand() -> None:
    """Eight phases, limits 20 mm and 10 degrees: (phases held in a row + 1 - worst share of a
    limit) / 9, 0 without a phase; a NaN movement in a phase that ran counts as past its
    limit."""
    turn_limit = np.radians(10.0)
    rows = [([1] * 8, 0.005, 0.0),               # held, moved 5 mm: (8 + 0.75) / 9
            ([1, 1, 0], 0.025, 0.0),             # failed third phase past the limit: 2 / 9
            ([], np.nan, np.nan),                # no grip: 0
            ([0] + [1] * 7, 0.003, turn_limit * 1.5),  # rest failed (turned), the rest
            #                                      held: none in a row, past a limit: 0
            ([1] * 8, 0.0, turn_limit / 4)]      # held, turned 2.5 degrees: (8 + 0.75) / 9
    margin = hold_margin(*records(rows), FULL)
    np.testing.assert_allclose(margin, [8.75 / 9, 2 / 9, 0.0, 0.0, 8.75 / 9], atol=1e-12)
    held, shift, turn = records([([1] * 8, 0.004, 0.0)])
    shift[0, 5] = np.nan  # a movement not recorded in a phase that ran: past the limit
    np.testing.assert_allclose(hold_margin(held, shift, turn, FULL), [8 / 9], atol=1e-12)


def test_the_shake_phase_counts_when_the_protocol_runs_it() -> None:
    """With ``shake`` the protocol has nine phases: a draw that held all nine and never moved
    scores 1; the same record read under the eight-phase protocol scores 1 too (the ninth
    column is not its phase), and a draw that held eight of nine scores (8 + 1) / 10."""
    shaken = HoldProtocol(shake=True)
    held, shift, turn = records([([1] * 9, 0.0, 0.0), ([1] * 8 + [0], 0.0, 0.0)])
    np.testing.assert_allclose(hold_margin(held, shift, turn, shaken), [1.0, 0.9], atol=1e-12)
    np.testing.assert_allclose(hold_margin(held[:1], shift[:1], turn[:1], FULL), [1.0],
                               atol=1e-12)


def test_every_held_draw_scores_above_every_other_in_pybullet() -> None:
    """The Panda's shipped cube grasps under joint noise (3 draws each at sigma 0.0033 and
    0.0133 rad, as the physics benchmark draws them), quick holding test in pybullet:
    both verdicts occur, held draws score at least 8/9 and the others at most 8/9, strictly
    below the lowest held one."""
    from kinegrasp_env.montecarlo.hold_engine import quick_hold_engine
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.world.grasps import shipped_grasps

    rng = np.random.default_rng(3)
    q = np.concatenate([np.repeat(np.asarray(g.q0, float)[None], 6, axis=0)
                        for g in shipped_grasps("cube", robot="panda")])
    sigma = np.tile(np.repeat([0.0033, 0.0133], 3), q.shape[0] // 6)[:, None]
    q[:, :7] += sigma / 0.0133 * JointNoise(0.0133).sample(q.shape[0], 7, rng)
    with quick_hold_engine("panda", "cube") as engine:
        hold = engine.run_hold(q)[1]
    margin = hold.margin(QUICK_PROTOCOL)
    held = hold.outcome == HELD
    assert 0 < held.sum() < held.size, np.bincount(hold.outcome)
    phases = len(QUICK_PROTOCOL.phases)
    assert margin[held].min() >= phases / (phases + 1) >= margin[~held].max()
    assert margin[held].min() > margin[~held].max()
    assert ((margin >= 0) & (margin <= 1)).all()
