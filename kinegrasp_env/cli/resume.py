"""The resume log of ``kinegrasp rank``: ``<out>.partial.jsonl``.

Line 1 is ``{"settings": {...}}``: every setting that changes a candidate's numbers (see
:data:`SETTING_LABELS`; not ``--criterion``, which only orders the finished candidates, nor
where the draws run, which changes nothing). Each further line is one finished candidate:
its index, successes, trials, chunks and the streaming moments of Q. A run with the same
settings reuses those candidates; a run with other settings is refused (one line naming the
setting), never mixed in.

Any number of interruptions: on every start the log is read, checked and written back whole
(settings, then the finished candidates in index order, through a temporary file and a
rename) before new lines are appended, so it always holds exactly one settings line, each
candidate at most once, and no cut-off line (a line cut off by a kill mid-write is dropped
and its candidate computed again).
"""

from __future__ import annotations

import json
from pathlib import Path

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.cli.common import CLIError
from kinegrasp_env.sampling.stats import StreamingMoments
from kinegrasp_env.toolkit.ranking import CandidateResult

#: The settings of a ranking that change a number, and how a message names them.
SETTING_LABELS = {
    "candidates_sha256": "candidates file content (SHA-256)",
    "engine": "--engine",
    "friction": "friction coefficient",
    "num_edges": "friction-cone edges",
    "noise": "--noise",
    "sigma": "--sigma",
    "method": "noise sampler",
    "samples": "--samples",
    "chunk": "chunk size",
    "seed": "--seed",
    "noise_model": "--noise-spec",
    "best_elbow_samples": "--best-elbow",
    "best_elbow_engine": "the engine --best-elbow chose with (a log of an older kinegrasp)",
    "robot": "robot (--robot, or the candidates'; a log of an older kinegrasp records none)",
    "criterion_scores": "hold scores (static check, holding test)",
    "hold_simulator": "--hold-simulator",
    "hold_margins": "the holding test's margins (a log of an older kinegrasp records none)",
    "draw_layout": "layout of the random draws (a log of an older kinegrasp)",
    "physics_model": "the physics simulated (a log of an older kinegrasp)",
}


def check_settings(path: Path, stored: object, settings: dict) -> None:
    """Refuse (:class:`CLIError`) a log whose settings differ from this run's ``settings``."""
    if not isinstance(stored, dict):
        raise CLIError(f"{path} is not a kinegrasp rank log (no settings line); delete it to "
                       "start over")
    for key, label in SETTING_LABELS.items():
        old = stored.get(key, "not recorded")
        new = json.loads(json.dumps(settings.get(key, "not recorded")))  # as the log has it
        if old != new:
            raise CLIError(f"{path} holds an interrupted ranking with other settings "
                           f"({label}: {_show(old)} there, {_show(new)} now); delete "
                           f"it to start over, or resume with the same settings")


def _show(value: object) -> str:
    if isinstance(value, str) and len(value) == 64:  # a SHA-256
        return value[:12]
    return json.dumps(value)


def resume(path: Path, settings: dict, n_candidates: int) -> dict[int, CandidateResult]:
    """Finished candidates of an interrupted run with the same settings, by index.

    Creates the log (settings line only) when there is none; otherwise checks it, refuses
    other settings or a damaged log, and writes it back whole (see the module docstring).
    """
    if not path.exists():
        write_atomic(path, json.dumps({"settings": settings}) + "\n")
        return {}
    done = read_log(path, settings, n_candidates)
    write_atomic(path, "".join(json.dumps(item) + "\n" for item in
                               [{"settings": settings},
                                *(result_to_json(done[i]) for i in sorted(done))]))
    return done


def read_log(path: Path, settings: dict, n_candidates: int) -> dict[int, CandidateResult]:
    """The finished candidates of the log at ``path`` (none where there is no log), by index;
    refuses (:class:`CLIError`) other settings or a damaged log. Writes nothing: a run checks
    an old log with it before work that comes ahead of the ranking."""
    if not path.exists():
        return {}
    lines = path.read_text().splitlines()
    try:
        first = json.loads(lines[0]) if lines else None
    except json.JSONDecodeError:
        first = None
    check_settings(path, first.get("settings") if isinstance(first, dict) else None, settings)
    done: dict[int, CandidateResult] = {}
    for number, line in enumerate(lines[1:], 2):
        try:
            result = result_from_json(json.loads(line))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError):
            if number == len(lines):  # cut off by a kill while it was written
                break
            raise CLIError(f"{path} line {number} is damaged; delete the file to start "
                           "over") from None
        if not 0 <= result.index < n_candidates or result.index in done:
            raise CLIError(f"{path} line {number}: candidate {result.index} is out of range "
                           "or repeated; delete the file to start over")
        done[result.index] = result
    return done


def result_to_json(result: CandidateResult) -> dict:
    """One log line (a dict) for a finished candidate."""
    m = result.moments
    moments = None if m is None else {"n": m.n, "mean": m.mean.tolist(), "m2": m.m2.tolist(),
                                      "m3": m.m3.tolist()}
    return {"index": result.index, "successes": result.successes, "trials": result.trials,
            "chunks": result.chunks, "moments": moments, "outcomes": result.outcomes,
            "holds": {score: list(pair) for score, pair in result.holds.items()},
            "margins": list(result.margins)}


def result_from_json(item: dict) -> CandidateResult:
    """The candidate of one log line (KeyError, TypeError or ValueError if malformed)."""
    data = item["moments"]
    moments = None if data is None else StreamingMoments.from_state(
        data["n"], data["mean"], data["m2"], data["m3"])
    outcomes = {str(name): int(count) for name, count in dict(item.get("outcomes") or {}).items()}
    holds = {str(score): (int(pair[0]), int(pair[1]))
             for score, pair in dict(item.get("holds") or {}).items()}
    total, count = item.get("margins") or (0.0, 0)
    return CandidateResult(int(item["index"]), int(item["successes"]), int(item["trials"]),
                           int(item["chunks"]), moments, holds=holds, outcomes=outcomes,
                           margins=(float(total), int(count)))
