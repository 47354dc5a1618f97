"""What ``kinegrasp elbow``'s searches share (a 7-joint arm's self-motion,
:mod:`kinegrasp_env.cli.elbow`, and a 6-joint arm's IK branches,
:mod:`kinegrasp_env.cli.elbow_branches`): the certificate's levels, the re-weighted run, the
plot and the printed summary."""

from __future__ import annotations

from contextlib import contextmanager

from kinegrasp_env.cli.common import CLIError, plural, positive_int, reported
from kinegrasp_env.cli.execution_options import executor_from
from kinegrasp_env.cli.grasp_choice import grasp_shown

#: ``--epsilon`` and ``--delta`` defaults: equal to ``toolkit.elbow_certificate``'s
#: ``DEFAULT_EPSILON`` and ``DEFAULT_DELTA`` (tested), copied so that building the parser
#: imports no NumPy.
DEFAULT_EPSILON, DEFAULT_DELTA = 0.05, 0.05
#: ``--ik-starts`` default (equal to ``robot.ik_branches.DEFAULT_STARTS``; copied, as above).
DEFAULT_IK_STARTS = 200


def reweighted_elbow(args, grasp, index, noise, samples, seed, epsilon, delta,
                     friction: float = 0.5, starts: int | None = None):
    """``elbow --method reweight``: (ElbowResult, ReweightEvidence) from one batch of
    closings (:func:`kinegrasp_env.toolkit.elbow_reweight_search.
    optimize_robot_elbow_reweighted`); with ``starts`` (a 6-joint arm's IK starts),
    (BranchResult, ReweightEvidence) of its IK branches
    (:func:`~kinegrasp_env.toolkit.elbow_reweight_search.
    optimize_robot_branches_reweighted`)."""
    import functools

    from kinegrasp_env.progress_bar import progress_bar
    from kinegrasp_env.toolkit.elbow_reweight_search import (
        check_robot_reweight,
        optimize_robot_branches_reweighted,
        optimize_robot_elbow_reweighted,
    )

    batch = None if args.batch is None else positive_int(args.batch, "--batch")
    optimize = (optimize_robot_elbow_reweighted if starts is None else
                functools.partial(optimize_robot_branches_reweighted, starts=starts))
    with reported(ValueError):  # noise, robot, object, batch: refused before any closing
        check_robot_reweight(grasp, noise, samples, epsilon, delta, batch, seed, args.engine)
    what = "IK branches" if starts is not None else "elbow"
    shown = grasp_shown(args, index, grasp)
    bar = progress_bar(desc=f"{what} of {args.object} grasp {shown} of {args.robot} (batch, "
                       "fresh draws, certificate)", total=3, unit="stage")
    with executor_from(args) as executor, batch_sized():
        out = optimize(grasp, noise, samples, seed, engine=args.engine, epsilon=epsilon,
                       delta=delta, batch=batch, executor=executor, friction=friction,
                       progress=lambda stage: bar.update(1))
    bar.close()
    return out


def twice_samples(need: int) -> str:
    """:func:`batch_sized`'s hint where the batch is twice ``--samples`` (``reproduce fig10
    --method reweight``)."""
    return f"give --samples {-(-need // 2)} or more (the batch is twice --samples)"


@contextmanager
def batch_sized(hint=lambda need: f"give --batch {need} or more (default: twice --samples)"):
    """A batch too small for its targets (:class:`~kinegrasp_env.sampling.reweight.
    BatchTooSmall`, found once the reachable targets are known, before any closing) as one
    CLIError line, ended by ``hint(need)`` (the option that makes it large enough)."""
    from kinegrasp_env.sampling.reweight import BatchTooSmall

    try:
        yield
    except BatchTooSmall as err:
        raise CLIError(f"{err}: {hint(err.need)}") from None


def reweight_lines(evidence: dict, samples: int, unit: str = "angle") -> str:
    """What the batch method adds to the summary (``ReweightEvidence.to_json()``); ``unit``:
    what its points are (``angle``: elbow angles; ``branch``: IK branches, by index)."""
    points = evidence["points"]
    ess = [p["ess"] for p in points]
    fallback = evidence["fallback_angles"]
    many = "branches" if unit == "branch" else "angles"
    named = (lambda p: f"{p:.0f}") if unit == "branch" else (lambda p: f"{p:+.3f}")
    lines = [f"  one batch of {evidence['batch']} closings re-weighted to every {unit} "
             f"(effective sample size {min(ess):.0f} .. {max(ess):.0f}; "
             + (f"{plural(len(fallback), unit, many)} below {samples} topped up with direct "
                "draws: " + ", ".join(named(p) for p in fallback) if fallback
                else f"no {unit} needed direct draws") + ")",
             f"  re-weighted P(FC) at the best {'branch' if unit == 'branch' else 'elbow'} "
             f"{evidence['chosen_reweighted_p_fc']:.3f}: "
             + ("agrees with the fresh draws" if evidence["chosen_agrees_with_fresh_draws"]
                else "DISAGREES with the fresh draws beyond both sampling errors (the "
                     "linearisation may not hold here: rerun with --method direct)")]
    return "\n".join(lines)


def elbow_plot(payload: dict, result, evidence, path: str, title: str) -> None:
    """``--plot``: P(FC) along the self-motion, with the fragile directions and both elbows'
    ellipses where a re-weighted run's batch has failing draws."""
    picture = None if evidence is None else evidence.picture()
    if picture is not None:
        from kinegrasp_env.toolkit.elbow_plots import plot_elbow_fragility

        plot_elbow_fragility(payload["curve"], result.nominal_psi, result.best_psi, picture,
                             path, title=f"{title}, and why")
    else:
        from kinegrasp_env.toolkit.elbow_plots import plot_elbow_curve

        if evidence is not None:  # a batch without a failing closing: no fragile direction
            title += "\n(no closing of the batch failed: no fragile direction to draw)"
        plot_elbow_curve(payload["curve"], result.nominal_psi, result.best_psi, path,
                         title=title, source="selection draws" if evidence is None
                         else "one re-weighted batch")


def gain_line(result: dict) -> str:
    """The paired gain of the chosen variant over the nominal one on the fresh draws, with
    its t-interval (:func:`~kinegrasp_env.toolkit.selection.interval_words`)."""
    from kinegrasp_env.toolkit.selection import interval_words

    words = interval_words(result["gain"], *result["gain_ci"])
    return f"  gain over nominal {result['gain']:+.3f} ({words}, paired)"


def show_elbow(args, payload: dict, result, evidence, shown: str, samples: int,
               title: str) -> None:
    """An elbow run's output: ``--plot`` (titled ``title``), then one JSON object
    (``payload``, with the re-weighted run's ``evidence`` where there is one, and the
    ``plot`` written) or the text
    summary (naming the grasp ``shown``: :func:`grasp_shown`)."""
    import json

    if evidence is not None:
        payload["reweight"] = evidence.to_json()
    if args.plot:
        elbow_plot(payload, result, evidence, args.plot, f"{title}: P(FC) along the self-motion")
        payload["plot"] = str(args.plot)
    if args.json:
        print(json.dumps(payload))
        return
    print(text_summary(payload, shown))
    if evidence is not None:
        print(reweight_lines(payload["reweight"], samples))
    if args.plot:
        print(f"  plot written to {args.plot}")


def text_summary(result: dict, shown: str) -> str:
    """The console summary of an elbow optimization (``ElbowResult.to_json()`` with the
    ``robot``)."""
    lo, hi = result["best_p_fc_ci"]
    nlo, nhi = result["nominal_p_fc_ci"]
    if "reweight" in result:
        how = (f"{len(result['curve'])} elbow angles from one batch of "
               f"{result['reweight']['batch']} closings, the best and the nominal again on "
               f"{result['samples']} fresh draws")
    else:
        how = (f"{len(result['curve'])} elbow angles x {result['samples']} draws, then again "
               f"on {result['samples']} fresh draws")
    return "\n".join([
        f"{result['object']} grasp {shown} of robot {result['robot']}, sigma = "
        f"{result['sigma']} rad, {how} ({result['engine']} engine)",
        f"  nominal elbow {result['nominal_psi']:+.3f} rad: P(FC) "
        f"{result['nominal_p_fc']:.3f} ({nlo:.3f} .. {nhi:.3f})",
        f"  best elbow    {result['best_psi']:+.3f} rad: P(FC) "
        f"{result['best_p_fc']:.3f} ({lo:.3f} .. {hi:.3f})  [fresh draws]",
        gain_line(result),
        *certificate_lines(result["certificate"], result["grid_step"])])


def certificate_lines(cert: dict, grid_step: float) -> list[str]:
    """The certificate (``Certificate.to_json()``) in words: the claim, then the verdict."""
    if cert["bound"] is None:
        return [f"  {cert['statement']}"]
    verdict = (f"certified at epsilon {cert['epsilon']:g}" if cert["certified"] else
               f"not certified at epsilon {cert['epsilon']:g} (psi = {cert['worst_psi']:+.3f} "
               "rad is the rival it cannot rule out)")
    return [f"  {cert['statement']}",
            f"    {verdict}; {plural(len(cert['rivals']), 'other angle')}, "
            f"{bounds_words(cert)}; angles between the {grid_step:.3f} rad grid points not "
            "covered"]


def bounds_words(cert: dict) -> str:
    """How a certificate (``Certificate.to_json()``) bounds its rivals, in words: exact
    binomial bounds on fresh draws, or a re-weighted batch's method and closings."""
    from kinegrasp_env.toolkit.elbow_certificate import METHOD

    if cert["method"] == METHOD:
        return f"exact one-sided binomial bounds on {cert['fresh_draws']} fresh draws"
    return f"{cert['method']} ({cert['fresh_draws']} closings)"
