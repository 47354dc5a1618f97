"""``kinegrasp report`` of any robot's grasps (``--robot NAME``, the grasp file's robot, else
the default one): every chosen grasp evaluated at each sigma by the robot's engine
(:func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`, the draws of
``kinegrasp evaluate`` with the same options), written as one page
(:func:`~kinegrasp_env.toolkit.report.robot.robot_page`).
"""

from __future__ import annotations

import dataclasses
import json
import shlex
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from kinegrasp_env.cli.command_words import friction_words, noise_words, sigma_words
from kinegrasp_env.cli.common import (
    NUM_EDGES,
    CLIError,
    check_spec_noise,
    friction_from,
    friction_setting,
    joint_noise,
    noise_spec_from,
    parse_seed,
    positive_int,
    reported,
)
from kinegrasp_env.cli.evaluation import check_robot_engine, draw_bar
from kinegrasp_env.cli.evaluation_output import evaluation_record
from kinegrasp_env.cli.execution_options import executor_from
from kinegrasp_env.cli.grasp_choice import (
    EVALUATE_OBJECT,
    id_index,
    read_palm_poses,
    solve_candidates,
)
from kinegrasp_env.cli.output_paths import HTML_SUFFIXES, input_files, output_file
from kinegrasp_env.robot.default import DEFAULT_ROBOT


def grasp_file_robot(args) -> str | None:
    """The robot of ``--grasps FILE`` when it is a readable grasp file or a palm-pose file
    that names one, else None (the default robot's path then reports a bad file)."""
    if not getattr(args, "grasps", None) or not Path(args.grasps).is_file():
        return None
    from kinegrasp_env.toolkit.candidates import is_candidate_file
    from kinegrasp_env.world.grasps import load_grasps

    try:
        if is_candidate_file(args.grasps):
            robot = json.loads(Path(args.grasps).read_text()).get("robot")
            return robot if isinstance(robot, str) else None
        grasps = load_grasps(args.grasps)
    except ValueError:
        return None
    return grasps[0].robot if grasps else None


def chosen_grasps(args, robot: str) -> tuple[str, list]:
    """(object, grasps): ``--grasp`` (comma-separated ids or indices; None: ``0``) of
    ``--grasps FILE`` (a palm-pose file's chosen candidates solved for ``robot``, a rejected
    one a line with its reason) or of the robot's shipped set of ``--object``; every grasp
    must be of ``robot`` and of one object."""
    from kinegrasp_env.toolkit.candidates import is_candidate_file
    from kinegrasp_env.world.grasps import (
        NoGraspSetError,
        check_robot,
        load_grasps,
        shipped_grasps,
    )

    candidates = None
    if args.grasps is not None:
        if Path(args.grasps).is_dir():
            raise CLIError(f"--grasps {args.grasps} is a folder, not a grasp file")
        if is_candidate_file(args.grasps):
            candidates = read_palm_poses(args.grasps, args.robot)
            grasps = candidates.candidates
        else:
            with reported(ValueError):  # load_grasps: missing file, bad JSON, bad fields
                grasps = load_grasps(args.grasps)
        source = args.grasps
    else:
        args.object = args.object or EVALUATE_OBJECT
        with reported(NoGraspSetError):
            grasps = shipped_grasps(args.object, robot)
        source = f"the shipped grasps of {args.object} for robot {robot}"
    if not grasps:
        raise CLIError(f"--grasps {args.grasps}: the file holds no grasps")
    grasps = [grasps[i] for i in picked_indices(args.grasp, [g.id for g in grasps], source)]
    if candidates is not None:
        grasps = solve_candidates(candidates, grasps, args.grasps, strict=True)[0]
    objects = sorted({g.object for g in grasps})
    if len(objects) != 1:
        raise CLIError(f"--grasps {args.grasps}: grasps of {', '.join(objects)}; a report "
                       "draws one object's grasps")
    if args.object is not None and args.object != objects[0]:
        raise CLIError(f"--object {args.object}: {source} holds grasps of {objects[0]}")
    with reported(ValueError):
        for g in grasps:
            check_robot(g, robot, "--robot")
    return objects[0], grasps


def picked_indices(text: str | None, ids: list[str], source: str) -> list[int]:
    """The indices ``--grasp`` names in a list of ``ids`` (comma-separated ids, else
    indices; None: ``0``, as ``evaluate``'s default: the id ``0``, else the first); one line
    for an unknown one or one named twice."""
    text = "0" if text is None else text
    picked: list[int] = []

    for word in (t.strip() for t in text.split(",")):
        if not word:
            raise CLIError(f"--grasp {text!r}: an empty id between commas")
        index = id_index(word, ids, source)
        if index in picked:
            raise CLIError(f"--grasp: {text!r} names grasp {ids[index]} twice")
        picked.append(index)
    return picked


@contextmanager
def closing_engines() -> Iterator[None]:
    """Close the engines this process built for its chunks (:func:`~kinegrasp_env.
    montecarlo.chunks.robot_engine`) on exit."""
    from kinegrasp_env.montecarlo.chunks import close_engines

    try:
        yield
    finally:
        close_engines()


def report_command(args, robot: str, sigmas: list[float], samples: int, seed: int,
                   out: Path) -> list[str]:
    """The canonical command line of the page (every setting spelled out)."""
    chosen = ["--grasps", str(args.grasps)] if args.grasps else ["--object", args.object]
    if args.grasp is not None:
        chosen += ["--grasp", args.grasp]
    return ["kinegrasp", "report", "--robot", robot, *chosen,
            *noise_words(args, ",".join(sigma_words(s) for s in sigmas)), "--samples",
            str(samples), "--seed", str(seed), "--engine", args.engine, *friction_words(args),
            "--out", str(out)]


def run_report(args, sigmas: list[float]) -> int:
    """``kinegrasp report``: the page of a robot's grasps (``--grasp``: comma-separated ids
    or indices, default ``0``, as ``evaluate``'s; ``sigmas``: the validated ``--sigma``
    values, or with ``--noise-spec`` one run of its model per grasp)."""
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.sampling.noise_spec import spec_of
    from kinegrasp_env.toolkit.report.arms import first_arms
    from kinegrasp_env.toolkit.report.page import write_page
    from kinegrasp_env.toolkit.report.robot import RobotRun, robot_page
    from kinegrasp_env.world.objects import load_object

    robot = args.robot or grasp_file_robot(args) or DEFAULT_ROBOT
    max_points = positive_int(args.max_points, "--max-points")
    arm_draws = positive_int(args.arm_draws, "--arm-draws", low=0)
    check_robot_engine(args.engine, robot)
    model = noise_spec_from(args)
    friction = friction_from(args, model)
    samples = positive_int(args.samples, "--samples")
    seed = parse_seed(args.seed)
    out = output_file(args.out, "--out", inputs=input_files(args), suffixes=HTML_SUFFIXES)
    with reported(RobotDescriptionError):
        description = load_robot(robot)
    if model is not None:
        check_spec_noise(args, model, description, args.engine)
        sigmas = [model.sigma]
    name, grasps = chosen_grasps(args, robot)
    runs, arms = [], []
    shown = 0 if model is not None else min(arm_draws, samples)
    with executor_from(args) as executor, closing_engines():
        for index, grasp in enumerate(grasps):
            for sigma in sigmas:
                label = (f"{name} grasp {grasp.id}" if model is not None
                         else f"{name} grasp {grasp.id} sigma {sigma_words(sigma)}")
                with draw_bar(samples, label) as progress:
                    runs.append(RobotRun(index, sigma, evaluate_grasp(
                        grasp, n=samples, seed=seed, engine=args.engine, robot=robot,
                        friction=friction, executor=executor, progress=progress,
                        **joint_noise(sigma, args.noise, model))))
            arms.append(first_arms(description, grasp, runs[-len(sigmas)].evaluation,
                                   sigmas[0], seed, args.noise, shown))
    # each grasp's nominal Q as this engine computes it at this friction
    nominal = {r.grasp: r.evaluation.q_nominal for r in runs}
    grasps = [dataclasses.replace(g, q_nominal=nominal[i]) for i, g in enumerate(grasps)]
    command = [*report_command(args, robot, sigmas, samples, seed, out),
               "--max-points", str(max_points),  # no arms are drawn under a noise spec
               *(["--arm-draws", str(arm_draws)] if model is None else [])]
    settings = {"robot": robot, "object": name, "grasps": ", ".join(g.id for g in grasps),
                "grasp source": args.grasps or f"shipped set of {name} for {robot}",
                **({"noise spec": args.noise_spec} if model is not None else
                   {"sigma [rad]": ", ".join(f"{s:g}" for s in sigmas), "noise": args.noise,
                    "noisy joints": ", ".join(description.arm_joints)}),
                "draws per grasp and sigma": samples, "seed (every grasp and sigma)": seed,
                "engine": args.engine, "contact model": description.contact_model,
                "friction mu": friction_setting(model, friction),
                "friction cone edges": NUM_EDGES, "contact points drawn at most": max_points,
                "noisy arms drawn": (min(arm_draws, samples) if model is None else
                                     "none under a noise spec")}
    text = robot_page(description, load_object(name), grasps, runs,
                      command=shlex.join(command), settings=settings, friction=friction,
                      num_edges=NUM_EDGES, max_points=max_points, arms=arms,
                      noise_spec=None if model is None else spec_of(model))
    write_page(out, text)
    size = len(text.encode())
    if args.json:
        print(json.dumps({"report": str(out), "bytes": size, "robot": robot, "object": name,
                          "runs": [{"grasp": grasps[r.grasp].id, **evaluation_record(
                              r.evaluation, sigma=r.sigma, noise=args.noise, model=model,
                              spec_file=args.noise_spec, samples=samples, seed=seed,
                              engine=args.engine)} for r in runs]}))
        return 0
    for r in runs:
        lo, hi = r.evaluation.ci
        label = (f"noise spec {args.noise_spec}" if model is not None
                 else f"sigma = {r.sigma:g} ({args.noise})")
        print(f"{name} grasp {grasps[r.grasp].id} of robot {robot}, {label}, {samples} "
              f"draws: P(FC) = {r.evaluation.p_fc:.4f} (95% CI {lo:.4f} .. {hi:.4f})")
    print(f"report written to {out} ({size / 1e6:.1f} MB)")
    return 0
