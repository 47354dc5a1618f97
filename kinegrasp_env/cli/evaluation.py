"""``kinegrasp evaluate`` of any robot's grasp, and what ``rank``, ``report`` and
``reproduce`` share with it (the engine and holding-test option checks, the quick holding
test's count, a grasp moved to an elbow angle): the robot's engines
(:mod:`kinegrasp_env.montecarlo.evaluate`), their draws in chunks on the command's
executor (:mod:`kinegrasp_env.montecarlo.chunks`), the page of ``--report``
(:func:`~kinegrasp_env.toolkit.report.robot.robot_page`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from kinegrasp_env.cli.common import (
    CLIError,
    check_spec_noise,
    friction_per_draw,
    friction_setting,
    joint_noise,
    reported,
)
from kinegrasp_env.cli.evaluation_output import (
    Evaluation,
    evaluation_record,
    hold_lines,
    print_evaluation,
)
from kinegrasp_env.cli.execution_options import executor_from


@contextmanager
def draw_bar(total: int, label: str) -> Iterator[Callable[[int, int], None]]:
    """A ``progress(done, total)`` callback that moves a bar of ``total`` draws on stderr
    (:func:`~kinegrasp_env.progress_bar.progress_bar`: plain lines off a terminal), closed on
    exit."""
    from kinegrasp_env.progress_bar import progress_bar

    bar = progress_bar(total=total, desc=label, unit="draw")
    try:
        yield lambda done, _total: bar.update(done - bar.n)
    finally:
        bar.close()


def check_hold_simulator(args, runs: bool, asked_by: str) -> None:
    """CLIError (one line) where ``--hold-simulator`` names a simulator that is not
    installed, or names one for a run without the holding test (``runs``: whether it runs;
    ``asked_by``: the option that runs it)."""
    from kinegrasp_env.physics.simulators import check_simulator

    if not runs:
        if args.hold_simulator != "pybullet":
            raise CLIError(f"--hold-simulator {args.hold_simulator} is the holding test's "
                           f"simulator; it runs with {asked_by}")
        return
    with reported(ValueError):
        check_simulator(args.hold_simulator)


def holding_test(grasp, robot: str, sigma, samples: int, seed: int, noise: str,
                 friction: float = 0.5, simulator: str = "pybullet",
                 model=None) -> tuple[int, float, str]:
    """How many of ``evaluate``'s draws of a grasp the quick holding test in ``simulator``
    holds, the mean of their margins (:func:`~kinegrasp_env.physics.protocol.hold_margin`),
    and the name of the simulator that ran it; ``model``: the ``--noise-spec`` model's draws
    (its joints and hand) instead of the joint noise."""
    from kinegrasp_env.montecarlo.evaluate import evaluation_rows
    from kinegrasp_env.montecarlo.hold_engine import quick_hold_engine
    from kinegrasp_env.physics.protocol import HELD

    with quick_hold_engine(robot, grasp.object, friction, simulator) as engine:
        q = evaluation_rows(grasp, engine, sigma=sigma, n=samples, seed=seed, noise=noise,
                            noise_model=model)[0]
        hold = engine.run_hold(q)[1]
        return (int((hold.outcome == HELD).sum()), float(hold.margin(engine.protocol).mean()),
                engine.simulator.name)


def check_robot_engine(engine: str, robot: str) -> None:
    """CLIError unless ``engine`` is one of a description robot's engines."""
    from kinegrasp_env.montecarlo.evaluate import ENGINES

    if engine not in ENGINES:
        raise CLIError(f"--engine {engine}: robot {robot!r} is evaluated by the "
                       f"{', '.join(ENGINES[:-1])} or {ENGINES[-1]} engine only")


def run_evaluate(args, grasp, robot: str, sigma: float, samples: int,
                 seed: int, friction: float, noise=None) -> int:
    """``kinegrasp evaluate`` of any robot's grasp: joint noise on its arm joints
    (``--sigma``/``--noise``), or ``noise``, the ``--noise-spec`` model (joints, palm,
    object, friction: :mod:`~kinegrasp_env.montecarlo.noise_rows`); friction mu
    ``friction``."""
    from kinegrasp_env.montecarlo.evaluate import check_robot, evaluate_grasp
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.sampling.noise_model import NoiseModel
    from kinegrasp_env.sampling.stats import wilson_interval

    check_robot_engine(args.engine, robot)
    model = noise if isinstance(noise, NoiseModel) else None
    if model is not None:
        check_spec_noise(args, model, robot, args.engine, bool(args.static_hold))
    if args.hold_test:
        from kinegrasp_env.montecarlo.draw_holds import check_hold_noise

        with reported(ValueError):
            check_hold_noise(model, robot, "--hold-test (the holding test)")
    check_hold_simulator(args, args.hold_test, "--hold-test")
    label = (f"noise spec {args.noise_spec}" if model is not None
             else f"sigma = {sigma:g} rad ({args.noise})")
    what = f"{grasp.object} grasp {grasp.id}"
    with reported(ValueError):
        check_robot(grasp, robot, "--robot")
        if args.elbow is not None:
            grasp = robot_grasp_at_elbow(grasp, robot, args.elbow)
            what += f" at elbow angle {grasp.meta['elbow_angle']:.3f} rad"
    with executor_from(args) as executor, reported(ValueError), \
            draw_bar(samples, f"{grasp.object} grasp {grasp.id}") as progress:
        stats = evaluate_grasp(grasp, n=samples, seed=seed, robot=robot, engine=args.engine,
                               **joint_noise(sigma, args.noise, model),
                               static_hold=args.static_hold, friction=friction,
                               executor=executor, progress=progress,
                               keep_draws=bool(args.plot or args.report))  # they draw contacts
    hold = ({"p_hold_static": stats.p_hold_static, "p_hold_static_ci": list(stats.hold_ci),
             "mass_kg": stats.mass} if args.static_hold else {})
    if math.isfinite(stats.push_median):
        hold["jaw_push_mm"] = {"median": 1e3 * stats.push_median, "p95": 1e3 * stats.push_p95}
    if args.hold_test:
        held, margin, simulator = holding_test(grasp, robot, sigma, samples, seed, args.noise,
                                               friction, args.hold_simulator, model)
        hold.update({"p_hold": held / samples, "p_hold_ci": list(wilson_interval(held, samples)),
                     "hold_margin": margin, "hold_simulator": simulator})
    if args.json:
        print(json.dumps({"robot": robot, "object": grasp.object, "grasp": grasp.id,
                          **evaluation_record(
                              stats, sigma=sigma, noise=args.noise, model=model,
                              spec_file=args.noise_spec, samples=samples, seed=seed,
                              engine=args.engine,
                              friction=None if friction_per_draw(model) else friction),
                          **hold}))
    else:
        extra = hold_lines(hold)
        if math.isfinite(stats.push_median):
            extra.append(f"  coupled jaws: one jaw touches first and would push the object "
                         f"{1e3 * stats.push_median:.1f} mm (median; 95th percentile "
                         f"{1e3 * stats.push_p95:.1f} mm) before the other touches; the "
                         "closing scores the object where it stands")
        print_evaluation(Evaluation(
            f"{what} of robot {robot}", label, samples,
            None if friction_per_draw(model) else friction,
            load_robot(robot).contact_model, stats.p_fc, stats.ci, stats.q_nominal,
            stats.q_mean, stats.q_std, stats.q_skew, stats.counts), extra)
    # after the results: a failing figure or page is a warning or an error, the results stand
    if args.plot:
        from kinegrasp_env.toolkit.plots import plot_contacts, safe_figure
        from kinegrasp_env.world.objects import load_object

        wrote = safe_figure(lambda: plot_contacts(
            load_object(grasp.object).mesh, stats.draws, args.plot,
            title=f"{what} of {robot}, {label}: "
                  f"P(FC) = {stats.p_fc:.3f}"), args.plot)
        if wrote is not None and not args.json:
            print(f"  plot written to {args.plot}")
    if args.report:
        write_evaluation_page(args, grasp, robot, sigma, stats, friction, label, model)
    return 0


def write_evaluation_page(args, grasp, robot: str, sigma, stats, friction: float,
                          label: str, model=None) -> None:
    """``evaluate --report FILE``: ``report``'s page of this one grasp and run
    (:func:`~kinegrasp_env.toolkit.report.robot.robot_page`): its table, its 3-D scene with
    the draws' contact points and the arm at its first draws (joint noise), Q's histogram
    and the outcome counts; ``model``: the ``--noise-spec`` model (its sources listed, no
    arms drawn)."""
    import dataclasses
    import shlex
    import sys

    from kinegrasp_env.cli.command_words import friction_words, noise_words, sigma_words
    from kinegrasp_env.cli.common import NUM_EDGES
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.sampling.noise_spec import spec_of
    from kinegrasp_env.toolkit.report.arms import first_arms
    from kinegrasp_env.toolkit.report.page import ARM_DRAWS, write_page
    from kinegrasp_env.toolkit.report.robot import RobotRun, robot_page
    from kinegrasp_env.toolkit.report.scene import MAX_POINTS
    from kinegrasp_env.world.objects import load_object

    description = load_robot(robot)
    chosen = (["--grasps", str(args.grasps), "--grasp", str(args.grasp)] if args.grasps
              else ["--object", grasp.object, "--grasp", str(args.grasp)])
    if args.elbow is not None:
        chosen += ["--elbow", str(args.elbow)]
    command = ["kinegrasp", "evaluate", "--robot", robot, *chosen,
               *noise_words(args, sigma_words(sigma)), "--samples", str(stats.n), "--seed",
               str(args.seed), "--engine", args.engine, *friction_words(args), "--report",
               str(args.report)]
    shown = dataclasses.replace(grasp, q_nominal=stats.q_nominal)
    arms = first_arms(description, grasp, stats, sigma, int(args.seed), args.noise,
                      0 if model is not None else min(ARM_DRAWS, stats.n))
    settings = {"robot": robot, "object": grasp.object, "grasp": grasp.id,
                "grasp source": args.grasps or f"shipped set of {grasp.object} for {robot}",
                "noise": label,
                "draws": stats.n, "seed": args.seed, "engine": args.engine,
                "contact model": description.contact_model,
                "friction mu": friction_setting(model, friction),
                "friction cone edges": NUM_EDGES,
                "contact points drawn at most": MAX_POINTS,
                "noisy arms drawn": len(arms.q) if model is None else
                "none under a noise spec"}
    text = robot_page(description, load_object(grasp.object), [shown],
                      [RobotRun(0, sigma, stats)], command=shlex.join(command),
                      settings=settings, friction=friction, num_edges=NUM_EDGES,
                      max_points=MAX_POINTS, arms=[arms],
                      noise_spec=None if model is None else spec_of(model))
    write_page(args.report, text)
    print(f"report written to {args.report} ({len(text.encode()) / 1e6:.1f} MB)",
          file=sys.stderr if args.json else sys.stdout)


def robot_grasp_at_elbow(grasp, robot: str, text: str):
    """``evaluate --elbow PSI`` of any robot: the grasp with its arm moved along a 7-joint
    arm's self-motion to elbow angle PSI (radians), or onto the IK branch of a 6-joint arm
    whose coordinate bin holds PSI (:class:`~kinegrasp_env.robot.branch_motion.BranchMotion`,
    as the envs have it); the palm pose kept. A bad or unreachable angle (the line names the
    reachable range: :func:`reachable_range`), or a 7-joint arm without ``arm_angle_links``,
    is a ValueError line."""
    import dataclasses

    import numpy as np

    from kinegrasp_env.cli.common import finite_float
    from kinegrasp_env.robot.branch_motion import elbow_motion
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit.elbow import wrap_angle

    psi = finite_float(text, "--elbow")
    if not -math.pi <= psi <= math.pi:
        raise ValueError(f"--elbow {text}: an elbow angle is in radians, within -pi .. pi")
    motion = elbow_motion(load_robot(robot))
    q0 = np.asarray(grasp.q0, dtype=float)
    moved, ok = motion.set_elbow_angle(q0, psi)
    if not ok:
        psi0 = float(motion.elbow_angle(q0[None])[0])
        lo, hi = reachable_range(grasp)
        raise ValueError(f"elbow angle {psi:g} rad is out of reach for grasp {grasp.id} of "
                         f"{grasp.object} (nominal {psi0:.3f}; reachable {lo:.3f} .. "
                         f"{hi:.3f} rad)")
    return dataclasses.replace(grasp, q0=moved, id=f"{grasp.id}@{wrap_angle(psi):.3f}",
                               meta={**grasp.meta, "elbow_angle": psi})


def reachable_range(grasp) -> tuple[float, float]:
    """(lowest, highest) elbow angle (radians) of the grasp's reachable self-motion: the
    angles ``kinegrasp elbow`` walks (:func:`~kinegrasp_env.toolkit.elbow_search.
    robot_reachable_configurations`: within the joint limits, the arm clear of the object)."""
    from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
    from kinegrasp_env.toolkit.elbow_search import robot_reachable_configurations

    with RobotReferenceEngine(grasp.robot, grasp.object) as engine:
        reach = robot_reachable_configurations(grasp, engine)
    return reach[0][0], reach[-1][0]
