"""The ``rank`` command: candidates (grasp files or palm-pose candidates) ranked by
robustness on common draws, fixed-n or adaptive with its certificate, resumable, written as a
CSV with the rejected candidates beside it."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from kinegrasp_env.cli.common import (
    NUM_EDGES,
    CLIError,
    certificate_levels,
    engine_name,
    friction_from,
    noise_from,
    plural,
    positive_int,
    reported,
)
from kinegrasp_env.cli.execution_options import check_execution, executor_from
from kinegrasp_env.cli.output_paths import (
    CSV_SUFFIXES,
    input_files,
    output_file,
    report_path,
)
from kinegrasp_env.cli.ranking_draws import check_candidates
from kinegrasp_env.cli.ranking_table import write_ranking, write_rejected
from kinegrasp_env.robot.default import DEFAULT_ROBOT

if TYPE_CHECKING:
    from kinegrasp_env.toolkit.ranking import CandidateResult


CHUNK = 250
#: ``rank``'s noise sampler: fixed, but recorded in the resume log with every other setting.
METHOD = "mc"


def best_elbows(grasps: list, robot: str, noise, samples: int, seed: int, engine: str,
                executor, friction: float = 0.5) -> list:
    """Each candidate moved to its most robust elbow angle (7 joints: the self-motion) or IK
    branch (6 joints) (``kinegrasp elbow``'s optimizer, by ``engine``; the fast one for the
    physics engine), chosen on draws of seed + 1, so the ranking's own draws (seed) stay
    independent of the choice. The angle (radians) or branch index chosen is in the moved
    grasp's ``meta`` (:data:`~kinegrasp_env.cli.ranking_table.ELBOW_COLUMNS`)."""
    from kinegrasp_env.progress_bar import progress_bar
    from kinegrasp_env.toolkit.elbow_search import optimize_variants

    kinematic = elbow_engine(engine)
    moved = []
    for grasp in progress_bar(grasps, desc="best elbow per candidate", unit="candidate"):
        with reported(ValueError):  # an arm without self-motion or branches
            best, branches = optimize_variants(grasp, noise, samples, seed + 1,
                                               friction=friction, evaluate_with=kinematic,
                                               executor=executor)
        chosen = ({"ik_branch": int(best.best_psi)} if branches
                  else {"elbow_angle": float(best.best_psi)})
        meta = {**grasp.meta, **chosen}
        moved.append(dataclasses.replace(grasp, q0=best.best_q, meta=meta))  # its own id
    return moved


def elbow_engine(engine: str) -> str:
    """The engine ``--best-elbow`` chooses with under the ranking's ``engine``: that one, or
    the fast one for the physics engine."""
    return "fast" if engine == "physics" else engine


def _merge_side(result: CandidateResult, side: dict[int, CandidateResult]) -> None:
    """A candidate's draws per outcome and hold scores from ``side`` where it has none yet
    (a resumed candidate has them from the log)."""
    if result.index in side:
        result.outcomes = result.outcomes or dict(side[result.index].outcomes)
        result.holds = result.holds or dict(side[result.index].holds)
        result.margins = result.margins if result.margins[1] else side[result.index].margins


def _hold_scores(args) -> tuple[bool, bool]:
    """(static hold check, quick holding test) a ranking runs."""
    from kinegrasp_env.toolkit.ranking import HOLD_TEST_CRITERIA

    static = bool(args.static_hold) or args.criterion == "hold_static"
    return static, args.criterion in HOLD_TEST_CRITERIA


def _more_settings(args, noise, engine: str, test: bool, best_elbow: int) -> dict:
    """The resume settings a run has beside every run's: the physics model where physics
    runs (results of another version's physics do not resume), the holding test's simulator
    (its log carries each candidate's margins), a noise spec's whole model, the best-elbow
    search's draws and engine (a different candidate set)."""
    settings = {}
    if engine == "physics" or test:
        from kinegrasp_env.physics.simulators import PHYSICS_MODEL

        settings["physics_model"] = PHYSICS_MODEL
    if test:
        settings["hold_simulator"] = args.hold_simulator
        settings["hold_margins"] = True
    if args.noise_spec:
        from kinegrasp_env.sampling.noise_spec import spec_of

        settings["noise_model"] = spec_of(noise)
    if args.best_elbow:
        settings["best_elbow_samples"] = best_elbow
        settings["best_elbow_engine"] = elbow_engine(engine)
    return settings


def _adaptive_top_k(args, candidates: int, top_k: int, given: bool, partial: Path) -> int:
    """``--adaptive``'s top-set size for ``candidates`` candidates: ``--top-k`` where
    ``given``, else as many as the candidates allow (``args.top_k`` set to it, as the page's
    command and settings name it); CLIError lines for fewer than 2 candidates, a top set as
    large as them, or a fixed-n log at ``partial``, which it cannot resume."""
    if candidates < 2:
        raise CLIError(f"--adaptive separates a top set from the rest: it needs 2 candidates "
                       f"at least, got {candidates}")
    if not given:
        top_k = min(top_k, candidates - 1)
        args.top_k = str(top_k)
    if top_k >= candidates:
        raise CLIError(f"--top-k must be below the number of candidates ({candidates})")
    if partial.exists():
        raise CLIError(f"{partial} holds an interrupted fixed-n ranking, which --adaptive "
                       "cannot resume; delete it, or resume without --adaptive")
    return top_k


def cmd_rank(args) -> int:
    from kinegrasp_env.cli import resume
    from kinegrasp_env.cli.ranking_draws import RankingDraws
    from kinegrasp_env.cli.report import write_rank_report
    from kinegrasp_env.montecarlo import grasp_stats
    from kinegrasp_env.sampling.noise_model import DRAW_LAYOUT
    from kinegrasp_env.toolkit.ranking import CRITERIA, MEAN_CRITERIA

    if args.adaptive and args.criterion in MEAN_CRITERIA:
        *counted, last = (c for c in CRITERIA if c not in MEAN_CRITERIA)
        raise CLIError(f"--criterion {args.criterion} ranks by a mean, which --adaptive cannot "
                       f"certify (its tests count the draws that succeed); use --criterion "
                       f"{', '.join(counted)} or {last} with --adaptive, or {args.criterion} "
                       "without it")
    top_k_given = args.top_k is not None
    _adaptive_defaults(args)
    check_execution(args)  # the options, before the candidates are solved
    best_elbow = positive_int(args.best_elbow, "--best-elbow") if args.best_elbow else 0
    top_k = positive_int(args.top_k, "--top-k") if args.adaptive else 0
    noise, sigma, samples, seed = noise_from(args)
    static, test = _hold_scores(args)
    friction = friction_from(args, noise, simulated=args.engine == "physics" or test)
    out = output_file(args.out, "--out", inputs=input_files(args), suffixes=CSV_SUFFIXES)
    report_path(args.report, inputs=input_files(args))
    grasps, digest, rejected = _candidates(args.candidates, args.robot, friction)
    engine = engine_name(args.engine)
    robot = args.robot or (grasps[0].robot if grasps else DEFAULT_ROBOT)
    check_candidates(args, grasps, robot, noise)
    chunk = min(CHUNK, samples)
    layout = grasp_stats.chunk_sizes(samples, chunk)
    # each candidate's draws per outcome and hold scores, beside what the ranking keeps
    side: dict[int, CandidateResult] = {}
    partial = out.with_name(out.name + ".partial.jsonl")
    settings = {"candidates_sha256": digest, "engine": engine, "friction": friction,
                "num_edges": NUM_EDGES, "noise": noise.kind, "sigma": sigma, "method": METHOD,
                "samples": samples, "chunk": chunk, "seed": seed, "draw_layout": DRAW_LAYOUT,
                "robot": robot,  # the draws: rows addressed in the seed's streams
                "criterion_scores": [static, test],  # the hold scores a log carries
                **_more_settings(args, noise, engine, test, best_elbow)}
    certify = _certify_settings(args) if args.adaptive else {}
    if args.adaptive:
        top_k = _adaptive_top_k(args, len(grasps), top_k, top_k_given, partial)
    with executor_from(args) as executor:
        if args.best_elbow:
            if not args.adaptive:  # an old log of other settings refused before the search
                resume.read_log(partial, settings, len(grasps))
            grasps = best_elbows(grasps, robot, noise, settings["best_elbow_samples"], seed,
                                 engine, executor, friction)
        done = {}
        if not args.adaptive:
            existed = partial.exists()
            done = resume.resume(partial, settings, len(grasps))
            if existed:
                print(f"resuming: {len(done)} of {len(grasps)} candidates already ranked in "
                      f"{partial}", file=sys.stderr)
        ranking = RankingDraws(
            grasps, robot, sigma=sigma, noise=noise.kind, seed=seed, engine=engine,
            friction=friction, static_hold=static, hold_test=test, layout=layout,
            executor=executor, side=side, model=noise if args.noise_spec else None,
            hold_simulator=args.hold_simulator, criterion=args.criterion)
        try:
            results, adaptive = _rank(args, grasps, ranking, layout, chunk, top_k, partial,
                                      done, certify, side)
            nominal = [ranking.nominal(i) for i in range(len(grasps))]
        finally:
            ranking.close()
    for r in results:  # resumed candidates carry theirs from the log
        _merge_side(r, side)
    grasps = [dataclasses.replace(g, q_nominal=q) for g, q in zip(grasps, nominal, strict=True)]
    write_ranking(grasps, results, out, partial, engine, adaptive, as_json=args.json,
                  hold_simulator=args.hold_simulator, rejected=rejected,
                  moved=bool(args.best_elbow))
    write_rejected(rejected, out, args.json)
    if args.report:
        write_rank_report(args, grasps, results, robot, noise=noise, samples=samples,
                          seed=seed, engine=engine, friction=friction, adaptive=adaptive)
    return 0


def _candidates(path: str, robot: str | None = None,
                friction: float = 0.5) -> tuple[list, str, list]:
    """The candidate grasps of ``rank``, the SHA-256 of their file and the rejected
    candidates (none but for a palm-pose file); refuses a file with no grasps or with
    repeated ids (the CSV is keyed by id, whatever the grasp's object). A palm-pose file
    (``kinegrasp_env.toolkit.candidates``) is solved to grasps first, for its robot or
    ``robot`` (``--robot``); its rejected candidates go to stderr and, once the ranking is
    written, to ``<out>.rejected.csv``."""
    from kinegrasp_env.world.grasps import check_unique_ids, load_grasps

    if Path(path).is_dir():
        raise CLIError(f"{path} is a folder, not a grasp file")
    from kinegrasp_env.toolkit.candidates import is_candidate_file

    if is_candidate_file(path):
        return _palm_pose_candidates(path, robot, friction)
    with reported(ValueError):  # load_grasps: missing file, bad JSON, bad fields
        grasps = load_grasps(path)
    if not grasps:
        raise CLIError(f"{path}: the file holds no grasps")
    with reported(ValueError):  # the ranking is keyed by id, whatever the object
        check_unique_ids([g.id for g in grasps], path, "grasps")
    return grasps, hashlib.sha256(Path(path).read_bytes()).hexdigest(), []


def _palm_pose_candidates(path: str, robot: str | None = None,
                          friction: float = 0.5) -> tuple[list, str, list]:
    """``_candidates`` for a palm-pose file: (grasps of the accepted candidates, SHA-256,
    rejected candidates); each rejected one is a line on stderr, and so is each accepted one
    whose nominal closing is not in force closure (ranked all the same)."""
    from kinegrasp_env.cli.grasp_choice import read_palm_poses, solve_candidates

    read = read_palm_poses(path, robot)
    grasps, rejected = solve_candidates(read, read.candidates, path, friction=friction)
    for g in grasps:
        if g.meta.get("nominal_force_closure") is False:
            how = g.meta.get("nominal_outcome", "no_force_closure").replace("_", " ")
            print(f"candidate {g.id}: its nominal closing is not in force closure ({how}, "
                  "Q = 0); ranked all the same", file=sys.stderr)
    if not grasps:
        raise CLIError(f"{path}: none of the {len(read.candidates)} candidates is reachable, "
                       "clear and closing; nothing ranked")
    return grasps, hashlib.sha256(Path(path).read_bytes()).hexdigest(), rejected


#: What ``rank --adaptive`` certifies unless told otherwise: the top set's size, the
#: indifference zone (the default is toolkit.adaptive_ranking.DEFAULT_EPSILON, tested; the
#: parser is built without NumPy) and the error level; the parser's help names them.
ADAPTIVE_DEFAULTS = {"top_k": "3", "epsilon": "0.01", "delta": "0.05"}


def _adaptive_defaults(args) -> None:
    """Refuse ``--top-k``, ``--epsilon`` or ``--delta`` without ``--adaptive`` (a fixed-n
    ranking certifies nothing), else fill in those not given."""
    given = [f"--{name.replace('_', '-')}" for name in ADAPTIVE_DEFAULTS
             if getattr(args, name) is not None]
    if given and not args.adaptive:
        raise CLIError(f"{' and '.join(given)} set{'s' if len(given) == 1 else ''} what "
                       "--adaptive certifies: add --adaptive, or leave "
                       f"{'it' if len(given) == 1 else 'them'} out")
    for name, default in ADAPTIVE_DEFAULTS.items():
        if getattr(args, name) is None:
            setattr(args, name, default)


def _certify_settings(args) -> dict:
    """``--delta`` in (0, 1) and ``--epsilon`` in [0, 1) of ``rank --adaptive``
    (:func:`~kinegrasp_env.cli.common.certificate_levels`)."""
    epsilon, delta = certificate_levels(args)
    return {"delta": delta, "epsilon": epsilon}


def _rank(args, grasps, evaluator, layout, chunk, top_k, partial: Path,
          done: dict[int, CandidateResult], certify: dict,
          side: dict[int, CandidateResult]) -> tuple[list, object]:
    """Fixed-n (``done``: candidates read back from ``partial``; each one finished now is
    appended to it, with its draws per outcome and hold scores from ``side``) or adaptive
    ranking (``certify``: its delta and epsilon): (the results in the order to show, the
    adaptive run's report or None)."""
    from kinegrasp_env.cli import resume
    from kinegrasp_env.progress_bar import progress_bar
    from kinegrasp_env.toolkit.ranking import CandidateResult, order, rank_fixed

    if args.adaptive:
        report = _rank_adaptive(grasps, evaluator, layout, chunk, top_k, args.criterion,
                                side=side, **certify)
        return report.results, report
    bar = progress_bar(total=len(grasps), desc="ranking", unit="grasp")
    with partial.open("a") as log:

        def record(index: int) -> None:
            bar.update(1)
            if index in done:
                return
            log.write(json.dumps(resume.result_to_json(results_so_far[index])) + "\n")
            log.flush()

        results_so_far: dict[int, CandidateResult] = {}

        def tracked(index: int, first: int, count: int):
            value = evaluator(index, first, count)
            result = CandidateResult(index)
            result.add(*value, count)
            _merge_side(result, side)
            results_so_far[index] = result
            return value

        results = rank_fixed(len(grasps), tracked, len(layout), progress=record, done=done)
        for r in results:  # the hold scores order the ranking too
            _merge_side(r, side)
        results = order(results, args.criterion)
    bar.close()
    return results, None


def _rank_adaptive(grasps, evaluator, layout, chunk, top_k, criterion: str, *,
                   delta: float, epsilon: float, side: dict):
    """Adaptive ranking under one overall progress report (a bar that advances with every
    chunk drawn, or a line per round off a terminal); the summary comes after the bar. A
    hold criterion certifies the hold score (the draws' successes are their holds); each
    result's P(FC) and hold scores come back from ``side``'s tallies."""
    from kinegrasp_env.toolkit.adaptive_ranking import (
        CERTIFIED_HOLDS,
        AdaptiveProgress,
        rank_adaptive,
    )
    from kinegrasp_env.toolkit.progress import Progress

    with Progress("rank", len(grasps) * sum(layout), len(layout), word="round") as bar:
        def update(state: AdaptiveProgress) -> None:
            bar.advance(state.draws, state.bound)
            if state.round_done:
                bar.cell_done(f"{state.undecided} of {len(grasps)} candidates undecided")

        paired = functools.partial(evaluator, outcomes=True)
        held = criterion in CERTIFIED_HOLDS  # the draws' successes are holds: order by them
        report = rank_adaptive(len(grasps), paired, len(layout), chunk, top_k=top_k,
                               delta=delta, epsilon=epsilon,
                               criterion="pfc" if held else criterion, progress=update,
                               measure=CERTIFIED_HOLDS.get(criterion, "P(FC)"),
                               budget=sum(layout))
    if held:  # each result's P(FC) and hold scores from the draws' tallies
        for r in report.results:
            r.successes = side[r.index].outcomes.get("force_closure", 0)
            r.holds = dict(side[r.index].holds)
            r.margins = side[r.index].margins
    print(f"adaptive: {report.draws} draws against {report.fixed_draws} for fixed n "
          f"({report.draws / report.fixed_draws:.0%}); top {top_k} by {report.measure} "
          f"{'certified' if report.separated else 'NOT certified'} (delta {delta:g}, epsilon "
          f"{epsilon:g}) after {plural(report.rounds, 'round')}", file=sys.stderr)
    return report
