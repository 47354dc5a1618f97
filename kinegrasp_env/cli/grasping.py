"""Grasp commands: ``objects`` (the catalog), ``evaluate`` (Monte Carlo P(FC) of one grasp) and
``reproduce`` (the paper's tables and figures).
"""

from __future__ import annotations

import json

from kinegrasp_env.cli.common import (
    CLIError,
    add_execution_args,
    add_noise_args,
    engine_name,
    executor_from,
    noise_from,
    parse_index,
    parse_seed,
    positive_int,
)


def cmd_objects(args) -> int:
    from kinegrasp_env.world.objects import catalog

    rows = catalog()
    if args.json:
        print(json.dumps(rows))
        return 0
    print(f"{'name':<12} {'size x, y, z [m]':<26} {'r_max [m]':>9} {'parts':>5}")
    for r in rows:
        size = ", ".join(f"{v:.3f}" for v in r["size"])
        print(f"{r['name']:<12} {size:<26} {r['r_max']:>9.4f} {r['parts']:>5}")
    return 0


def cmd_evaluate(args) -> int:
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.world.grasps import grasp_by_index

    noise, sigma, samples, seed = noise_from(args)
    index = parse_index(args.grasp)
    grasp = grasp_by_index(args.object, index)
    engine = engine_name(args.engine)
    with executor_from(args) as executor:
        stats = evaluate_grasp(grasp, noise, samples, seed, engine=engine,
                               return_draws=bool(args.plot), progress=True, executor=executor)
    if args.plot:
        from kinegrasp_env.toolkit.plots import plot_contacts
        from kinegrasp_env.world.objects import load_object

        plot_contacts(load_object(args.object).mesh, stats.draws, args.plot,
                      title=f"{args.object} grasp {index}, sigma = {sigma:g}: "
                            f"P(FC) = {stats.p_fc:.3f}")
    if args.json:
        print(json.dumps(stats.to_json()))
    else:
        lo, hi = stats.p_fc_ci
        print(f"{args.object} grasp {index}, sigma = {sigma:g} ({args.noise}), {samples} draws")
        print(f"  P(FC)   = {stats.p_fc:.4f}  (95% CI {lo:.4f} .. {hi:.4f})")
        print(f"  Q: nominal {stats.q_nominal:.5f}, mean {stats.q_mean:.5f}, std "
              f"{stats.q_std:.5f}, skewness {stats.q_skew:.3f}, error {stats.error:.5f}")
        print("  outcomes: " + ", ".join(f"{k} {v}" for k, v in stats.outcomes.items()))
        if args.plot:
            print(f"  plot written to {args.plot}")
    return 0


def cmd_reproduce(args) -> int:
    from kinegrasp_env.toolkit import experiments
    from kinegrasp_env.toolkit.experiments import markdown_table1, table1

    samples = positive_int(args.samples, "--samples")
    engine = engine_name(args.engine)
    if args.figure not in ("table1", "fig7", "fig9", "fig10"):
        raise CLIError(f"unknown experiment {args.figure!r}; available: table1, fig7, fig9, "
                       "fig10")
    out = args.out or f"out/{args.figure}"
    seed = parse_seed(args.seed)
    grasps = positive_int(args.grasps, "--grasps")
    with executor_from(args) as executor:
        if args.figure == "fig7":
            rows = experiments.fig7(out, samples=samples, seed=seed, engine=engine,
                                    executor=executor)
            for r in rows:
                print(f"{r['object']:<12} {r['config']:<8} id {r['id']:<5} "
                      f"P(FC) {r['p_fc']:.3f}")
            print(f"written: {out}/fig7.csv and fig7_<object>.png")
        elif args.figure in ("fig9", "fig10"):
            rows = experiments.fig9_10(args.figure, out, samples=samples, seed=seed,
                                       engine=engine, executor=executor)
            for r in rows:
                print(f"{r['object']:<12} id {r['id']:<5} P(FC) {r['p_fc']:.3f} Q mean "
                      f"{r['q_mean']:.5f} nominal {r['q_nominal']:.5f}")
            print(f"written: {out}/{args.figure}.csv and {args.figure}.png")
        else:
            rows = table1(args.object, samples, out, grasps=grasps, seed=seed, progress=True,
                          engine=engine, executor=executor)
            print(markdown_table1(rows, args.object, samples))
            print(f"written: {out}/table1.csv, table1.md, pfc_vs_sigma.png")
    return 0


def add_commands(sub) -> None:
    """Register ``objects``, ``evaluate`` and ``reproduce``."""
    p = sub.add_parser("objects", help="list the object catalog")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_objects)

    p = sub.add_parser("evaluate", help="Monte Carlo P(FC) and quality of a shipped grasp")
    p.add_argument("--object", default="spray_flask")
    p.add_argument("--grasp", default="0", help="index in the object's shipped grasp set")
    add_noise_args(p, 0.0133)
    add_execution_args(p, 1)
    p.add_argument("--engine", default="pybullet", help="pybullet (reference) or fast")
    p.add_argument("--plot", help="write a PNG of the draws' contacts on the object")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("reproduce", help="reproduce a table or figure of the paper")
    p.add_argument("figure", help="table1, fig7, fig9 or fig10")
    p.add_argument("--object", default="spray_flask")
    p.add_argument("--samples", default="10000")
    p.add_argument("--grasps", default="5")
    p.add_argument("--seed", default="0")
    add_execution_args(p, 2)
    p.add_argument("--engine", default="pybullet", help="pybullet (reference) or fast")
    p.add_argument("--out", help="output folder (default out/<figure>)")
    p.set_defaults(func=cmd_reproduce)
