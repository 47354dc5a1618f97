"""``kinegrasp validate``: does P(FC) predict holding? The kinematic closing and the holding
test (closing on the pinned object, grip, release, six gravity directions, lift, optional
shake; :mod:`kinegrasp_env.physics.protocol`) on the same draws, per draw and per grasp
(:mod:`kinegrasp_env.toolkit.validation`).

``--json`` prints the summary (keys: :mod:`kinegrasp_env.toolkit.validation_report`): per
grasp ``grip_shift_mm`` and ``draw_outcomes`` (per draw), ``outcomes`` and ``phases`` (each
phase's ``run`` and ``held`` counts), P(FC) of both closings and P(hold)."""

from __future__ import annotations

import math
from pathlib import Path

from kinegrasp_env.cli.common import (
    CLIError,
    add_friction_arg,
    finite_float,
    friction_from,
    grasp_index_help,
    parse_seed,
    plural,
    positive_int,
    print_json,
    reported,
    shipped_grasp,
    sigma_value,
)
from kinegrasp_env.cli.execution_options import processes_from
from kinegrasp_env.cli.output_paths import output_folder
from kinegrasp_env.robot.default import DEFAULT_ROBOT


def add_commands(sub) -> None:
    """Register ``validate``."""
    from kinegrasp_env.physics.simulators import SIMULATORS

    p = sub.add_parser("validate", help="holding test: does P(FC) predict that the hand holds "
                       "the object? (grip shift, six gravity directions, lift; same draws as "
                       "the kinematic closing)")
    p.add_argument("--object", default="all", help="a built-in object, or `all` for the four "
                   "(with --grasps: the file's objects; an object named there must be the "
                   "file's)")
    p.add_argument("--grasp", nargs="+", help=grasp_index_help() + " (several allowed; default "
                   "all of the object's shipped grasps; with --grasps: ids or indices in the "
                   "file)")
    p.add_argument("--grasps", help="a grasp file (e.g. `kinegrasp plan`'s output) instead of "
                   "the shipped sets")
    p.add_argument("--sigma", default="0.0133", help="joint noise on the robot's arm joints, "
                   "radians")
    p.add_argument("--samples", default="100", help="draws per grasp")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    p.add_argument("--processes", default="1", help="worker processes (more than this "
                   "machine's cores is capped to them, with a warning)")
    p.add_argument("--kinematic-engine", default="fast", choices=("fast", "pybullet"),
                   help="engine of the kinematic outcome (fast: same outcomes as pybullet "
                   "draw by draw, much faster)")
    p.add_argument("--simulator", default="pybullet", choices=tuple(SIMULATORS),
                   help="the simulator that runs the holding test")
    p.add_argument("--torque-scale", default="1", help="multiplies the torque (or force) "
                   "limits of the hand's joints: the URDF's efforts or the description's "
                   "(the output names those used)")
    p.add_argument("--shake", action="store_true", help="add the shake phase after the lift "
                   "(1.5 s at 2 Hz: 3 cm along (0, 1, 1)/sqrt 2 and 20 degrees about x)")
    p.add_argument("--robot", help="catalog robot (default: the grasp file's, else "
                   "kuka_sdh); the robot's shipped grasps (assets/grasps/NAME/) or "
                   "--grasps of it are held by its own hand (its motors at the URDF's "
                   "effort limits or the description's efforts)")
    add_friction_arg(p)
    p.add_argument("--out", required=True, help="output folder (results are cached there: "
                   "a rerun with the same settings resumes)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=cmd_validate)


def file_grasps(path: str, indices: list[str] | None, robot: str | None = None,
                friction: float = 0.5) -> list[tuple[int, object]]:
    """``(index, grasp)`` of a grasp file: all, or the given indices (ids, else indices); of
    a palm-pose file: its candidates (all or those), solved for the file's robot or
    ``robot`` at ``friction`` (:func:`candidate_grasps`)."""
    from kinegrasp_env.toolkit.candidates import is_candidate_file
    from kinegrasp_env.world.grasps import load_grasps

    if Path(path).is_file() and is_candidate_file(path):
        return candidate_grasps(path, indices, robot, friction)

    with reported(ValueError):
        grasps = load_grasps(path)
    if not grasps:
        raise CLIError(f"--grasps {path}: the file has no grasps")
    if indices is None:
        return list(enumerate(grasps))
    from kinegrasp_env.cli.grasp_choice import id_index

    ids = [g.id for g in grasps]
    return [(index, grasps[index]) for index in (id_index(text, ids, path) for text in indices)]


def candidate_grasps(path: str, indices: list[str] | None, robot: str | None,
                     friction: float = 0.5) -> list[tuple[int, object]]:
    """``(index, grasp)`` of a palm-pose file's candidates (all, or the given ids, else
    indices), each solved to a grasp (IK, clearance, closing) for the file's robot or
    ``robot``; a rejected one is a line on stderr and left out (all rejected: one line)."""
    from kinegrasp_env.cli.grasp_choice import id_index, read_palm_poses, solve_candidates

    read = read_palm_poses(path, robot)
    ids = [c.id for c in read.candidates]
    chosen = (range(len(ids)) if indices is None
              else [id_index(text, ids, path) for text in indices])
    grasps, _ = solve_candidates(read, [read.candidates[i] for i in chosen], path,
                                 friction=friction)
    if not grasps:
        raise CLIError(f"--grasps {path}: none of the chosen candidates is reachable, clear "
                       "and closing; nothing to validate")
    return [(ids.index(g.id), g) for g in grasps]


def shipped_choice(args, robot: str) -> list[tuple[int, object]]:
    """A robot's shipped grasps (``--object``: one of its shipped objects, or ``all``; with
    ``--grasp``, those indices of the object's set), as ``(index, grasp)``."""
    from kinegrasp_env.world.grasps import NoGraspSetError, shipped_grasps, shipped_objects
    from kinegrasp_env.world.objects import OBJECT_NAMES, is_object

    objects = shipped_objects(robot)
    if args.object == "all":
        if args.grasp is not None:
            raise CLIError("--grasp needs one --object, not `all`")
        names = objects
    elif args.object in objects:
        names = (args.object,)
    elif not is_object(args.object):
        raise CLIError(f"--object: unknown object {args.object!r}; choose from "
                       f"{', '.join(objects)}, all (or an imported object with --grasps)")
    elif args.object not in OBJECT_NAMES:  # a placed copy has its base's grasps; an
        with reported(NoGraspSetError):  # imported object none: how to make them
            shipped_grasps(args.object, robot)
        names = (args.object,)
    else:
        raise CLIError(f"--object: robot {robot!r} has no shipped grasps of {args.object!r} "
                       f"(shipped: {', '.join(objects) or 'none'}); give --grasps (e.g. "
                       "`kinegrasp plan`'s output)")
    if args.grasp is not None:
        return [shipped_grasp(names[0], text, robot) for text in args.grasp]
    return [pair for name in names for pair in enumerate(shipped_grasps(name, robot))]


def selected_robot(args) -> str:
    """The robot: ``--robot``, else the grasp file's, else the default; a grasp file of
    another robot than ``--robot`` refused (checked before any grasp is read in full)."""
    if args.robot is not None:
        from kinegrasp_env.robot.catalog import robot_names

        if args.robot not in robot_names():
            raise CLIError(f"--robot: unknown robot {args.robot!r}; choose from "
                           f"{', '.join(robot_names())}")
    if args.grasps is None:
        return args.robot or DEFAULT_ROBOT
    from kinegrasp_env.toolkit.candidates import is_candidate_file, read_candidates

    if Path(args.grasps).is_file() and is_candidate_file(args.grasps):
        with reported(ValueError):  # the file's robot, or --robot (checked against it)
            return read_candidates(args.grasps, args.robot).robot
    robots = {g.robot for _, g in file_grasps(args.grasps, None)}
    found = robots.pop() if len(robots) == 1 else None
    if found is None:
        raise CLIError(f"--grasps {args.grasps}: the file's grasps are of several robots")
    if args.robot is not None and found != args.robot:
        raise CLIError(f"--grasps {args.grasps}: grasps of robot {found!r}, not of "
                       f"{args.robot!r}")
    return found


def selected_grasps(args, robot: str, friction: float = 0.5) -> list[tuple[int, object]]:
    """The grasps to validate, as ``(index, grasp)``; duplicates refused, and a grasp file
    whose grasps are not of ``--object`` (when one is named, not ``all``)."""
    chosen = (file_grasps(args.grasps, args.grasp, args.robot, friction)
              if args.grasps is not None
              else shipped_choice(args, robot))
    if args.grasps is not None and args.object != "all":
        others = sorted({g.object for _, g in chosen} - {args.object})
        if others:
            raise CLIError(f"--object {args.object}: {args.grasps} holds grasps of "
                           f"{', '.join(others)}")
    seen = set()
    for index, grasp in chosen:
        if (grasp.object, index) in seen:
            raise CLIError(f"--grasp: {grasp.object} grasp {index} is given twice")
        seen.add((grasp.object, index))
    return chosen


def settings_from(args) -> dict:
    """The ``ValidationSettings`` fields, checked (without importing the physics)."""
    sigma = sigma_value(args.sigma)
    from kinegrasp_env.physics.simulators import check_simulator

    scale = finite_float(args.torque_scale, "--torque-scale")
    if scale <= 0:
        raise CLIError(f"--torque-scale must be > 0, got {args.torque_scale}")
    with reported(ValueError):
        check_simulator(args.simulator)
    return {"sigma": sigma, "samples": positive_int(args.samples, "--samples"),
            "seed": parse_seed(args.seed), "kinematic": args.kinematic_engine,
            "simulator": args.simulator, "torque_scale": scale, "shake": args.shake,
            "friction": friction_from(args, simulated=True)}


def cmd_validate(args) -> int:
    robot = selected_robot(args)
    fields = settings_from(args)
    processes = processes_from(args.processes)
    grasps = selected_grasps(args, robot, fields["friction"])
    check_robot_run(robot, fields)
    out = output_folder(args.out)
    from kinegrasp_env.toolkit.validation import ValidationSettings
    from kinegrasp_env.toolkit.validation_report import write_results

    settings = ValidationSettings(**fields)
    summary, results = validate_robot(robot, grasps, settings, out, processes)
    paths = write_results(out, results, summary, protocol=settings.protocol)
    if args.json:
        print_json({**summary, "files": {k: str(v) for k, v in paths.items()}})
    else:
        print_summary(summary, paths)
    return 0


def check_robot_run(robot: str, fields: dict) -> None:
    """CLIError (one line) for what a robot's run cannot honour (before any output is
    written)."""
    from kinegrasp_env.toolkit.validation import ValidationSettings
    from kinegrasp_env.toolkit.validation_draws import check_settings

    with reported(ValueError):
        check_settings(robot, ValidationSettings(**fields))


def validate_robot(robot: str, grasps, settings, out, processes: int):
    """(summary, results) of a robot's grasps (on ``processes`` workers)."""
    from kinegrasp_env.toolkit.validation import run_validation
    from kinegrasp_env.toolkit.validation_draws import motors_summary
    from kinegrasp_env.toolkit.validation_report import summarize

    motors = motors_summary(robot, settings.torque_scale)
    results = run_validation(grasps, settings, out, processes, progress=True)
    return summarize(results, settings, bootstrap_seed=settings.seed,
                     robot={"name": robot, "motors": motors}), results


def limits_text(summary: dict) -> str:
    """The motor limits of a run, in words."""
    p = summary["protocol"]
    scale = "" if p["torque_scale"] == 1 else f" x {p['torque_scale']:g}"
    return "motors " + ", ".join(f"{m['joint']} {m['effort']:g} {m['unit']} "
                                 f"({m['source']}{scale})" for m in p["motors"])


def print_summary(summary: dict, paths: dict) -> None:
    from kinegrasp_env.toolkit.validation_stats import MIN_INTERVAL_GRASPS

    s, p = summary["settings"], summary["protocol"]
    robot = f"robot {s['robot']}, " if "robot" in s else ""
    print(f"validate: {robot}{len(summary['grasps'])} grasps, sigma {s['sigma']:g} rad, "
          f"mu {s['friction']:g}, {s['samples']} draws each, seed {s['seed']} (kinematic "
          f"engine: {s['kinematic']}, simulator: {s['simulator']})")
    shake = (f"shake {p['shake_amplitude'] * 100:g} cm / {math.degrees(p['shake_angle']):g} deg "
             f"at {p['shake_frequency']:g} Hz" if p["shake"] else "no shake")
    print(f"holding test: held = within {p['max_shift'] * 100:g} cm and "
          f"{math.degrees(p['max_turn']):g} deg of the post-grip pose (palm frame); gravity "
          f"{p['gravity_time']:g} s per direction, lift {p['lift_height'] * 100:g} cm, {shake}; "
          f"{limits_text(summary)}")
    print(f"{'grasp':<18} {'P(FC) kin':>10} {'P(FC) phys':>11} {'P(hold)':>8}  95% CI hold"
          f"  {'grip shift mm (median)':>22}  outcomes")
    for g in summary["grasps"]:
        lo, hi = g["p_hold_ci"]
        shifts = [v for v in g["grip_shift_mm"] if v is not None]
        shift = f"{sorted(shifts)[len(shifts) // 2]:.1f}" if shifts else "-"
        counts = ", ".join(f"{k} {v}" for k, v in g["outcomes"].items() if v)
        print(f"{g['object'] + ' ' + str(g['index']):<18} {g['p_fc_kinematic']:>10.3f} "
              f"{g['p_fc_physics']:>11.3f} {g['p_hold']:>8.3f}  [{lo:.2f}, {hi:.2f}]"
              f"  {shift:>22}  {counts}")
    print("phases held / run: " + ", ".join(f"{name} {c['held']}/{c['run']}"
                                            for name, c in summary["phases"].items()))
    for name, m in summary["confusion"].items():
        print(f"{name} (rows predicted F/T, columns actual F/T): {m}")
    for name, c in summary["spearman"].items():
        rho = "n/a" if c["rho"] is None else f"{c['rho']:.3f}"
        if c["n"] < MIN_INTERVAL_GRASPS:
            interval = f"no interval from {plural(c['n'], 'grasp')}: it needs " \
                       f"{MIN_INTERVAL_GRASPS}"
        else:
            lo, hi = ("n/a" if v is None else f"{v:.3f}" for v in c["ci"])
            interval = f"bootstrap {c['confidence']:.0%} [{lo}, {hi}], {c['n']} grasps"
        print(f"Spearman {name}: {rho} ({interval})")
    print("wrote " + ", ".join(str(p) for p in paths.values()))
