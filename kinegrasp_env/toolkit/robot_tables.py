"""The paper's Table I, Fig. 7 and Fig. 9 for a description robot's grasps.

Each runs the protocol the default robot's experiment runs
(:mod:`kinegrasp_env.toolkit.experiments`) on another robot's grasps, every evaluation
:func:`~kinegrasp_env.montecarlo.robot_evaluate.evaluate_robot_grasp` (joint noise on the
arm joints, seed ``seed``: the draws of ``kinegrasp evaluate --robot NAME --seed SEED``):

* **Table I**: the moments of Q over the force-closure draws and P(FC) with its Wilson 95%
  interval of the first ``grasps`` grasps of one object at each sigma (``table1.csv``,
  ``table1.md``, ``pfc_vs_sigma.png``);
* **Fig. 9**: success rate, mean Q with its standard deviation and the error (nominal - mean)
  of the first ``count`` grasps of each object at one sigma (``fig9.csv``, ``fig9.png``);
* **Fig. 7**: the same contacts reached with two arm configurations, the most and the least
  robust of ``variants`` configurations of each object's first grasp along a 7-joint arm's
  self-motion or among a 6-joint arm's IK branches
  (:func:`~kinegrasp_env.toolkit.robot_reproduce.variant_block`: chosen on the
  selection draws, reported on fresh ones with their paired gap), ``fig7.csv`` and the
  contact scatter of each pair, ``fig7_<object>.png``.

There are no paper values to set beside another robot's numbers: the tables are the robot's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.montecarlo.robot_evaluate import evaluate_robot_grasp, make_engine
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.endeffector import PAPER_SIGMAS
from kinegrasp_env.toolkit.experiments import TABLE1_COLUMNS, markdown_table1, write_rows
from kinegrasp_env.toolkit.progress import cell_progress
from kinegrasp_env.toolkit.robot_reproduce import (
    COLUMNS,
    check_variants,
    variant_block,
    variant_label,
)
from kinegrasp_env.world.grasps import Grasp, write_atomic

#: fig9.csv's columns (the robot last: readers of the older columns by position keep working).
FIG9_COLUMNS = ("object", "id", "p_fc", "q_mean", "q_std", "q_nominal", "error", "samples",
                "sigma", "robot")


def _cell(grasp: Grasp, sigma: float, samples: int, seed: int, runner, executor,
          report, label: str):
    """One cell's :func:`~kinegrasp_env.montecarlo.robot_evaluate.evaluate_robot_grasp` on
    ``runner``'s engine, reported to ``report`` (a :class:`~kinegrasp_env.toolkit.progress.
    Progress`, or None) as its chunks come back and, ``label`` first, when it is done."""
    stats = evaluate_robot_grasp(grasp, sigma=sigma, n=samples, seed=seed, engine=runner,
                                 executor=executor,
                                 progress=None if report is None else report.evaluation())
    if report is not None:
        report.finish_cell(samples, f"{label}: P(FC) {stats.p_fc:.3f}")
    return stats


def robot_table1(description: RobotDescription, object_name: str, grasps: Sequence[Grasp],
                 samples: int, out_dir: str | Path, *,
                 sigmas: tuple[float, ...] = PAPER_SIGMAS, seed: int = 0,
                 engine: str = "pybullet", friction: float = 0.5,
                 executor: Executor | None = None, progress: bool = False) -> list[dict]:
    """Table I of ``grasps`` (grasps of ``description`` on ``object_name``; a row's ``grasp``
    is its index among them) at each sigma (radians); writes the module's files.
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
                             "q_skew": stats.q_skew})
    out = Path(out_dir)
    title = f"{object_name} (robot {description.name})"
    write_rows(out, "table1.csv", [{**r, "robot": description.name} for r in rows],
               (*TABLE1_COLUMNS, "robot"))
    write_atomic(out / "table1.md", markdown_table1(rows, title, samples))
    safe_figure(lambda: plot_pfc_vs_sigma(rows, out / "pfc_vs_sigma.png",
                                          title=f"{title}: P(FC) vs noise"),
                out / "pfc_vs_sigma.png")
    return rows


def robot_fig9(description: RobotDescription, out_dir: str | Path, *,
               grasp_sets: Mapping[str, Sequence[Grasp]], samples: int = 1000,
               sigma: float = 0.0033, count: int = 10, seed: int = 0,
               engine: str = "pybullet", friction: float = 0.5,
               executor: Executor | None = None, progress: bool = False) -> list[dict]:
    """Fig. 9 of the first ``count`` grasps of each object of ``grasp_sets``; writes
    ``fig9.csv`` (:data:`FIG9_COLUMNS`) and ``fig9.png``; ``executor`` and ``progress`` as
    :func:`robot_table1`'s."""
    from kinegrasp_env.toolkit.plots import plot_success_quality, safe_figure

    rows = []
    cells = sum(len(list(grasps)[:count]) for grasps in grasp_sets.values())
    with cell_progress(progress, "fig9", cells, samples) as report:
        for name, grasps in grasp_sets.items():
            with make_engine(engine, description, name, friction=friction) as runner:
                for grasp in list(grasps)[:count]:
                    s = _cell(grasp, sigma, samples, seed, runner, executor, report,
                              f"{name} grasp {grasp.id}")
                    rows.append({"robot": description.name, "object": name, "id": grasp.id,
                                 "p_fc": s.p_fc, "q_mean": s.q_mean, "q_std": s.q_std,
                                 "q_nominal": s.q_nominal, "error": s.q_nominal - s.q_mean,
                                 "samples": samples, "sigma": sigma})
    out = Path(out_dir)
    write_rows(out, "fig9.csv", rows, FIG9_COLUMNS)
    safe_figure(lambda: plot_success_quality(
        rows, out / "fig9.png", title=f"fig9, robot {description.name}: sigma = {sigma:g}, "
                                      f"{samples} draws per grasp"), out / "fig9.png")
    return rows


def robot_fig7(description: RobotDescription, out_dir: str | Path, *,
               grasp_sets: Mapping[str, Sequence[Grasp]], samples: int = 2000,
               sigma: float = 0.0133, variants: int = 8, seed: int = 0,
               engine: str = "pybullet", friction: float = 0.5,
               executor: Executor | None = None) -> list[dict]:
    """Fig. 7 of each object's first grasp (a 7-joint arm with an elbow angle, or a 6-joint
    arm's IK branches): the robust
    and the fragile rows (:data:`COLUMNS`, on fresh draws) in ``fig7.csv``, and each pair's
    contact scatter in ``fig7_<object>.png``.

    Raises:
        ValueError: an arm without variants (:func:`~kinegrasp_env.toolkit.robot_reproduce.
            check_variants`), or no object with two variants in force
            closure.
    """
    from kinegrasp_env.toolkit.plots import plot_contacts_pair, safe_figure
    from kinegrasp_env.world.objects import load_object

    check_variants(description, "fig7")
    rows, pairs = [], []
    for name, grasps in grasp_sets.items():
        block, fresh = variant_block(description, name, grasps[0], samples=samples,
                                     sigma=sigma, count=variants, seed=seed, engine=engine,
                                     friction=friction, executor=executor)
        chosen = sorted((r for r in block if r["config"]), key=lambda r: r["config"] != "robust")
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
