"""Report commands: ``report`` (one grasp's evaluation, at one or several noise levels or
under a noise model, as a self-contained interactive HTML page) and ``screenshot`` (a page
rendered to PNG by the system's headless Chromium through Playwright, the ``screenshot``
extra; network off). ``report`` and ``evaluate --report`` write every robot's page
through :mod:`kinegrasp_env.cli.grasp_report`; ``rank --report`` and ``elbow --report``
write theirs through :func:`write_rank_report` and :func:`write_elbow_report`.
"""

from __future__ import annotations

import html
import json
import re
import shlex
import sys
from pathlib import Path

from kinegrasp_env.cli.command_words import friction_words, noise_words, sigma_words
from kinegrasp_env.cli.common import (
    NUM_EDGES,
    CLIError,
    add_engine_arg,
    add_friction_arg,
    add_noise_spec_arg,
    add_object_arg,
    float_list,
    friction_setting,
    positive_int,
    sigma_value,
)
from kinegrasp_env.cli.execution_options import add_execution_args
from kinegrasp_env.cli.output_paths import PNG_SUFFIXES, input_files, output_file

#: Defaults of ``--max-points`` and ``--arm-draws``: equal to ``report.scene.MAX_POINTS`` and
#: ``report.page.ARM_DRAWS`` (tested), kept here so that building the parser stays cheap.
MAX_POINTS_DEFAULT = 15_000
ARM_DRAWS_DEFAULT = 20


def sigmas_from(text: str) -> list[float]:
    """``--sigma``: one value or a comma-separated list, each in [0, pi] radians, distinct."""
    values = [sigma_value(s) for s in float_list(text, "--sigma")]
    if len(set(values)) != len(values):
        raise CLIError(f"--sigma: {text!r} lists a value twice")
    return values


def noise_settings(args, noises: list) -> dict:
    """The noise rows of a page's settings (``noises``: JointNoise or NoiseModel, one per
    run): the spec file and its sources, or the sigmas and the distribution."""
    if getattr(args, "noise_spec", None):
        return {"noise spec": args.noise_spec,
                "noise sources": ", ".join(noises[0].sources) or "none (every source exact)"}
    return {"sigma [rad]": ", ".join(sigma_words(n.sigma) for n in noises),
            "noise": noises[0].kind}


def cmd_report(args) -> int:
    from kinegrasp_env.cli.grasp_report import run_report

    return run_report(args, sigmas_from(args.sigma))


#: Draws whose arm skeletons a ranking page draws per candidate (the same rows for every one).
RANK_ARM_DRAWS = 10


def hold_scores(result) -> dict[str, float]:
    """A ranked candidate's hold scores for its report row, keyed as ``rank``'s CSV columns
    (:data:`~kinegrasp_env.cli.ranking_table.HOLD_COLUMNS`, the margin with the holding
    test): P(hold, static), P(hold) and the holding test's mean margin, those it has."""
    from kinegrasp_env.cli.ranking_table import HOLD_COLUMNS, MARGIN_COLUMN

    out = {HOLD_COLUMNS[score][0]: result.p_hold(score) for score in result.holds}
    if "test" in result.holds:
        out[MARGIN_COLUMN[0]] = result.hold_margin()
    return out


def write_rank_report(args, grasps, results, robot: str, *, noise, samples: int, seed: int,
                      engine: str, friction: float = 0.5, adaptive=None) -> None:
    """``rank --report FILE`` of any robot's candidates: the sortable table and each
    candidate's 3-D scene on demand (:func:`~kinegrasp_env.toolkit.report.ranking.
    rank_page`), with the arm at the ranking's first draws under joint noise; an adaptive
    run's (``adaptive``: its report) labels and what it certified, as the console shows
    them."""
    from kinegrasp_env.cli.ranking_table import certified_line
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit.ranking import HOLD_TEST_CRITERIA
    from kinegrasp_env.toolkit.report.arms import first_arms
    from kinegrasp_env.toolkit.report.page import write_page
    from kinegrasp_env.toolkit.report.ranking import rank_page
    from kinegrasp_env.world.objects import load_object

    description = load_robot(robot)
    rows = []
    for r in results:
        lo, hi = r.interval()
        mean, std, _ = r.q_stats()
        rows.append({"index": r.index, "id": grasps[r.index].id, "p_fc": r.p_fc,
                     "p_fc_lo": lo, "p_fc_hi": hi, "q_mean": mean,
                     "q_std": std,
                     "q_nominal": grasps[r.index].q_nominal, "samples": r.trials,
                     "q_skew": r.q_stats()[2], "outcomes": dict(r.outcomes),
                     "holds": hold_scores(r)})
    if adaptive is not None:
        for row, label in zip(rows, adaptive.certified, strict=True):
            row["certified"] = label
    command = ["kinegrasp", "rank", args.candidates, "--robot", robot,
               *noise_words(args, sigma_words(noise.sigma)), "--samples", str(samples),
               "--seed", str(seed), "--criterion", args.criterion,
               *(["--static-hold"] if args.static_hold else []),
               *(["--hold-simulator", args.hold_simulator]
                 if args.criterion in HOLD_TEST_CRITERIA else []),
               *(["--adaptive", "--top-k", str(args.top_k), "--epsilon", str(args.epsilon),
                  "--delta", str(args.delta)] if args.adaptive else []),
               *(["--best-elbow", str(args.best_elbow)] if args.best_elbow else []),
               "--engine", engine, *friction_words(args), "--out", str(args.out), "--report",
               str(args.report)]
    names = list(dict.fromkeys(g.object for g in grasps))
    joint_noise = not getattr(args, "noise_spec", None)
    settings = {"robot": robot, "candidates": args.candidates, "object": ", ".join(names),
                **noise_settings(args, [noise]),
                "draws per candidate": samples, "seed (every candidate)": seed,
                "criterion": args.criterion,
                "adaptive": f"top {args.top_k}, epsilon {args.epsilon}, delta {args.delta}"
                if args.adaptive else "no",
                "engine": engine, "contact model": description.contact_model,
                "friction mu": friction_setting(noise, friction),
                "friction cone edges": NUM_EDGES,
                "noisy arms drawn": min(RANK_ARM_DRAWS, samples) if joint_noise else
                "none (a noise spec's draws move more than the arm)"}
    arms = ([first_arms(description, g, None, noise.sigma, seed, noise.kind,
                        min(RANK_ARM_DRAWS, samples)) for g in grasps] if joint_noise else None)
    text = rank_page(description, {name: load_object(name) for name in names}, grasps, rows,
                     command=shlex.join(command), settings=settings, arms=arms,
                     friction=friction, num_edges=NUM_EDGES,
                     certificate=None if adaptive is None else
                     certified_line(adaptive, max(r.trials for r in results)))
    write_page(args.report, text)
    print(f"report written to {args.report} ({len(text.encode()) / 1e6:.1f} MB)",
          file=sys.stderr if args.json else sys.stdout)


def chosen_words(args, grasp, index: int) -> list[str]:
    """The words that choose an elbow page's grasp again: ``--grasps FILE --grasp ID`` (the
    file's grasps are found by id first), else ``--object NAME --grasp INDEX`` of the shipped
    set."""
    if getattr(args, "grasps", None):
        return ["--grasps", str(args.grasps), "--grasp", str(grasp.id)]
    return ["--object", args.object, "--grasp", str(index)]


def elbow_command_settings(args, grasp, index: int, result, noise, robot: str,
                           evidence=None, friction: float = 0.5) -> tuple[str, dict]:
    """(the command line that reproduces an elbow page, its settings table) of ``elbow
    --report`` of robot ``robot`` (the grasp chosen from ``--grasps FILE`` or a shipped set)."""
    out = Path(args.report)
    chosen = chosen_words(args, grasp, index)
    command = ["kinegrasp", "elbow", "--robot", robot, *chosen,
               *noise_words(args, sigma_words(noise.sigma)), "--samples", str(result.samples),
               "--seed", str(result.seed), "--engine", result.engine,
               "--epsilon", f"{result.certificate.epsilon:g}",
               "--delta", f"{result.certificate.delta:g}", *friction_words(args), "--report",
               str(out)]
    if evidence is not None:
        command[-2:-2] = ["--method", "reweight", "--batch", str(evidence.batch)]
    settings = {"robot": robot, "object": grasp.object,
                "grasp": f"index {index} (id {grasp.id})",
                **noise_settings(args, [noise]),
                "draws per elbow angle (selection; fresh again)": result.samples,
                "seed (selection: chunks 0..K-1, fresh: K..2K-1)": result.seed,
                "engine": result.engine, "elbow angles evaluated": len(result.curve),
                "fine grid step [rad]": f"{result.grid_step:.4f}",
                "certificate epsilon, delta": f"{result.certificate.epsilon:g}, "
                                              f"{result.certificate.delta:g}",
                "friction mu": friction_setting(noise, friction),
                "friction cone edges": NUM_EDGES}
    if evidence is None:  # a re-weighted angle has direct draws only where topped up
        settings["noisy arms drawn per view"] = ARM_DRAWS_DEFAULT
    else:
        settings["method"] = (f"reweight: one batch of {evidence.batch} closings over the "
                              "palm's deviation, the chosen and nominal elbow on fresh "
                              "direct draws")
    return shlex.join(command), settings


def write_elbow_report(args, description, grasp, index: int, result, noise, evidence=None,
                       friction: float = 0.5) -> None:
    """``elbow --report FILE``: P(FC) along the self-motion with the nominal and the best
    elbow marked, and the robot at both (:func:`~kinegrasp_env.toolkit.report.elbow.
    elbow_page`; ``result``: ``optimize_robot_elbow(grasp, noise, ...)``, or the re-weighted
    search's with its ``evidence``: then the batch, and the fragile directions drawn)."""
    from kinegrasp_env.toolkit.report.elbow import elbow_page

    command, settings = elbow_command_settings(args, grasp, index, result, noise,
                                               description.name, evidence, friction)
    text = elbow_page(description, grasp, result, noise, command=command, settings=settings,
                      friction=friction, num_edges=NUM_EDGES, arm_draws=ARM_DRAWS_DEFAULT,
                      fragility=None if evidence is None else evidence.picture(),
                      reweighted=evidence is not None)
    _written(args, text)


def _written(args, text: str) -> None:
    """Write ``--report``'s page and say so (on stderr beside ``--json``)."""
    from kinegrasp_env.toolkit.report.page import write_page

    out = Path(args.report)
    write_page(out, text)
    print(f"report written to {out} ({len(text.encode()) / 1e6:.1f} MB)",
          file=sys.stderr if args.json else sys.stdout)


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
    from kinegrasp_env.toolkit.report.browser import (
        BrowserError,
        check_page,
        find_chromium,
        load_playwright,
    )

    page = Path(args.page)
    if not page.is_file():
        raise CLIError(f"{args.page}: no such file")
    out = output_file(args.out, "--out", inputs=input_files(args), suffixes=PNG_SUFFIXES)
    width = positive_int(args.width, "--width")
    height = positive_int(args.height, "--height")
    opener = show_candidates(page, args.show)
    try:
        load_playwright()
    except BrowserError as exc:
        raise CLIError(f"screenshot: {exc}") from None
    if find_chromium() is None:
        raise CLIError("no chromium on PATH (Debian: apt-get install chromium)")
    try:
        check = check_page(page, before_screenshot=opener, width=width, height=height)
    except BrowserError as exc:
        raise CLIError(f"chromium: {exc}") from None
    from kinegrasp_env.toolkit.report.page import write_page

    write_page(out, check.screenshot)
    drawn = (f"drawn in {check.ready_ms:.0f} ms" if check.ready_ms is not None else
             "not drawn" if check.expected else "no kinegrasp figure (not a kinegrasp report?)")
    print(f"{page}: {drawn}, {len(check.errors)} console errors; screenshot written to {out}")
    for error in check.errors:
        print(f"  {error}", file=sys.stderr)
    for url in check.remote:
        print(f"  network request refused: {url}", file=sys.stderr)
    return 0 if not check.errors and not check.remote and check.ready_ms is not None else 1


def add_commands(sub) -> None:
    """Register ``report`` and ``screenshot``."""
    from kinegrasp_env.cli.common import DISTRIBUTION_NAMES as DISTRIBUTIONS
    from kinegrasp_env.cli.grasp_choice import EVALUATE_OBJECT
    from kinegrasp_env.robot.default import DEFAULT_ROBOT

    p = sub.add_parser("report", help="evaluate one grasp or several and write a "
                       "self-contained interactive HTML page (P(FC) and Q table, 3-D scenes, "
                       "histogram, outcomes, P(FC) vs sigma)")
    add_object_arg(p, None, f"catalog object, built-in or imported (default {EVALUATE_OBJECT}; "
                   "with --grasps: the grasp's own)")
    p.add_argument("--grasps", help="a grasp file (e.g. `kinegrasp plan`'s output) or a "
                   "palm-pose file; --grasp is then an id in it, or an index")
    p.add_argument("--grasp", help="ids or indices of the shipped set's grasps (or with "
                   "--grasps, of that file's), comma-separated (default 0: the grasp with id "
                   "0, else the first; as evaluate's)")
    p.add_argument("--robot", help="catalog robot (default: the grasp file's, else "
                   f"{DEFAULT_ROBOT})")
    p.add_argument("--sigma", default="0.0133", help="joint noise standard deviation, "
                   "radians; several, comma-separated, give the P(FC)-vs-sigma curve (the "
                   "3-D views are of the first)")
    p.add_argument("--noise", default="gaussian", choices=DISTRIBUTIONS,
                   help="distribution of the joint noise (all with standard deviation sigma)")
    add_noise_spec_arg(p)
    p.add_argument("--samples", default="2000", help="Monte Carlo draws per sigma")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_execution_args(p, 1)
    add_engine_arg(p)
    add_friction_arg(p)
    p.add_argument("--out", required=True, help="the HTML file to write")
    p.add_argument("--max-points", default=str(MAX_POINTS_DEFAULT),
                   help="most draw contact points drawn (a uniform random subset past it)")
    p.add_argument("--arm-draws", default=str(ARM_DRAWS_DEFAULT),
                   help="noisy draws whose arm skeletons are drawn")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("screenshot", help="render an HTML report to PNG in the system's "
                       "headless Chromium (network off; needs the screenshot extra: "
                       "Playwright); exit 1 on console errors or a request off the machine")
    p.add_argument("page", help="the HTML file")
    p.add_argument("--out", required=True, help="the PNG file to write")
    p.add_argument("--width", default="1400", help="viewport width, CSS pixels")
    p.add_argument("--height", default="1000", help="viewport height, CSS pixels")
    p.add_argument("--show", help="on a ranking page, the ids of the candidates whose 3-D "
                   "views to open first, comma-separated (e.g. 3v1,3)")
    p.set_defaults(func=cmd_screenshot)
