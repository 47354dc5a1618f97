"""The paper's experiments for any robot's grasps, as functions that write tables and figures.

Every evaluation is :func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`
(joint noise on the arm joints, seed ``seed``: the draws of ``kinegrasp evaluate --robot NAME
--seed SEED``):

* **Table I**: the moments of Q over the force-closure draws and P(FC) with its Wilson 95%
  interval of the first ``grasps`` grasps of one object at each sigma (``table1.csv``,
  ``table1.md``, ``pfc_vs_sigma.png``);
* **Fig. 9**: success rate, mean Q with its standard deviation and the error (nominal - mean)
  of the first ``count`` grasps of each object at one sigma (``fig9.csv``, ``fig9.png``);
* **Fig. 7**: the same contacts reached with two arm configurations, the most and the least
  robust of ``variants`` configurations of each object's first grasp along a 7-joint arm's
  self-motion or among a 6-joint arm's IK branches (:mod:`~kinegrasp_env.toolkit.
  arm_variants`: chosen on the selection draws, reported on fresh ones with their paired
  gap), ``fig7.csv`` and the contact scatter of each pair, ``fig7_<object>.png``;
* **Fig. 10**: every one of ``count`` such configurations of each object's first grasp, and
  the robust and fragile pair among them (``fig10.csv``, ``fig10.png``).

The paper's own values (its robot's) are set beside these by ``scripts/paper_side_by_side.py``.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.montecarlo.evaluate import evaluate_grasp, make_engine
from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.endeffector import PAPER_SIGMAS
from kinegrasp_env.toolkit.arm_variants import (
    COLUMNS,
    check_variants,
    find_variants,
    variant_block,
    variant_label,
    variant_work,
)
from kinegrasp_env.toolkit.progress import cell_progress, reported_cell
from kinegrasp_env.world.grasps import Grasp

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
        lines.append(f"| {first.get('id', grasp)} | {_fmt(first['q_nominal'])} | "
                     + " | ".join(_cell_text(cells[s]) for s in sigmas) + " |")
    return "\n".join(lines) + "\n"


def write_rows(out: Path, name: str, rows: list[dict],
                columns: tuple[str, ...] | None = None) -> None:
    """``rows`` as CSV ``out/name`` (atomically); columns default to the first row's keys."""
    out.mkdir(parents=True, exist_ok=True)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns or rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / name, buffer.getvalue())


#: fig9.csv's columns (the robot and P(FC)'s Wilson 95% interval last: readers of the older
#: columns by position keep working).
FIG9_COLUMNS = ("object", "id", "p_fc", "q_mean", "q_std", "q_nominal", "error", "samples",
                "sigma", "robot", "p_fc_lo", "p_fc_hi")


def _write_success_quality(out_dir: str | Path, name: str, rows: list[dict],
                           columns: tuple[str, ...], title: str) -> None:
    """``<name>.csv`` of ``rows`` and the success-rate and quality plot ``<name>.png`` (a
    figure that fails is a warning: the CSV stays)."""
    from kinegrasp_env.toolkit.plots import plot_success_quality, safe_figure

    out = Path(out_dir)
    write_rows(out, f"{name}.csv", rows, columns)
    safe_figure(lambda: plot_success_quality(rows, out / f"{name}.png",
                                             title=f"{name}, {title}"), out / f"{name}.png")


def _cell(grasp: Grasp, sigma: float, samples: int, seed: int, runner, executor,
          report, label: str):
    """One cell's :func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp` on
    ``runner``'s engine, reported to ``report`` (a :class:`~kinegrasp_env.toolkit.progress.
    Progress`, or None: :func:`~kinegrasp_env.toolkit.progress.reported_cell`)."""
    return reported_cell(report, samples, label, lambda progress: evaluate_grasp(
        grasp, sigma=sigma, n=samples, seed=seed, engine=runner, executor=executor,
        progress=progress, keep_draws=False))


def table1(description: RobotDescription, object_name: str, grasps: Sequence[Grasp],
                 samples: int, out_dir: str | Path, *,
                 sigmas: tuple[float, ...] = PAPER_SIGMAS, seed: int = 0,
                 engine: str = "pybullet", friction: float = 0.5,
                 executor: Executor | None = None, progress: bool = False) -> list[dict]:
    """Table I of ``grasps`` (grasps of ``description`` on ``object_name``; a row's ``grasp``
    is its index among them, its ``id`` the grasp's id, which the table and the figure show)
    at each sigma (radians); writes the module's files.
    ``executor``: each evaluation's draws in chunks on it (the same draws, row for row);
    ``progress``: a line per cell on stderr, or a bar on a terminal that moves as the
    chunks of a run on ``executor`` come back (:class:`~kinegrasp_env.toolkit.progress.
    Progress`)."""
    from kinegrasp_env.toolkit.plots import plot_pfc_vs_sigma, safe_figure

    rows = []
    cells = len(grasps) * len(sigmas)
    with make_engine(engine, description, object_name, friction=friction) as runner, \
            cell_progress(progress, "table1", cells, samples) as report:
        for index, grasp in enumerate(grasps):
            for sigma in sigmas:
                stats = _cell(grasp, sigma, samples, seed, runner, executor, report,
                              f"{object_name} grasp {grasp.id} sigma {sigma:g}")
                rows.append({"grasp": index, "sigma": sigma, "q_nominal": stats.q_nominal,
                             "q_mean": stats.q_mean, "q_var": stats.q_std ** 2,
                             "p_fc": stats.p_fc, "p_fc_lo": stats.ci[0],
                             "p_fc_hi": stats.ci[1], "samples": samples,
                             "q_skew": stats.q_skew, "id": str(grasp.id)})
    out = Path(out_dir)
    title = f"{object_name} (robot {description.name})"
    write_rows(out, "table1.csv", [{**r, "robot": description.name} for r in rows],
               (*TABLE1_COLUMNS, "robot", "id"))
    write_atomic(out / "table1.md", markdown_table1(rows, title, samples))
    safe_figure(lambda: plot_pfc_vs_sigma(rows, out / "pfc_vs_sigma.png",
                                          title=f"{title}: P(FC) vs noise"),
                out / "pfc_vs_sigma.png")
    return rows


def fig9(description: RobotDescription, out_dir: str | Path, *,
               grasp_sets: Mapping[str, Sequence[Grasp]], samples: int = 1000,
               sigma: float = 0.0033, count: int = 10, seed: int = 0,
               engine: str = "pybullet", friction: float = 0.5,
               executor: Executor | None = None, progress: bool = False) -> list[dict]:
    """Fig. 9 of the first ``count`` grasps of each object of ``grasp_sets``; writes
    ``fig9.csv`` (:data:`FIG9_COLUMNS`) and ``fig9.png``; ``executor`` and ``progress`` as
    :func:`table1`'s."""

    rows = []
    cells = sum(len(list(grasps)[:count]) for grasps in grasp_sets.values())
    with cell_progress(progress, "fig9", cells, samples) as report:
        for name, grasps in grasp_sets.items():
            with make_engine(engine, description, name, friction=friction) as runner:
                for grasp in list(grasps)[:count]:
                    s = _cell(grasp, sigma, samples, seed, runner, executor, report,
                              f"{name} grasp {grasp.id}")
                    rows.append({"robot": description.name, "object": name, "id": grasp.id,
                                 "p_fc": s.p_fc, "p_fc_lo": s.ci[0], "p_fc_hi": s.ci[1],
                                 "q_mean": s.q_mean, "q_std": s.q_std,
                                 "q_nominal": s.q_nominal, "error": s.q_nominal - s.q_mean,
                                 "samples": samples, "sigma": sigma})
    _write_success_quality(out_dir, "fig9", rows, FIG9_COLUMNS,
                           f"robot {description.name}: sigma = {sigma:g}, {samples} draws "
                           "per grasp")
    return rows


def _variant_sets(description: RobotDescription, grasp_sets: Mapping[str, Sequence[Grasp]],
                  count: int, friction: float) -> dict[str, list[Grasp]]:
    """Per object of ``grasp_sets``: up to ``count`` configuration variants of its first grasp
    (:func:`~kinegrasp_env.toolkit.arm_variants.find_variants`, at friction mu
    ``friction``; named apart from the set's own grasps, a grasp file's variants among
    them)."""
    return {name: find_variants(description, name, grasps[0], count, friction,
                                {g.id for g in grasps})
            for name, grasps in grasp_sets.items()}


def _variant_progress(enabled: bool, name: str, sets: Mapping[str, list[Grasp]],
                      samples: int, method: str = "direct"):
    """The progress report of fig7 or fig10 over ``sets``' variants
    (:func:`~kinegrasp_env.toolkit.arm_variants.variant_work`)."""
    work = [variant_work(v, samples, method) for v in sets.values()]
    return cell_progress(enabled, name, sum(c for c, _ in work), samples,
                         total=sum(d for _, d in work))


def fig7(description: RobotDescription, out_dir: str | Path, *,
         grasp_sets: Mapping[str, Sequence[Grasp]], samples: int = 2000,
         sigma: float = 0.0133, variants: int = 8, seed: int = 0,
         engine: str = "pybullet", friction: float = 0.5,
         executor: Executor | None = None, progress: bool = False) -> list[dict]:
    """Fig. 7 of each object's first grasp (a 7-joint arm with an elbow angle, or a 6-joint
    arm's IK branches): the robust and the fragile rows (:data:`~kinegrasp_env.toolkit.
    arm_variants.COLUMNS`, on fresh draws) in ``fig7.csv``, and each pair's contact scatter
    in ``fig7_<object>.png``; ``executor`` and ``progress`` as :func:`table1`'s.

    Raises:
        ValueError: an arm without variants (:func:`~kinegrasp_env.toolkit.arm_variants.
            check_variants`), or no object with two variants in force closure.
    """
    from kinegrasp_env.toolkit.plots import plot_contacts_pair, safe_figure
    from kinegrasp_env.world.objects import load_object

    check_variants(description, "fig7")
    sets = _variant_sets(description, grasp_sets, variants, friction)
    rows, pairs = [], []
    with _variant_progress(progress, "fig7", sets, samples) as report:
        for name, found in sets.items():
            block, fresh = variant_block(description, name, found, samples=samples,
                                         sigma=sigma, seed=seed, engine=engine,
                                         friction=friction, executor=executor, report=report)
            chosen = sorted((r for r in block if r["config"]),
                            key=lambda r: r["config"] != "robust")
            if chosen:
                rows += chosen
                pairs.append((name, chosen, fresh))
    if not rows:
        raise ValueError(f"no object has two configurations of the first grasp of robot "
                         f"{description.name!r} in force closure; nothing written")
    out = Path(out_dir)
    write_rows(out, "fig7.csv", rows, COLUMNS)
    for name, chosen, fresh in pairs:
        path = out / f"fig7_{name}.png"
        safe_figure(lambda name=name, chosen=chosen, fresh=fresh, path=path: plot_contacts_pair(
            load_object(name).mesh, [f.draws for f in fresh],
            [f"{variant_label(row, 2)}: P(FC) = {f.p_fc:.3f}"
             for row, f in zip(chosen, fresh, strict=True)], path,
            title=f"{name}, robot {description.name}: same contacts, two arm "
                  f"configurations, sigma = {sigma:g} (fresh draws)"), path)
    return rows


def check_method(method: str) -> None:
    """ValueError for an unknown fig10 method (``direct`` or ``reweight``: any arm with
    variants, :func:`~kinegrasp_env.toolkit.arm_variants.check_variants`, has the six joints
    a palm deviation's Gaussian needs)."""
    if method not in ("direct", "reweight"):
        raise ValueError(f"unknown method {method!r}: direct or reweight")


def fig10(description: RobotDescription, out_dir: str | Path, *,
          grasp_sets: Mapping[str, Sequence[Grasp]], samples: int = 1000,
          sigma: float = 0.0033, count: int = 10, seed: int = 0,
          engine: str = "pybullet", friction: float = 0.5, method: str = "direct",
          executor: Executor | None = None, progress: bool = False) -> list[dict]:
    """Fig. 10 of ``description`` (a 7-joint arm with an elbow angle, or a 6-joint arm): per
    object of ``grasp_sets``, ``count`` variants of its first grasp. Writes ``fig10.csv``
    (:data:`~kinegrasp_env.toolkit.arm_variants.COLUMNS`), then ``fig10.png`` (a figure that
    fails is a warning: the CSV stays).

    Args:
        engine: the Monte Carlo engine (``pybullet``, ``fast`` or ``physics``); the
            variants and their nominal closings use the reference engine.
        method: ``direct`` (draws per variant) or ``reweight`` (one batch per object:
            :func:`~kinegrasp_env.toolkit.arm_variants.variant_block`).
        executor, progress: as :func:`table1`'s.

    Raises:
        ValueError: an arm without variants, an unknown method, or no variant in force
            closure.
    """

    check_variants(description, "fig10")
    check_method(method)
    sets = _variant_sets(description, grasp_sets, count, friction)
    rows = []
    with _variant_progress(progress, "fig10", sets, samples, method) as report:
        for name, found in sets.items():
            rows += variant_block(description, name, found, samples=samples, sigma=sigma,
                                  seed=seed, engine=engine, friction=friction, method=method,
                                  executor=executor, report=report)[0]
    if not rows:
        raise ValueError(f"no variant of the first grasp of robot {description.name!r} closes "
                         "in force closure; nothing written")
    from kinegrasp_env.montecarlo.palm_batch import BATCH_FACTOR

    draws = (f"{samples} draws per variant" if method == "direct" else
             f"one batch of {BATCH_FACTOR * samples} closings re-weighted to each variant")
    _write_success_quality(out_dir, "fig10", rows, COLUMNS,
                           f"robot {description.name}: sigma = {sigma:g}, {draws}")
    return rows
