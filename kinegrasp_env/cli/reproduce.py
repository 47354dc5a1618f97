"""``reproduce EXPERIMENT``: the paper's protocols on a robot's grasps (Table I, Figs. 7, 9 and
10: :mod:`kinegrasp_env.toolkit.experiments`), every evaluation ``evaluate --robot``'s; the
default robot is the paper's, any catalog robot runs them alike."""

from __future__ import annotations

from kinegrasp_env.cli.common import CLIError, parse_seed, positive_int, reported
from kinegrasp_env.cli.elbow_output import batch_sized, twice_samples
from kinegrasp_env.cli.evaluation import check_robot_engine
from kinegrasp_env.cli.execution_options import executor_from
from kinegrasp_env.cli.figure_grasps import (
    FIG7_VARIANTS,
    FIGURE_GRASPS,
    TABLE1_GRASPS,
    TABLE1_OBJECT,
    imported_without_grasps,
    is_count,
    written,
)
from kinegrasp_env.cli.output_paths import output_folder

#: The experiments that compare configurations of one palm pose (a 7-joint arm's
#: self-motion, a 6-joint arm's IK branches).
VARIANT_EXPERIMENTS = ("fig7", "fig10")


def grasp_sets(args, robot: str, only: str | None = None) -> tuple[dict[str, list], int]:
    """``reproduce EXPERIMENT --robot NAME``'s (grasp sets by object, grasps or variants per
    object): the robot's shipped sets (of ``only``, else ``--object``, else of every object
    it has one for) and a count, or a grasp file of the robot."""
    from kinegrasp_env.cli.figure_grasps import grasp_file
    from kinegrasp_env.world.grasps import (
        NoGraspSetError,
        check_robot,
        shipped_grasps,
        shipped_objects,
    )

    if args.grasps is None or is_count(args.grasps):
        count = positive_int(args.grasps or str(FIGURE_GRASPS), "--grasps")
        objects = (only or args.object,) if only or args.object else shipped_objects(robot)
        if not objects:
            raise CLIError(f"robot {robot!r} has no shipped grasps; give them with --grasps "
                           f"FILE (e.g. from `kinegrasp plan --robot {robot} --object cube "
                           "--out grasps.json`)")
        sets = {}
        for name in objects:
            try:
                sets[name] = shipped_grasps(name, robot)
            except NoGraspSetError as exc:
                if not exc.imported:
                    raise CLIError(str(exc)) from None
                raise imported_without_grasps(name, robot) from None
        return sets, count
    grasps = grasp_file(args.grasps)
    if args.object is not None and args.object != grasps[0].object:
        raise CLIError(f"--object {args.object}: {args.grasps} holds grasps of "
                       f"{grasps[0].object}")
    with reported(ValueError):
        for g in grasps:
            check_robot(g, robot, "--robot")
    return {grasps[0].object: grasps}, FIGURE_GRASPS


def check_count(count: int, sets: dict[str, list], robot: str) -> None:
    """A :class:`CLIError` line where ``--grasps`` asks for more grasps than a shipped set
    of ``sets`` (object -> grasps) holds."""
    name = min(sets, key=lambda n: len(sets[n]))
    if count > len(sets[name]):
        raise CLIError(f"--grasps must be between 1 and {len(sets[name])} ({name} has "
                       f"{len(sets[name])} shipped grasps of robot {robot}), got {count}")


def reproduce(args, samples: int, friction: float = 0.5) -> int:
    """``reproduce EXPERIMENT --robot NAME`` of a robot's grasps
    (:mod:`kinegrasp_env.toolkit.experiments`); Figs. 7 and 10 move a 7-joint arm along its
    self-motion or compare a 6-joint arm's IK branches (another arm is one line)."""
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.robot.description import RobotDescriptionError
    from kinegrasp_env.toolkit.arm_variants import check_variants

    robot = args.robot
    check_robot_engine(args.engine, robot)
    with reported(RobotDescriptionError):
        description = load_robot(robot)
    method = getattr(args, "method", "direct")
    if args.figure in VARIANT_EXPERIMENTS:
        from kinegrasp_env.toolkit.experiments import check_method

        with reported(ValueError):  # before any work
            check_variants(description, args.figure)
            check_method(method)
    if args.figure == "table1":
        return table1_command(args, description, samples, friction)
    sets, count = grasp_sets(args, robot)
    if args.figure == "fig7":  # a count is its configurations; a file's first grasp is moved
        count = count if args.grasps and is_count(args.grasps) else FIG7_VARIANTS
    if args.figure in ("fig7", "fig10") and count < 2:
        raise CLIError(f"--grasps {count}: {args.figure} compares the most and the least "
                       "robust of N configurations, N >= 2")
    if args.figure == "fig9" and args.grasps and is_count(args.grasps):
        check_count(count, sets, robot)
    out = str(output_folder(f"out/{args.figure}" if args.out is None else args.out))
    seed = parse_seed(args.seed)
    if args.figure in ("fig7", "fig9"):
        return figure_command(args, description, sets, count, out, samples, seed, friction)
    from kinegrasp_env.toolkit.experiments import fig10

    with executor_from(args) as executor:  # after every check: Ray takes seconds to start
        with reported(ValueError), batch_sized(twice_samples):
            rows = fig10(description, out, grasp_sets=sets, samples=samples, count=count,
                         seed=seed, engine=args.engine, friction=friction, method=method,
                         executor=executor, progress=True)
    from kinegrasp_env.montecarlo.palm_batch import BATCH_FACTOR
    from kinegrasp_env.toolkit.arm_variants import variant_label

    print_level(rows, f"{samples} draws per variant" if method == "direct" else
                f"one batch of {BATCH_FACTOR * samples} closings per grasp re-weighted to each "
                f"variant (a variant whose effective sample falls short of {samples}: on its "
                "own draws)")
    for r in rows:
        shown = {"direct": "" if method == "direct" else " (its own draws: the batch's "
                 "effective sample was too small)",
                 "reweighted": f" (effective sample {r['samples']})"}[r["estimate"]]
        print(f"{r['object']:<12} id {r['id']:<5} {variant_label(r)} P(FC) "
              f"{r['p_fc']:.3f} ({r['p_fc_lo']:.3f} .. {r['p_fc_hi']:.3f}){shown} Q mean "
              f"{r['q_mean']:.5f} nominal {r['q_nominal']:.5f}")
    if any(r["config"] for r in rows):
        from kinegrasp_env.toolkit.selection import provenance

        own = sum(r["estimate"] == "direct" for r in rows)
        print("robust and fragile variants " + provenance(
            samples, seed, batch=None if method == "direct" else BATCH_FACTOR * samples)
            + (f"; {own} of the candidates on their own {samples} draws (the batch's "
               "effective sample too small)" if method != "direct" and own else ""))
    print_pairs(rows)
    print(written(out, ["fig10.csv", "fig10.png"]))
    return 0


def print_level(rows: list[dict], draws: str) -> None:
    """The line above fig9's and fig10's rows: the noise level, the ``draws`` behind each
    row (words), and what the intervals are."""
    if rows:
        print(f"sigma = {rows[0]['sigma']:g} rad, {draws}; P(FC) with its 95% interval")


def print_pairs(rows: list[dict]) -> None:
    """The robust and fragile rows among ``rows`` (fig7, fig10), per object robust first, on
    their fresh draws, and each object's paired gap."""
    from kinegrasp_env.toolkit.arm_variants import variant_label
    from kinegrasp_env.toolkit.selection import format_gap

    objects = list(dict.fromkeys(r["object"] for r in rows))
    for r in sorted((r for r in rows if r["config"]),
                    key=lambda r: (objects.index(r["object"]), r["config"] != "robust")):
        print(f"{r['object']:<12} {r['config']:<8} id {r['id']:<5} {variant_label(r)} P(FC) "
              f"{r['fresh_p_fc']:.3f} (95% CI {r['fresh_p_fc_lo']:.3f} .. "
              f"{r['fresh_p_fc_hi']:.3f}), chosen at {r['selection_p_fc']:.3f}")
        if r["config"] == "fragile":
            print(f"{r['object']:<12} robust - fragile {format_gap(r)}, paired")


def figure_command(args, description, sets: dict, count: int, out: str, samples: int,
                   seed: int, friction: float) -> int:
    """``reproduce fig7|fig9 --robot NAME`` (:mod:`kinegrasp_env.toolkit.experiments`), on
    the executor ``--processes`` asks for."""
    from kinegrasp_env.toolkit.experiments import fig7, fig9
    from kinegrasp_env.toolkit.selection import provenance

    with executor_from(args) as executor, reported(ValueError):
        if args.figure == "fig9":
            rows = fig9(description, out, grasp_sets=sets, samples=samples, count=count,
                        seed=seed, engine=args.engine, friction=friction, executor=executor,
                        progress=True)
        else:
            rows = fig7(description, out, grasp_sets=sets, samples=samples, variants=count,
                        seed=seed, engine=args.engine, friction=friction, executor=executor,
                        progress=True)
    if args.figure == "fig7":
        print(f"robust and fragile configurations {provenance(samples, seed)}")
        print_pairs(rows)
    else:
        print_level(rows, f"{samples} draws per grasp")
        for r in rows:
            print(f"{r['object']:<12} id {r['id']:<5} P(FC) {r['p_fc']:.3f} ({r['p_fc_lo']:.3f} "
                  f".. {r['p_fc_hi']:.3f}) Q mean {r['q_mean']:.5f} nominal "
                  f"{r['q_nominal']:.5f}")
    pngs = ([f"fig7_{name}.png" for name in dict.fromkeys(r["object"] for r in rows)]
            if args.figure == "fig7" else ["fig9.png"])
    print(written(out, [f"{args.figure}.csv", *pngs]))
    return 0


def table1_command(args, description, samples: int, friction: float) -> int:
    """``reproduce table1 [--robot NAME]``: Table I of the robot's first ``--grasps``
    (default 5, or the whole set where it has fewer) grasps of ``--object`` (default: the
    paper's object, the spray flask, where the robot has shipped grasps of it, else the first
    object it has them of; a count above the set's size is refused), or of every grasp of a
    grasp file (of ``--object`` where it is given)."""
    from kinegrasp_env.toolkit.experiments import table1

    robot = description.name
    if args.grasps is not None and not is_count(args.grasps):
        from kinegrasp_env.cli.figure_grasps import grasp_file
        from kinegrasp_env.world.grasps import check_robot

        grasps = grasp_file(args.grasps)
        name = grasps[0].object
        if args.object is not None and args.object != name:
            raise CLIError(f"--object {args.object}: {args.grasps} holds grasps of {name}")
        with reported(ValueError):
            for g in grasps:
                check_robot(g, robot, "--robot")
    else:
        from kinegrasp_env.world.grasps import shipped_objects

        asked = args.grasps is not None
        args.grasps = args.grasps or TABLE1_GRASPS
        objects = (args.object,) if args.object else shipped_objects(robot)
        if not objects:
            raise CLIError(f"robot {robot!r} has no shipped grasps; give them with --grasps "
                           f"FILE (e.g. from `kinegrasp plan --robot {robot} --object cube "
                           "--out grasps.json`)")
        name = TABLE1_OBJECT if TABLE1_OBJECT in objects else objects[0]
        sets, _ = grasp_sets(args, robot, name)
        count = positive_int(args.grasps, "--grasps")
        if not asked:  # the default count: as many as the set has, up to it
            count = min(count, len(sets[name]))
        check_count(count, {name: sets[name]}, robot)
        grasps = sets[name][:count]
    out = str(output_folder("out/table1" if args.out is None else args.out))
    seed = parse_seed(args.seed)
    with executor_from(args) as executor:  # after every check: Ray takes seconds to start
        rows = table1(description, name, grasps, samples, out, seed=seed,
                      engine=args.engine, friction=friction, executor=executor,
                      progress=True)
    from kinegrasp_env.toolkit.experiments import markdown_table1

    print(markdown_table1(rows, f"{name} (robot {robot})", samples))
    print(written(out, ["table1.csv", "table1.md", "pfc_vs_sigma.png"]))
    return 0
