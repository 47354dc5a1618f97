"""``kinegrasp elbow`` of a 6-joint arm: the grasp's variants are the IK branches of its palm
pose (no self-motion); the search over them (direct or re-weighted), its summary and its
page."""

from __future__ import annotations

import json
import sys

from kinegrasp_env.cli.common import friction_setting, plural
from kinegrasp_env.cli.elbow_output import (
    bounds_words,
    gain_line,
    reweight_lines,
    reweighted_elbow,
)
from kinegrasp_env.cli.execution_options import executor_from
from kinegrasp_env.cli.grasp_choice import grasp_shown


def branches_searched(args, index, grasp, noise, samples, seed, epsilon, delta, starts,
                      friction: float):
    """(BranchResult, ReweightEvidence or None) of ``--method direct``
    (:func:`kinegrasp_env.toolkit.elbow_search.optimize_robot_branches`) or ``reweight``
    (:func:`~kinegrasp_env.cli.elbow_output.reweighted_elbow` of the branches, its inputs
    checked before any closing)."""
    from kinegrasp_env.progress_bar import progress_bar

    if args.method == "reweight":
        return reweighted_elbow(args, grasp, index, noise, samples, seed, epsilon, delta,
                                friction, starts=starts)
    from kinegrasp_env.toolkit.elbow_search import optimize_robot_branches

    bar = progress_bar(desc=f"IK branches of {args.object} grasp "
                           f"{grasp_shown(args, index, grasp)} of {args.robot} (selection, "
                           "then fresh draws)", unit="branch")
    with executor_from(args) as executor:
        result = optimize_robot_branches(grasp, noise, samples, seed, starts=starts,
                                         epsilon=epsilon, delta=delta, friction=friction,
                                         progress=lambda done: bar.update(done - bar.n),
                                         evaluate_with=args.engine, executor=executor)
    bar.close()
    return result, None


def cmd_elbow_branches(args, index, grasp, noise, samples, seed, epsilon, delta,
                       starts, friction: float = 0.5) -> int:
    """A 6-joint arm's grasp across its IK branches (:func:`branches_searched`)."""
    result, evidence = branches_searched(args, index, grasp, noise, samples, seed, epsilon,
                                         delta, starts, friction)
    payload = {"robot": args.robot, "ik_starts": starts, **result.to_json()}
    picture = None  # a re-weighted search's why (the plot's and the page's)
    if evidence is not None:
        payload["reweight"] = evidence.to_json()
        picture = evidence.picture()
    if args.plot:  # before the results are printed: a failing figure is a warning
        from kinegrasp_env.toolkit.elbow_plots import plot_branches
        from kinegrasp_env.toolkit.plots import safe_figure

        draws = (f"one batch of {payload['reweight']['batch']} closings" if evidence
                 else f"{samples} draws per branch")
        title = (f"{args.robot}: {args.object} grasp {grasp_shown(args, index, grasp)}, sigma = "
                 f"{payload['sigma']:g} rad, {draws}")
        if safe_figure(lambda: plot_branches(payload, args.plot, title, picture), args.plot):
            payload["plot"] = str(args.plot)
    if args.json:
        print(json.dumps(payload))
    else:
        print(branch_summary(payload, grasp_shown(args, index, grasp)))
        if evidence is not None:
            print(reweight_lines(payload["reweight"], samples, unit="branch"))
        if "plot" in payload:
            print(f"plot written to {payload['plot']}")
    if args.report:
        write_branch_report(args, index, grasp, result, noise, starts, friction, picture)
    return 0


def write_branch_report(args, index: int, grasp, result, noise, starts: int,
                        friction: float, fragility: dict | None = None) -> None:
    """``elbow --report FILE`` of a 6-joint arm: the IK branches' page
    (:func:`~kinegrasp_env.toolkit.report.robot_branches.robot_branch_page`; ``fragility``:
    a re-weighted search's picture, drawn on it)."""
    import shlex

    from kinegrasp_env.cli.command_words import friction_words, noise_words, sigma_words
    from kinegrasp_env.cli.common import NUM_EDGES
    from kinegrasp_env.cli.report import chosen_words
    from kinegrasp_env.robot.catalog import load_robot
    from kinegrasp_env.toolkit.report.page import write_page
    from kinegrasp_env.toolkit.report.robot_branches import robot_branch_page

    summary, cert = result.result, result.result.certificate
    command = ["kinegrasp", "elbow", "--robot", args.robot, *chosen_words(args, grasp, index),
               *noise_words(args, sigma_words(noise.sigma)), "--samples",
               str(summary.samples), "--seed", str(summary.seed), "--engine", summary.engine,
               "--ik-starts", str(starts), "--method", args.method,
               *(["--batch", str(args.batch)] if args.batch is not None else []),
               "--epsilon", f"{cert.epsilon:g}", "--delta", f"{cert.delta:g}",
               *friction_words(args), "--report", str(args.report)]
    settings = {"robot": args.robot, "object": grasp.object,
                "grasp": f"index {index} (id {grasp.id})", "sigma [rad]": noise.sigma,
                "noise": noise.kind, "draws per branch (selection; fresh again)":
                summary.samples, "seed (selection; fresh)": summary.seed,
                "engine": summary.engine, "method": args.method, "IK starts": starts,
                "IK branches found": len(result.branches),
                "certificate epsilon, delta": f"{cert.epsilon:g}, {cert.delta:g}",
                "friction mu": friction_setting(noise, friction),
                "friction cone edges": NUM_EDGES}
    text = robot_branch_page(load_robot(args.robot), grasp, result,
                             command=shlex.join(command), settings=settings,
                             friction=friction, num_edges=NUM_EDGES, fragility=fragility)
    write_page(args.report, text)
    print(f"report written to {args.report} ({len(text.encode()) / 1e6:.1f} MB)",
          file=sys.stderr if args.json else sys.stdout)


def branch_summary(result: dict, shown: str) -> str:
    """The console summary of a 6-joint arm's IK-branch search (``BranchResult.to_json()``
    with ``robot`` and ``ik_starts``; a re-weighted run's with ``reweight``)."""
    lo, hi = result["best_p_fc_ci"]
    nlo, nhi = result["nominal_p_fc_ci"]
    n, cert = len(result["branches"]), result["certificate"]
    branches = plural(n, "IK branch", "IK branches")
    how = (f"{branches} from one batch of {result['reweight']['batch']} closings, the best "
           f"and the nominal again on {result['samples']} fresh draws"
           if "reweight" in result else
           f"{branches} x {result['samples']} draws, then again on {result['samples']} "
           "fresh draws")
    lines = [
        f"robot {result['robot']}: a 6-joint arm has no self-motion; the variants of "
        f"{result['object']} grasp {shown} are its {branches} ({result['ik_starts']} IK "
        "starts)",
        f"{result['object']} grasp {shown} of robot {result['robot']}, sigma = "
        f"{result['sigma']} rad, {how} ({result['engine']} engine)",
        f"  nominal branch {result['nominal_branch']} ({result['nominal_label']}): P(FC) "
        f"{result['nominal_p_fc']:.3f} ({nlo:.3f} .. {nhi:.3f})",
        f"  best branch    {result['best_branch']} ({result['best_label']}): P(FC) "
        f"{result['best_p_fc']:.3f} ({lo:.3f} .. {hi:.3f})  [fresh draws]",
        gain_line(result),
        f"  {cert['statement']}"]
    if cert["bound"] is not None:
        verdict = (f"certified at epsilon {cert['epsilon']:g}" if cert["certified"] else
                   f"not certified at epsilon {cert['epsilon']:g} (branch "
                   f"{cert['worst_branch']} is the rival it cannot rule out)")
        rivals = plural(len(cert["rivals"]), "other branch", "other branches")
        lines.append(f"    {verdict}; {rivals}, {bounds_words(cert)}; branches the IK starts "
                     "did not find not covered")
    for point in result["curve"]:
        fresh = (f", {point['fresh_p_fc']:.3f} fresh" if "fresh_p_fc" in point else "")
        lines.append(f"  branch {point['branch']} ({point['label']}): P(FC) {point['p_fc']:.3f} "
                     f"{'re-weighted' if 'reweight' in result else 'selection'}{fresh}")
    scored = {point["branch"] for point in result["curve"]}
    for branch in (b for b in result["branches"] if b["branch"] not in scored):
        lines.append(f"  branch {branch['branch']} ({branch['label']}): left out, its arm meets "
                     "the object or the table (the batch cannot see that)")
    return "\n".join(lines)
