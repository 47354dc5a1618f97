"""``rank``'s output: the ranking as a CSV (atomically) and a console table or one JSON
object, the rejected palm-pose candidates beside it, and what an adaptive run certified."""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from kinegrasp_env.cli.common import plural

if TYPE_CHECKING:
    from kinegrasp_env.toolkit.ranking import CandidateResult

CSV_COLUMNS = ("id", "p_fc", "p_fc_lo", "p_fc_hi", "q_mean", "q_std", "q_skew", "q_nominal",
               "error", "samples", "engine")
#: The draws per outcome, after :data:`CSV_COLUMNS`; equal to ``montecarlo.draws.OUTCOMES``
#: (tested), copied so that building the parser stays cheap.
OUTCOME_COLUMNS = ("start_collision", "missed", "no_force_closure", "force_closure")
#: After the outcome counts: 1 where the candidate's nominal closing is in force closure
#: (its nominal Q above 0), 0 where it is not (ranked all the same, flagged).
NOMINAL_COLUMN = "nominal_fc"
#: The hold scores' columns (``toolkit.ranking.HOLD_SCORES`` -> (CSV column, table header));
#: each CSV column comes with its ``_lo`` and ``_hi`` interval ends.
HOLD_COLUMNS = {"static": ("p_hold_static", "P(stat)"), "test": ("p_hold", "P(hold)")}
#: With the quick holding test: the mean of its margins (CSV column, table header), after
#: the hold columns.
MARGIN_COLUMN = ("hold_margin", "margin")
#: With ``--best-elbow``: the elbow angle (radians; 7-joint arms) or IK branch (6-joint
#: arms) each candidate was moved to, from its grasp's ``meta``, after the hold columns.
ELBOW_COLUMNS = ("elbow_angle", "ik_branch")
_ELBOW_HEADERS = {"elbow_angle": "elbow", "ik_branch": "branch"}
#: What each hold score is, printed under the table.
HOLD_NOTES = {
    "static": "P(stat): the static hold check (the contacts carry the object's weight in six "
              "gravity directions and the lift within the hand's effort limits)",
    "test": "P(hold): the quick holding test in {simulator} (the hand closed on the object under "
            "dynamics, six gravity directions and the lift; it agrees with the full test on "
            "most draws: benchmarks/quick_hold.py); margin: the mean over the draws of how far "
            "each got through it, in [0, 1] (the phases held in a row, then how little the "
            "object moved; every draw that held above every other)"}

def _fmt(value: float) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else \
        f"{value:.6g}"


def _fixed(value: float) -> str:
    """Five decimals for the console table ('-' where undefined)."""
    return "-" if value is None or math.isnan(value) else f"{value:.5f}"


def write_rejected(rejected: list, out: Path, quiet: bool = False) -> None:
    """``<out>.rejected.csv``: id, reason, detail of each rejected palm-pose candidate (an
    older one is removed when there are none); the line saying so on stderr when ``quiet``
    (stdout holds JSON)."""
    from kinegrasp_env.atomic_files import write_atomic

    path = out.with_name(out.name + ".rejected.csv")
    if not rejected:
        if path.exists():
            path.unlink()
        return
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(("id", "reason", "detail"))
    writer.writerows((r.id, r.reason, r.detail) for r in rejected)
    write_atomic(path, buffer.getvalue())
    print(f"{plural(len(rejected), 'rejected candidate')} written to {path}",
          file=sys.stderr if quiet else sys.stdout)


def _elbow(value, digits: int = 6) -> str:
    """An :data:`ELBOW_COLUMNS` value: the angle to ``digits`` decimals of a radian (the CSV
    6, the console table 3), the branch index, or empty."""
    if value is None:
        return ""
    return str(value) if isinstance(value, int) else f"{value:.{digits}f}"


def _ordinal(k: int) -> str:
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


def certified_line(report, samples: int) -> str:
    """What an adaptive run certified, at which delta and epsilon (the line under its
    table)."""
    k, delta, eps = len(report.top), f"{report.delta:g}", f"{report.epsilon:g}"
    count = {label: report.certified.count(label) for label in ("top-k", "rest", "unresolved")}
    best = "best" if k == 1 else f"{_ordinal(k)} best"
    measure = getattr(report, "measure", "P(FC)")
    if eps == "0":
        claim = ("the most robust" if k == 1 and measure == "P(FC)"
                 else f"the best by {measure}" if k == 1 else f"in the top {k} by {measure}")
    else:
        claim = f"within {eps} of the {best} {measure}"
    rows = "the row marked top-k is" if k == 1 else f"each of the {k} rows marked top-k is"
    if report.separated:
        return (f"certified at delta {delta}, epsilon {eps}: {rows} {claim} (false with "
                f"probability <= {delta})")
    return (f"NOT certified at delta {delta}, epsilon {eps} within {samples} draws per "
            f"candidate: {plural(count['top-k'], 'row')} marked top-k (each {claim}), "
            f"{count['rest']} "
            f"rest (out of the top {k}), {count['unresolved']} unresolved")


def certificate_json(report, samples: int) -> dict:
    """What an adaptive run certified, for ``rank --json``: ``certified`` (its top k is),
    ``statement`` (:func:`certified_line`), ``measure``, ``top_k``, ``delta``, ``epsilon``,
    ``draws`` made against ``fixed_draws`` of a fixed-n run, ``rounds``."""
    return {"certified": bool(report.separated), "statement": certified_line(report, samples),
            "measure": getattr(report, "measure", "P(FC)"), "top_k": len(report.top),
            "delta": float(report.delta), "epsilon": float(report.epsilon),
            "draws": int(report.draws), "fixed_draws": int(report.fixed_draws),
            "rounds": int(report.rounds)}


def write_ranking(grasps, results: list[CandidateResult], out: Path, partial: Path,
                   engine: str, adaptive=None, as_json: bool = False,
                   hold_simulator: str = "pybullet", rejected: list = (),
                   moved: bool = False) -> None:
    """The ranking as CSV (atomically), then as a console table, or with ``as_json`` as one
    JSON object (``ranking``: the rows in rank order, NaN as null; ``written``: the CSV;
    ``rejected``: each rejected palm-pose candidate's id, reason and detail; where the
    holding test scored, ``hold_simulator``: the simulator it ran in; of an adaptive run
    ``certificate``: :func:`certificate_json`);
    ``adaptive`` (an adaptive run's report) adds the ``certified`` column and the line
    saying what it certified; ``moved`` (``--best-elbow``) adds the elbow angle or IK branch
    each candidate was moved to (:data:`ELBOW_COLUMNS`, from its grasp's ``meta``)."""
    from kinegrasp_env.atomic_files import write_atomic

    rows = []
    for r in results:
        g = grasps[r.index]
        lo, hi = r.interval()
        mean, std, skew = r.q_stats()
        row = {"id": g.id, "p_fc": r.p_fc, "p_fc_lo": lo, "p_fc_hi": hi, "q_mean": mean,
               "q_std": std, "q_skew": skew, "q_nominal": g.q_nominal,
               "error": g.q_nominal - mean if not math.isnan(mean) else math.nan,
               "samples": r.trials, "engine": engine,
               **{name: r.outcomes.get(name, 0) for name in OUTCOME_COLUMNS},
               NOMINAL_COLUMN: int(g.q_nominal > 0)}
        for score, (column, _) in HOLD_COLUMNS.items():
            row[column] = r.p_hold(score)
            row[f"{column}_lo"], row[f"{column}_hi"] = r.hold_interval(score)
        row[MARGIN_COLUMN[0]] = r.hold_margin()
        row.update({c: g.meta[c] for c in ELBOW_COLUMNS if moved and c in g.meta})
        rows.append(row)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    labels = adaptive.certified if adaptive is not None else [None] * len(rows)
    extra = ("certified",) if adaptive is not None else ()
    scores = [score for score in HOLD_COLUMNS if any(score in r.holds for r in results)]
    hold = tuple(f"{HOLD_COLUMNS[score][0]}{end}" for score in scores
                 for end in ("", "_lo", "_hi"))
    hold += (MARGIN_COLUMN[0],) if "test" in scores else ()
    elbow = tuple(c for c in ELBOW_COLUMNS if any(c in row for row in rows))
    writer.writerow(CSV_COLUMNS + OUTCOME_COLUMNS + (NOMINAL_COLUMN,) + hold + elbow + extra)
    for row, label in zip(rows, labels, strict=True):
        writer.writerow([row["id"], *(_fmt(row[c]) for c in CSV_COLUMNS[1:-2]), row["samples"],
                         row["engine"], *(row[c] for c in OUTCOME_COLUMNS), row[NOMINAL_COLUMN],
                         *(_fmt(row[c]) for c in hold), *(_elbow(row.get(c)) for c in elbow),
                         *([label] if extra else [])])
    write_atomic(out, buffer.getvalue())
    if partial.exists():
        partial.unlink()
    if as_json:
        def plain(value):
            return None if isinstance(value, float) and math.isnan(value) else value

        absent = {f"{column}{end}" for score, (column, _) in HOLD_COLUMNS.items()
                  if score not in scores for end in ("", "_lo", "_hi")}
        absent |= set() if "test" in scores else {MARGIN_COLUMN[0]}
        shown = [{"rank": i, **{k: plain(v) for k, v in row.items() if k not in absent},
                  **({"certified": label} if extra else {})}
                 for i, (row, label) in enumerate(zip(rows, labels, strict=True), 1)]
        print(json.dumps({"ranking": shown, "written": str(out),
                          "rejected": [{"id": r.id, "reason": r.reason, "detail": r.detail}
                                       for r in rejected],
                          **({"hold_simulator": hold_simulator} if "test" in scores else {}),
                          **({} if adaptive is None else {"certificate": certificate_json(
                              adaptive, max(r.trials for r in results))})}))
        return
    width = max([8, *(len(str(row["id"])) for row in rows)])
    print(f"{'rank':>4} {'id':>{width}} {'P(FC)':>7} {'95% CI':>15} {'Q mean':>9} {'Q nominal':>9} "
          f"{'draws':>6}" + "".join(f" {HOLD_COLUMNS[s][1]:>7} {'95% CI':>15}" for s in scores)
          + (f" {MARGIN_COLUMN[1]:>6}" if "test" in scores else "")
          + "".join(f" {_ELBOW_HEADERS[c]:>6}" for c in elbow)
          + (f" {'certified':>10}" if extra else ""))
    for i, (row, label) in enumerate(zip(rows, labels, strict=True), 1):
        held = "".join(f" {row[c]:>7.3f} {row[c + '_lo']:>7.3f}..{row[c + '_hi']:<6.3f}"
                       for c in (HOLD_COLUMNS[s][0] for s in scores))
        held += f" {row[MARGIN_COLUMN[0]]:>6.3f}" if "test" in scores else ""
        held += "".join(f" {_elbow(row.get(c), 3):>6}" for c in elbow)
        print(f"{i:>4} {row['id']:>{width}} {row['p_fc']:>7.3f} "
              f"{row['p_fc_lo']:>7.3f}..{row['p_fc_hi']:<6.3f} {_fixed(row['q_mean']):>9} "
              f"{row['q_nominal']:>9.5f} {row['samples']:>6}" + held
              + (f" {label:>10}" if extra else ""))
    for score in scores:
        print(HOLD_NOTES[score].format(simulator=hold_simulator))
    if adaptive is not None:
        print(certified_line(adaptive, max(r.trials for r in results)))
    print(f"written to {out}")
