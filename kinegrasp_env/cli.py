"""The ``kinegrasp`` command.

Every sub-command validates its input up front and reports a bad value in one line on
stderr with exit status 2 (no traceback); results go to stdout (``--json`` for machines),
progress bars to stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Sequence

import numpy as np


class CLIError(ValueError):
    """A user error: printed as one line, exit status 2."""


# ----------------------------------------------------------------------------- parsing helpers
def finite_float(text: str, name: str = "value") -> float:
    try:
        value = float(text)
    except ValueError:
        raise CLIError(f"{name}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise CLIError(f"{name}: {text!r} is not a finite number")
    return value


def float_list(text: str, name: str) -> list[float]:
    parts = [p.strip() for p in text.split(",")]
    if not text.strip() or any(p == "" for p in parts):
        raise CLIError(f"{name}: {text!r} is not a comma-separated list of numbers")
    return [finite_float(p, name) for p in parts]


def nonnegative(value: float, name: str) -> float:
    if value < 0:
        raise CLIError(f"{name} must be >= 0, got {value:g}")
    return value


def positive_int(text: str | int, name: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise CLIError(f"{name}: {text!r} is not an integer") from None
    if value < 1:
        raise CLIError(f"{name} must be >= 1, got {value}")
    return value


def _to_jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


def print_json(payload: dict) -> None:
    print(json.dumps({k: _to_jsonable(v) for k, v in payload.items()}))


def _format_moments(label: str, mean, cov, skew=None) -> str:
    with np.printoptions(precision=6, suppress=False):
        text = f"{label}\n  mean: {np.asarray(mean)}\n  cov:\n{np.asarray(cov)}"
        return text if skew is None else f"{text}\n  skew: {np.asarray(skew)}"


def _add_noise_args(p: argparse.ArgumentParser, sigma_default: float) -> None:
    p.add_argument("--sigma", default=str(sigma_default),
                   help=f"joint noise standard deviation, radians (default {sigma_default})")
    p.add_argument("--noise", default="gaussian", choices=("gaussian", "uniform", "triangular"))
    p.add_argument("--samples", default="10000", help="number of Monte Carlo draws")
    p.add_argument("--seed", default="0", help="random seed")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _noise_from(args) -> tuple:
    from kinegrasp_env.noise import JointNoise

    sigma = nonnegative(finite_float(args.sigma, "--sigma"), "--sigma")
    samples = positive_int(args.samples, "--samples")
    seed = _seed(args.seed)
    return JointNoise(sigma, args.noise), sigma, samples, seed


def _seed(text: str) -> int:
    try:
        seed = int(text)
    except ValueError:
        raise CLIError(f"--seed: {text!r} is not an integer") from None
    if seed < 0:
        raise CLIError(f"--seed must be >= 0, got {seed}")
    return seed


# ----------------------------------------------------------------------------- commands
def cmd_planar(args) -> int:
    from kinegrasp_env.planar import PlanarArm
    from kinegrasp_env.stats import moments

    links = float_list(args.links, "--links")
    q0 = float_list(args.q0, "--q0")
    if len(links) != len(q0):
        raise CLIError(f"--links has {len(links)} lengths but --q0 has {len(q0)} angles")
    if any(v <= 0 for v in links):
        raise CLIError(f"--links: link lengths must be > 0, got {args.links}")
    noise, sigma, samples, seed = _noise_from(args)
    arm = PlanarArm(tuple(links))
    ee = arm.sample(np.array(q0), noise, samples, np.random.default_rng(seed))
    mom = moments(ee)
    exact_mean, exact_cov = arm.exact_moments(np.array(q0), noise)
    if args.plot:
        from kinegrasp_env.plots import plot_planar

        plot_planar(arm.joint_positions(np.array(q0)), ee, mom.mean, mom.cov, args.plot,
                    title=f"{len(links)}-link arm, sigma = {sigma:g} rad ({args.noise})")
    if args.json:
        print_json({"mean": mom.mean, "cov": mom.cov, "skew": mom.skew, "samples": samples,
                    "exact_mean": exact_mean, "exact_cov": exact_cov, "sigma": sigma,
                    "noise": args.noise, "seed": seed})
    else:
        print(_format_moments(f"end effector of a {len(links)}-link planar arm "
                              f"({samples} draws)", mom.mean, mom.cov, mom.skew))
        print(_format_moments("closed form", exact_mean, exact_cov))
        if args.plot:
            print(f"plot written to {args.plot}")
    return 0


def cmd_kuka_ee(args) -> int:
    from kinegrasp_env.endeffector import check_kuka_q0, sample_kuka_end_effector
    from kinegrasp_env.stats import moments

    q0 = float_list(args.q0, "--q0")
    try:
        q0 = check_kuka_q0(q0)
    except ValueError as exc:
        raise CLIError(f"--q0: {exc}") from None
    noise, sigma, samples, seed = _noise_from(args)
    ee = sample_kuka_end_effector(q0, noise, samples, np.random.default_rng(seed))
    mom = moments(ee)
    if args.json:
        print_json({"mean": mom.mean, "cov": mom.cov, "skew": mom.skew, "samples": samples,
                    "sigma": sigma, "noise": args.noise, "seed": seed})
    else:
        print(_format_moments(f"KUKA palm position ({samples} draws)", mom.mean, mom.cov,
                              mom.skew))
    return 0


def cmd_convergence(args) -> int:
    from tqdm import tqdm

    from kinegrasp_env.endeffector import (
        DEFAULT_KUKA_Q0,
        DEFAULT_PLANAR_LINKS,
        DEFAULT_PLANAR_Q0,
        PAPER_SIGMAS,
        kuka_convergence,
        planar_convergence,
    )
    from kinegrasp_env.planar import PlanarArm
    from kinegrasp_env.plots import plot_convergence

    trials = positive_int(args.trials, "--trials")
    truth = positive_int(args.truth_samples, "--truth-samples")
    max_n = positive_int(args.max_samples, "--max-samples")
    if max_n < 10:
        raise CLIError(f"--max-samples must be >= 10, got {max_n}")
    seed = _seed(args.seed)
    sizes = np.unique(np.round(np.logspace(1, np.log10(max_n), 10)).astype(int))
    arm = PlanarArm(DEFAULT_PLANAR_LINKS)
    jobs = [(label, s) for label in ("2-link planar arm", "KUKA iiwa") for s in PAPER_SIGMAS]
    curves: dict[str, dict[float, object]] = {}
    for i, (label, sigma) in enumerate(tqdm(jobs, desc="convergence", file=sys.stderr,
                                            disable=None)):
        stream = np.random.default_rng([seed, i])  # independent stream per curve
        if label.startswith("2-link"):
            curve = planar_convergence(arm, DEFAULT_PLANAR_Q0, sigma, sizes=sizes, trials=trials,
                                       truth_samples=truth, seed=stream)
        else:
            curve = kuka_convergence(DEFAULT_KUKA_Q0, sigma, sizes=sizes, trials=trials,
                                     truth_samples=truth, seed=stream)
        curves.setdefault(label, {})[sigma] = curve
    path = plot_convergence(curves, args.out)
    summary = {label: {f"{s:g}": {"samples": c.sizes.tolist(), "mean_error": c.mean_error.tolist(),
                                  "cov_error": c.cov_error.tolist(),
                                  "skew_error": c.skew_error.tolist()}
                       for s, c in by.items()} for label, by in curves.items()}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"convergence figure written to {path}")
    return 0


def cmd_objects(args) -> int:
    from kinegrasp_env.objects import catalog

    rows = catalog()
    if args.json:
        print(json.dumps(rows))
        return 0
    print(f"{'name':<12} {'size x, y, z [m]':<26} {'r_max [m]':>9} {'parts':>5}")
    for r in rows:
        size = ", ".join(f"{v:.3f}" for v in r["size"])
        print(f"{r['name']:<12} {size:<26} {r['r_max']:>9.4f} {r['parts']:>5}")
    return 0


def add_execution_args(parser: argparse.ArgumentParser, default_processes: int) -> None:
    """``--backend``, ``--address`` and ``--processes`` (see :func:`executor_from`)."""
    parser.add_argument("--backend", default="local",
                        help="local (a process pool on this machine, the default) or ray")
    parser.add_argument("--address", help="Ray cluster to use with --backend ray (e.g. "
                        "ray://head:10001); without it a local Ray instance is started")
    parser.add_argument("--processes", default=None,
                        help=f"local worker processes (default {default_processes}); with "
                        "--backend ray and no --address, the local Ray instance's CPUs "
                        "(default: all)")
    parser.set_defaults(default_processes=default_processes)


def executor_from(args):
    """The :class:`~kinegrasp_env.execution.Executor` that the command line asks for."""
    from kinegrasp_env.execution import BACKENDS, make_executor

    if args.backend not in BACKENDS:
        raise CLIError(f"--backend must be one of {', '.join(BACKENDS)}, got {args.backend!r}")
    processes = None if args.processes is None else positive_int(args.processes, "--processes")
    if args.backend == "local" and processes is None:
        processes = args.default_processes
    return make_executor(args.backend, processes, args.address)


def engine_name(value: str) -> str:
    """Validated ``--engine`` value."""
    from kinegrasp_env.evaluate import ENGINES

    if value not in ENGINES:
        raise CLIError(f"--engine must be one of {', '.join(ENGINES)}, got {value!r}")
    return value


def cmd_evaluate(args) -> int:
    from kinegrasp_env.evaluate import evaluate_grasp
    from kinegrasp_env.grasps import grasp_by_index

    noise, sigma, samples, seed = _noise_from(args)
    index = _index(args.grasp)
    grasp = grasp_by_index(args.object, index)
    engine = engine_name(args.engine)
    with executor_from(args) as executor:
        stats = evaluate_grasp(grasp, noise, samples, seed, engine=engine,
                               return_draws=bool(args.plot), progress=True, executor=executor)
    if args.plot:
        from kinegrasp_env.objects import load_object
        from kinegrasp_env.plots import plot_contacts

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


def _index(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise CLIError(f"--grasp: {text!r} is not an integer") from None


def cmd_reproduce(args) -> int:
    from kinegrasp_env import experiments
    from kinegrasp_env.experiments import markdown_table1, table1

    samples = positive_int(args.samples, "--samples")
    engine = engine_name(args.engine)
    if args.figure not in ("table1", "fig7", "fig9", "fig10"):
        raise CLIError(f"unknown experiment {args.figure!r}; available: table1, fig7, fig9, "
                       "fig10")
    out = args.out or f"out/{args.figure}"
    seed = _seed(args.seed)
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


# ----------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="kinegrasp", description="Grasp quality under kinematic (joint-angle) noise.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("planar", help="end-effector statistics of a planar arm under joint noise")
    p.add_argument("--links", default="2,2", help="comma-separated link lengths, metres")
    p.add_argument("--q0", default="0.0,1.5708", help="comma-separated joint angles, radians")
    _add_noise_args(p, 0.0175)
    p.add_argument("--plot", help="write a PNG of the arm, the sampled cloud and its ellipse")
    p.set_defaults(func=cmd_planar)

    p = sub.add_parser("kuka-ee", help="palm-position statistics of the KUKA under joint noise")
    p.add_argument("--q0", default="0,0.6,0,-1.2,0,0.8,0", help="7 arm joint angles, radians")
    _add_noise_args(p, 0.0133)
    p.set_defaults(func=cmd_kuka_ee)

    p = sub.add_parser("convergence", help="Fig. 3: estimator convergence, planar arm and KUKA")
    p.add_argument("--out", default="convergence.png", help="output PNG")
    p.add_argument("--trials", default="10")
    p.add_argument("--truth-samples", default="100000")
    p.add_argument("--max-samples", default="10000")
    p.add_argument("--seed", default="0")
    p.add_argument("--json", action="store_true", help="print the curves as JSON")
    p.set_defaults(func=cmd_convergence)

    p = sub.add_parser("objects", help="list the object catalog")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_objects)

    p = sub.add_parser("evaluate", help="Monte Carlo P(FC) and quality of a shipped grasp")
    p.add_argument("--object", default="spray_flask")
    p.add_argument("--grasp", default="0", help="index in the object's shipped grasp set")
    _add_noise_args(p, 0.0133)
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

    from kinegrasp_env.cli_toolkit import add_commands

    add_commands(sub)
    return parser


_NEGATIVE_VALUE = re.compile(r"^-(\.?\d|inf|nan)", re.IGNORECASE)


def _glue_negative_values(argv: list[str]) -> list[str]:
    """Turn ``--q0 -0.5,1`` into ``--q0=-0.5,1`` (argparse would read -0.5,1 as an option)."""
    out: list[str] = []
    for token in argv:
        if (out and out[-1].startswith("--") and "=" not in out[-1]
                and _NEGATIVE_VALUE.match(token)):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(_glue_negative_values(argv))
    try:
        return int(args.func(args) or 0)
    except (CLIError, ValueError, FileNotFoundError, KeyError) as exc:
        message = exc.args[0] if exc.args else str(exc)
        print(f"kinegrasp {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("kinegrasp: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    # run the importable module's main, so its exception classes are the ones other
    # modules raise (``python -m`` executes this file as a separate ``__main__`` module)
    from kinegrasp_env.cli import main as _main

    sys.exit(_main())
