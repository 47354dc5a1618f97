"""The paper's experiments as functions that write tables and figures (Table I, ...)."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path

from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import Executor, LocalExecutor
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.progress import Progress, cell_progress
from kinegrasp_env.toolkit.selection import robust_fragile, stats_from_chunk
from kinegrasp_env.world.grasps import Grasp, shipped_grasps, write_atomic
from kinegrasp_env.world.objects import OBJECT_NAMES

#: Table I's CSV columns; new columns go at the end (readers by position keep working).
TABLE1_COLUMNS = ("grasp", "sigma", "q_nominal", "q_mean", "q_var", "p_fc", "p_fc_lo", "p_fc_hi",
                  "samples", "q_skew")


def _fmt(value: float, digits: int = 4) -> str:
    return "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else \
        f"{value:.{digits}g}"


def _cell_text(row: dict) -> str:
    """mean / var / skew / P(FC) [lo, hi] of one Table I cell."""
    interval = ""
    if row.get("p_fc_lo") is not None and row.get("p_fc_hi") is not None:
        interval = f" [{row['p_fc_lo']:.3f}, {row['p_fc_hi']:.3f}]"
    return (f"{_fmt(row['q_mean'])} / {_fmt(row['q_var'], 3)} / "
            f"{_fmt(row.get('q_skew'), 3)} / {row['p_fc']:.3f}{interval}")


def markdown_table1(rows: list[dict], object_name: str, samples: int) -> str:
    """Table I as markdown: per grasp and sigma (radians), mean / variance / skewness of Q
    over the force-closure draws and P(FC) with its Wilson 95% interval."""
    sigmas = sorted({r["sigma"] for r in rows})
    head = "| grasp | Q nominal | " + " | ".join(
        f"sigma = {s:g} rad: mean / var / skew / P(FC) [95% CI]" for s in sigmas) + " |"
    lines = [f"Table I, {object_name}, {samples} draws per cell; sigma = joint noise std in "
             "radians; Q (Ferrari-Canny) moments over the force-closure draws; P(FC) with its "
             "Wilson 95% interval", "", head, "|" + "---|" * (len(sigmas) + 2)]
    for grasp in sorted({r["grasp"] for r in rows}):
        cells = {r["sigma"]: r for r in rows if r["grasp"] == grasp}
        first = next(iter(cells.values()))
        lines.append(f"| {grasp} | {_fmt(first['q_nominal'])} | "
                     + " | ".join(_cell_text(cells[s]) for s in sigmas) + " |")
    return "\n".join(lines) + "\n"


def _cell_callback(report: Progress | None):
    return False if report is None else report.evaluation()


def _cell_done(report: Progress | None, label: str, stats) -> None:
    if report is not None:
        report.cell_done(f"{label}: P(FC) {stats.p_fc:.3f}")


def _executor(executor: Executor | None, processes: int) -> AbstractContextManager[Executor]:
    """The caller's executor (left open), else a local pool for the experiment's duration."""
    return nullcontext(executor) if executor is not None else LocalExecutor(processes)


def _evaluate_set(grasps, sigma: float, samples: int, seed: int, processes: int,
                  engine: str = "pybullet", return_draws: bool = False,
                  executor: Executor | None = None, report: Progress | None = None,
                  friction: float = 0.5) -> list:
    """Evaluate ``grasps`` at ``sigma`` (friction mu ``friction``); one progress cell each."""
    stats = []
    with _executor(executor, processes) as run_on:
        for g in grasps:
            stats.append(evaluate_grasp(g, JointNoise(sigma), samples, seed, engine=engine,
                                        return_draws=return_draws, executor=run_on,
                                        progress=_cell_callback(report), friction=friction))
            _cell_done(report, f"{g.object} grasp {g.id} sigma {sigma:g}", stats[-1])
    return stats


def write_rows(out: Path, name: str, rows: list[dict],
                columns: tuple[str, ...] | None = None) -> None:
    """``rows`` as CSV ``out/name`` (atomically); columns default to the first row's keys."""
    out.mkdir(parents=True, exist_ok=True)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns or rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / name, buffer.getvalue())


def _fig7_candidates(objects: tuple[str, ...], variants: int) -> dict[str, list]:
    """Per object: shipped grasp 0 and up to ``variants`` null-space variants of it."""
    from kinegrasp_env.toolkit.planner import GraspPlanner

    candidates = {}
    for name in objects:
        grasp = shipped_grasps(name)[0]
        planner = GraspPlanner(name)
        try:
            candidates[name] = [grasp, *planner.variants(grasp, variants)]
        finally:
            planner.close()
    return candidates


def fig7(out_dir: str | Path, *, objects: tuple[str, ...] = ("drill", "spray_flask"),
         samples: int = 2000, sigma: float = 0.0133, variants: int = 8, seed: int = 0,
         processes: int = 1, engine: str = "pybullet", executor: Executor | None = None,
         progress: bool = False, friction: float = 0.5) -> list[dict]:
    """Fig. 7: the same contacts reached with two arm configurations, the most and the least
    robust of shipped grasp 0 and ``variants`` null-space variants of it: P(FC), the moments
    of Q and the scatter of contact points and normals for each.

    The two are chosen by P(FC) on ``samples`` selection draws per configuration and
    reported on ``samples`` fresh draws (:mod:`.selection`: chunks ``0..K-1`` and ``K..2K-1``
    of ``seed``), so the reported gap is not inflated by the choice. Writes ``fig7.csv``
    (:func:`~.selection.robust_fragile`'s rows), then ``fig7_<object>.png`` of the fresh
    draws (a figure that fails is a warning: the CSV stays). ``progress``: one overall
    report."""
    from kinegrasp_env.toolkit.plots import plot_contacts_pair, safe_figure
    from kinegrasp_env.world.objects import load_object

    out = Path(out_dir)
    candidates = _fig7_candidates(objects, variants)
    cells = sum(len(c) + 2 for c in candidates.values())
    rows, pairs = [], []
    with _executor(executor, processes) as run_on, \
            cell_progress(progress, "fig7", cells, samples) as report:
        for name in objects:
            stats = _evaluate_set(candidates[name], sigma, samples, seed, processes, engine,
                                  executor=run_on, report=report, friction=friction)
            chosen, fresh = robust_fragile(
                name, candidates[name], stats,
                _fresh_evaluator(sigma, samples, seed, engine, run_on, report, friction),
                samples, seed)
            rows += [{**row, "sigma": sigma} for row in chosen]
            pairs.append((name, [(row, s) for row, s in zip(chosen, fresh, strict=True)]))
    write_rows(out, "fig7.csv", rows)
    for name, pair in pairs:
        path = out / f"fig7_{name}.png"
        safe_figure(lambda name=name, pair=pair, path=path: plot_contacts_pair(
            load_object(name).mesh, [s.draws for _, s in pair],
            [f"elbow {row['elbow_angle'] or 0:.2f} rad: P(FC) = {s.p_fc:.3f}"
             for row, s in pair], path,
            title=f"{name}: same contacts, two arm configurations, sigma = {sigma:g} "
                  f"(fresh draws)"), path)
    return rows


def _fresh_evaluator(sigma: float, samples: int, seed: int, engine: str, executor: Executor,
                     report: Progress | None, friction: float = 0.5):
    """:data:`~.selection.Evaluator` of the fresh draws, one progress cell each."""
    def evaluate(grasp: Grasp, first_chunk: int):
        stats = stats_from_chunk(grasp, JointNoise(sigma), samples, seed, first_chunk,
                                 engine=engine, executor=executor, friction=friction,
                                 progress=_cell_callback(report))
        _cell_done(report, f"{grasp.object} grasp {grasp.id} sigma {sigma:g} (fresh draws)",
                   stats)
        return stats
    return evaluate


def variant_sets(objects: Sequence[str], count: int,
                 grasp_sets: Mapping[str, Sequence[Grasp]]) -> dict[str, list[Grasp]]:
    """Per object, the grasps fig10 evaluates: ``count`` null-space variants of the first
    grasp of its set (``grasp_sets[name]``, else its shipped set), by the default planner."""
    from kinegrasp_env.toolkit.planner import GraspPlanner

    sets = {}
    for name in objects:
        base = list(grasp_sets[name]) if name in grasp_sets else shipped_grasps(name)
        if not base:
            raise ValueError(f"the grasp set of {name} is empty")
        planner = GraspPlanner(name)
        try:
            sets[name] = planner.variants(base[0], count)
        finally:
            planner.close()
    return sets


def fig10(out_dir: str | Path, *, samples: int = 1000, sigma: float = 0.0033,
          count: int = 10, seed: int = 0, processes: int = 1,
          engine: str = "pybullet", executor: Executor | None = None,
          progress: bool = False, objects: Sequence[str] = OBJECT_NAMES,
          grasp_sets: Mapping[str, Sequence[Grasp]] | None = None,
          method: str = "direct", friction: float = 0.5) -> list[dict]:
    """Fig. 10 of the default robot: success rate, mean quality (with its std) and the error
    (nominal - mean) of ``count`` null-space variants of each object's first grasp (same
    contacts, different arms: :func:`variant_sets`) at ``sigma``. An object's set is
    ``grasp_sets[name]`` if given (how an imported object, which has no shipped set, is
    drawn), else its shipped set. Writes ``fig10.csv``, then ``fig10.png`` (a figure that
    fails is a warning: the CSV stays). ``progress``: one overall report. (Fig. 9, and every
    other robot's Fig. 10: :mod:`~kinegrasp_env.toolkit.robot_tables`,
    :mod:`~kinegrasp_env.toolkit.robot_reproduce`.)

    Each variant's row is its estimate on ``samples`` draws (chunks ``0..K-1`` of ``seed``);
    per object of two variants or more, the most and the least robust variant (``config``
    robust / fragile, empty for the others) are chosen on those draws and reported on fresh
    ones (:mod:`.selection`): their rows carry ``fresh_p_fc`` with its interval,
    ``fresh_samples`` and the paired ``gap`` (robust - fragile) on the fresh draws.

    ``method`` ``reweight``: each object's variants from one batch of closings
    (:func:`~kinegrasp_env.toolkit.batch_stats.variant_stats`; ``samples`` then reads as
    each row's effective sample size); the robust and fragile pair is still reported on
    fresh direct draws.

    Raises:
        NoGraspSetError: an imported object without a grasp set.
        ValueError: an unknown method.
    """
    from kinegrasp_env.toolkit.plots import plot_success_quality, safe_figure

    if method not in ("direct", "reweight"):
        raise ValueError(f"unknown method {method!r}: direct or reweight")
    out = Path(out_dir)
    sets = variant_sets(objects, count, grasp_sets or {})
    rows = []
    chooses = {name: len(g) >= 2 for name, g in sets.items()}
    cells = sum(len(g) + 2 * chooses[name] for name, g in sets.items())
    with _executor(executor, processes) as run_on, \
            cell_progress(progress, "fig10", cells, samples) as report:
        for name, grasps in sets.items():
            if method == "reweight":
                from kinegrasp_env.toolkit.batch_stats import variant_stats

                stats = variant_stats(list(grasps), sigma, samples, seed, engine=engine,
                                      executor=run_on, friction=friction)
                for g, s in zip(grasps, stats, strict=True):
                    _cell_done(report, f"{g.object} grasp {g.id} sigma {sigma:g}", s)
            else:
                stats = _evaluate_set(grasps, sigma, samples, seed, processes, engine,
                                      executor=run_on, report=report, friction=friction)
            block = [{"object": name, "id": g.id, "p_fc": s.p_fc, "q_mean": s.q_mean,
                      "q_std": s.q_std, "q_nominal": s.q_nominal, "error": s.error,
                      "samples": s.samples, "sigma": sigma}
                     for g, s in zip(grasps, stats, strict=True)]
            _mark_pair(block, name, grasps, stats, chooses[name],
                       _fresh_evaluator(sigma, samples, seed, engine, run_on, report,
                                        friction), samples, seed)
            rows += block
    write_rows(out, "fig10.csv", rows)
    safe_figure(lambda: plot_success_quality(
        rows, out / "fig10.png",
        title=f"fig10: sigma = {sigma:g}, {samples} draws per grasp"), out / "fig10.png")
    return rows


#: fig10's columns of the chosen pair (empty for the other variants).
PAIR_COLUMNS = ("config", "fresh_p_fc", "fresh_p_fc_lo", "fresh_p_fc_hi", "fresh_samples",
                "selection_p_fc", "gap", "gap_lo", "gap_hi")


def _mark_pair(block: list[dict], name: str, grasps: list[Grasp], stats: list, chooses: bool,
               evaluate, samples: int, seed: int) -> None:
    """Add :data:`PAIR_COLUMNS` to one object's fig10 rows: the robust and fragile variants
    (chosen on the rows' draws) with their fresh-draw numbers, empty elsewhere."""
    for row in block:
        row.update(dict.fromkeys(PAIR_COLUMNS, ""))
    if not chooses:
        return
    chosen, _ = robust_fragile(name, grasps, stats, evaluate, samples, seed)
    by_id = {g.id: row for g, row in zip(grasps, block, strict=True)}
    for pair_row in chosen:
        by_id[pair_row["id"]].update({
            "config": pair_row["config"], "fresh_p_fc": pair_row["p_fc"],
            "fresh_p_fc_lo": pair_row["p_fc_lo"], "fresh_p_fc_hi": pair_row["p_fc_hi"],
            "fresh_samples": pair_row["samples"], "selection_p_fc": pair_row["selection_p_fc"],
            "gap": pair_row["gap"],
            "gap_lo": pair_row["gap_lo"], "gap_hi": pair_row["gap_hi"]})
