"""Report commands: ``report`` (one grasp's evaluation, at one or several noise levels, as a
self-contained interactive HTML page) and ``screenshot`` (a page rendered to PNG by headless
Chromium, network off). ``evaluate --report`` and ``rank --report`` write their pages through
:func:`write_evaluation_report` and :func:`write_rank_report`.
"""

from __future__ import annotations

import html
import json
import re
import shlex
import sys
from pathlib import Path

from kinegrasp_env.cli.common import (
    MAX_SIGMA,
    CLIError,
    add_engine_arg,
    add_execution_args,
    add_object_arg,
    engine_name,
    executor_from,
    float_list,
    grasp_index_help,
    nonnegative,
    output_file,
    parse_seed,
    positive_int,
    shipped_grasp,
)

FRICTION, NUM_EDGES = 0.5, 8
#: Defaults of ``--max-points`` and ``--arm-draws``: equal to ``report_scene.MAX_POINTS`` and
#: ``report.ARM_DRAWS`` (tested), kept here so that building the parser stays cheap.
MAX_POINTS_DEFAULT = 15_000
ARM_DRAWS_DEFAULT = 20


def sigmas_from(text: str) -> list[float]:
    """``--sigma``: one value or a comma-separated list, each in [0, pi] radians, distinct."""
    values = [nonnegative(s, "--sigma") for s in float_list(text, "--sigma")]
    for value in values:
        if value > MAX_SIGMA:
            raise CLIError(f"--sigma must be <= pi ({MAX_SIGMA:.5f} rad), got {value:g}")
    if len(set(values)) != len(values):
        raise CLIError(f"--sigma: {text!r} lists a value twice")
    return values


def _settings(grasp, index: int, sigmas: list[float], noise: str, samples: int, seed: int,
              engine: str, max_points: int, arm_draws: int) -> dict:
    from kinegrasp_env.montecarlo.evaluate import DEFAULT_CHUNK

    return {"object": grasp.object, "grasp": f"index {index} (id {grasp.id})",
            "sigma [rad]": ", ".join(f"{s:g}" for s in sigmas), "noise": noise,
            "draws per sigma": samples, "seed": seed, "engine": engine,
            "friction mu": FRICTION, "friction cone edges": NUM_EDGES,
            "draws per chunk (random streams)": DEFAULT_CHUNK,
            "contact points drawn at most": max_points, "noisy arms drawn": arm_draws}


def write_evaluation_report(path: Path, grasp, index: int, runs: list, *, command: list[str],
                            max_points: int, arm_draws: int) -> int:
    """Write the page of ``runs`` (GraspStats, the first with draws); returns its bytes."""
    from kinegrasp_env.toolkit.report import evaluation_page, write_page

    first = runs[0]
    settings = _settings(grasp, index, [float(r.sigma) for r in runs], first.noise,
                         first.samples, first.seed, first.engine, max_points, arm_draws)
    text = evaluation_page(grasp, runs, command=shlex.join(command), settings=settings,
                           friction=FRICTION, num_edges=NUM_EDGES, max_points=max_points,
                           arm_draws=arm_draws)
    write_page(path, text)
    return len(text.encode())


def evaluation_command(args, name: str, index: int, sigma_text: str, samples: int, seed: int,
                       engine: str, out_option: str, out: Path) -> list[str]:
    """The canonical command line of an evaluation page (every setting spelled out; a grasp
    from ``evaluate --grasps FILE`` keeps the file and the ``--grasp`` given)."""
    chosen = ["--grasp", str(index)]
    if getattr(args, "grasps", None):
        chosen = ["--grasps", str(args.grasps), "--grasp", str(args.grasp)]
    return ["kinegrasp", name, "--object", args.object, *chosen, "--sigma", sigma_text,
            "--noise", args.noise, "--samples", str(samples), "--seed", str(seed), "--engine",
            engine, out_option, str(out)]


def cmd_report(args) -> int:
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
    from kinegrasp_env.sampling.noise import JointNoise

    sigmas = sigmas_from(args.sigma)
    samples = positive_int(args.samples, "--samples")
    seed = parse_seed(args.seed)
    index, grasp = shipped_grasp(args.object, args.grasp)
    engine = engine_name(args.engine)
    max_points = positive_int(args.max_points, "--max-points")
    arm_draws = positive_int(args.arm_draws, "--arm-draws", low=0)
    out = output_file(args.out, "--out")
    with executor_from(args) as executor:
        runs = [evaluate_grasp(grasp, JointNoise(sigma, args.noise), samples, seed,
                               engine=engine, return_draws=i == 0, progress=True,
                               executor=executor)
                for i, sigma in enumerate(sigmas)]
    command = evaluation_command(args, "report", index, ",".join(f"{s:g}" for s in sigmas),
                                 samples, seed, engine, "--out", out)
    command += ["--max-points", str(max_points), "--arm-draws", str(arm_draws)]
    size = write_evaluation_report(out, grasp, index, runs, command=command,
                                   max_points=max_points, arm_draws=arm_draws)
    if args.json:
        print(json.dumps({"report": str(out), "bytes": size,
                          "runs": [r.to_json() for r in runs]}))
        return 0
    for run in runs:
        lo, hi = run.p_fc_ci
        print(f"{args.object} grasp {index}, sigma = {run.sigma:g} ({args.noise}), {samples} "
              f"draws: P(FC) = {run.p_fc:.4f} (95% CI {lo:.4f} .. {hi:.4f})")
    print(f"report written to {out} ({size / 1e6:.1f} MB)")
    return 0


def report_path(text: str | None, name: str = "--report") -> Path | None:
    """A validated ``--report`` file, or None when not asked for."""
    return None if text is None else output_file(text, name)


def evaluate_report(args, grasp, index: int, stats) -> None:
    """``evaluate --report FILE``: the page of one evaluation (``stats`` with its draws)."""
    out = Path(args.report)
    command = evaluation_command(args, "evaluate", index, f"{stats.sigma:g}", stats.samples,
                                 stats.seed, stats.engine, "--report", out)
    size = write_evaluation_report(out, grasp, index, [stats], command=command,
                                   max_points=MAX_POINTS_DEFAULT, arm_draws=ARM_DRAWS_DEFAULT)
    print(f"report written to {out} ({size / 1e6:.1f} MB)",
          file=sys.stderr if args.json else sys.stdout)


def write_rank_report(args, grasps, results, *, noise, samples: int, seed: int,
                      engine: str) -> None:
    """``rank --report FILE``: the sortable table and each candidate's 3-D views."""
    from kinegrasp_env.toolkit.report import rank_page, write_page

    rows = []
    for r in results:
        lo, hi = r.interval()
        mean, std, _ = r.q_stats()
        rows.append({"index": r.index, "id": grasps[r.index].id, "p_fc": r.p_fc,
                     "p_fc_lo": lo, "p_fc_hi": hi, "q_mean": mean,
                     "q_std": std,
                     "q_nominal": grasps[r.index].q_nominal, "samples": r.trials})
    command = ["kinegrasp", "rank", args.candidates, "--sigma", f"{noise.sigma:g}", "--noise",
               noise.kind, "--samples", str(samples), "--seed", str(seed), "--criterion",
               args.criterion, *(["--adaptive", "--top-k", str(args.top_k)] if args.adaptive
                                 else []),
               "--engine", engine, "--out", str(args.out), "--report", str(args.report)]
    settings = {"candidates": args.candidates, "object": grasps[0].object,
                "sigma [rad]": f"{noise.sigma:g}", "noise": noise.kind,
                "draws per candidate": samples, "seed": seed, "criterion": args.criterion,
                "adaptive": f"top {args.top_k}" if args.adaptive else "no",
                "engine": engine, "friction mu": FRICTION, "friction cone edges": NUM_EDGES}
    text = rank_page(grasps, rows, command=shlex.join(command), settings=settings, noise=noise,
                     seed=seed, samples=samples, friction=FRICTION, num_edges=NUM_EDGES)
    write_page(args.report, text)
    print(f"report written to {args.report} ({len(text.encode()) / 1e6:.1f} MB)")


def show_candidates(page: Path, text: str | None) -> str | None:
    """JavaScript that opens the 3-D views of the ranking candidates ``--show`` names."""
    if not text:
        return None
    ids = [t.strip() for t in text.split(",")]
    known = re.findall(r'<tr class="kg-item" [^>]*data-id="([^"]*)"', page.read_text())
    missing = [i for i in ids if html.escape(i, quote=True) not in known]
    if missing:
        raise CLIError(f"--show: {page} has no candidate {missing[0]!r}"
                       + (f" (ids: {', '.join(known)})" if known else " (not a ranking page)"))
    selectors = json.dumps([f'tr.kg-item[data-id="{html.escape(i, quote=True)}"] button'
                            for i in ids])
    return f"{selectors}.forEach(s => document.querySelector(s).click())"


def cmd_screenshot(args) -> int:
    from kinegrasp_env.toolkit.report_browser import BrowserError, check_page, find_chromium

    page = Path(args.page)
    if not page.is_file():
        raise CLIError(f"{args.page}: no such file")
    out = output_file(args.out, "--out")
    width = positive_int(args.width, "--width")
    height = positive_int(args.height, "--height")
    opener = show_candidates(page, args.show)
    if find_chromium() is None:
        raise CLIError("no chromium on PATH (Debian: apt-get install chromium)")
    try:
        check = check_page(page, before_screenshot=opener, width=width, height=height)
    except BrowserError as exc:
        raise CLIError(f"chromium: {exc}") from None
    from kinegrasp_env.toolkit.report import write_page

    write_page(out, check.screenshot)
    drawn = "not drawn" if check.ready_ms is None else f"drawn in {check.ready_ms:.0f} ms"
    print(f"{page}: {drawn}, {len(check.errors)} console errors; screenshot written to {out}")
    for error in check.errors:
        print(f"  {error}", file=sys.stderr)
    return 0 if not check.errors and check.ready_ms is not None else 1


def add_commands(sub) -> None:
    """Register ``report`` and ``screenshot``."""
    from kinegrasp_env.sampling.noise import DISTRIBUTIONS

    p = sub.add_parser("report", help="evaluate one grasp and write a self-contained "
                       "interactive HTML page (3-D views, histogram, P(FC) vs sigma)")
    add_object_arg(p, "spray_flask", "catalog object")
    p.add_argument("--grasp", default="0", help=grasp_index_help())
    p.add_argument("--sigma", default="0.0133", help="joint noise standard deviation, "
                   "radians; several, comma-separated, give the P(FC)-vs-sigma curve (the "
                   "3-D views are of the first)")
    p.add_argument("--noise", default="gaussian", choices=DISTRIBUTIONS,
                   help="distribution of the joint noise (all with standard deviation sigma)")
    p.add_argument("--samples", default="2000", help="Monte Carlo draws per sigma")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_execution_args(p, 1)
    add_engine_arg(p)
    p.add_argument("--out", required=True, help="the HTML file to write")
    p.add_argument("--max-points", default=str(MAX_POINTS_DEFAULT),
                   help="most draw contact points drawn (a uniform random subset past it)")
    p.add_argument("--arm-draws", default=str(ARM_DRAWS_DEFAULT),
                   help="noisy draws whose arm skeletons are drawn")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("screenshot", help="render an HTML report to PNG in headless Chromium "
                       "(network off); exit 1 on console errors")
    p.add_argument("page", help="the HTML file")
    p.add_argument("--out", required=True, help="the PNG file to write")
    p.add_argument("--width", default="1400", help="viewport width, CSS pixels")
    p.add_argument("--height", default="1000", help="viewport height, CSS pixels")
    p.add_argument("--show", help="on a ranking page, the ids of the candidates whose 3-D "
                   "views to open first, comma-separated (e.g. 3v1,3)")
    p.set_defaults(func=cmd_screenshot)
