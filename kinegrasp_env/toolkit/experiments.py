"""The paper's experiments as functions that write tables and figures (Table I, ...)."""

from __future__ import annotations

import csv
import io
import math
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path

from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.montecarlo.execution import Executor, LocalExecutor
from kinegrasp_env.robot.endeffector import PAPER_SIGMAS
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import shipped_grasps, write_atomic

TABLE1_COLUMNS = ("grasp", "sigma", "q_nominal", "q_mean", "q_var", "p_fc", "p_fc_lo", "p_fc_hi",
                  "samples")


def table1(object_name: str, samples: int, out_dir: str | Path, *, grasps: int = 5,
           sigmas: tuple[float, ...] = PAPER_SIGMAS, seed: int = 0, processes: int = 1,
           noise: str = "gaussian", progress: bool = False,
           engine: str = "pybullet", executor: Executor | None = None) -> list[dict]:
    """Table I: mean, variance of Q and P(FC) for the first ``grasps`` shipped grasps at each
    sigma. Writes ``table1.csv``, ``table1.md`` and ``pfc_vs_sigma.png`` into ``out_dir``."""
    chosen = shipped_grasps(object_name)[:grasps]
    rows = []
    with _executor(executor, processes) as run_on:
        cells = [(grasp, sigma) for grasp in chosen for sigma in sigmas]
        all_stats = [evaluate_grasp(grasp, JointNoise(sigma, noise), samples, seed,
                                    progress=progress, engine=engine, executor=run_on)
                     for grasp, sigma in cells]
    for (grasp, sigma), stats in zip(cells, all_stats, strict=True):
        rows.append({"grasp": int(grasp.id), "sigma": sigma, "q_nominal": stats.q_nominal,
                     "q_mean": stats.q_mean, "q_var": stats.q_var, "p_fc": stats.p_fc,
                     "p_fc_lo": stats.p_fc_ci[0], "p_fc_hi": stats.p_fc_ci[1],
                     "samples": stats.samples})
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=TABLE1_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / "table1.csv", buffer.getvalue())
    write_atomic(out / "table1.md", markdown_table1(rows, object_name, samples))
    from kinegrasp_env.toolkit.plots import plot_pfc_vs_sigma

    plot_pfc_vs_sigma(rows, out / "pfc_vs_sigma.png", title=f"{object_name}: P(FC) vs noise")
    return rows


def _fmt(value: float, digits: int = 4) -> str:
    return "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else \
        f"{value:.{digits}g}"


def markdown_table1(rows: list[dict], object_name: str, samples: int) -> str:
    sigmas = sorted({r["sigma"] for r in rows})
    head = "| grasp | Q nominal | " + " | ".join(
        f"sigma={s:g}: mean / var / P(FC)" for s in sigmas) + " |"
    lines = [f"Table I, {object_name}, {samples} draws per cell (Q over force-closure draws)",
             "", head, "|" + "---|" * (len(sigmas) + 2)]
    for grasp in sorted({r["grasp"] for r in rows}):
        cells = {r["sigma"]: r for r in rows if r["grasp"] == grasp}
        first = next(iter(cells.values()))
        lines.append(f"| {grasp} | {_fmt(first['q_nominal'])} | " + " | ".join(
            f"{_fmt(cells[s]['q_mean'])} / {_fmt(cells[s]['q_var'], 3)} / "
            f"{cells[s]['p_fc']:.3f}" for s in sigmas) + " |")
    return "\n".join(lines) + "\n"


def _executor(executor: Executor | None, processes: int) -> AbstractContextManager[Executor]:
    """The caller's executor (left open), else a local pool for the experiment's duration."""
    return nullcontext(executor) if executor is not None else LocalExecutor(processes)


def _evaluate_set(grasps, sigma: float, samples: int, seed: int, processes: int,
                  engine: str = "pybullet", return_draws: bool = False,
                  executor: Executor | None = None) -> list:
    from kinegrasp_env.montecarlo.evaluate import evaluate_grasp

    with _executor(executor, processes) as run_on:
        return [evaluate_grasp(g, JointNoise(sigma), samples, seed, engine=engine,
                               return_draws=return_draws, executor=run_on) for g in grasps]


def _write_rows(out: Path, name: str, rows: list[dict]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / name, buffer.getvalue())


def fig7(out_dir: str | Path, *, objects: tuple[str, ...] = ("drill", "spray_flask"),
         samples: int = 2000, sigma: float = 0.0133, variants: int = 8, seed: int = 0,
         processes: int = 1, engine: str = "pybullet",
         executor: Executor | None = None) -> list[dict]:
    """Fig. 7: the same contacts reached with two arm configurations (the most and the least
    robust of ``variants`` null-space variants of shipped grasp 0): P(FC) and the scatter of
    contact points and normals for each. Writes ``fig7_<object>.png`` and ``fig7.csv``."""
    from kinegrasp_env.toolkit.planner import GraspPlanner
    from kinegrasp_env.toolkit.plots import plot_contacts_pair
    from kinegrasp_env.world.objects import load_object

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in objects:
        grasp = shipped_grasps(name)[0]
        planner = GraspPlanner(name)
        try:
            candidates = [grasp, *planner.variants(grasp, variants)]
        finally:
            planner.close()
        stats = _evaluate_set(candidates, sigma, samples, seed, processes, engine,
                              return_draws=True, executor=executor)
        best = max(range(len(stats)), key=lambda i: stats[i].p_fc)
        worst = min(range(len(stats)), key=lambda i: stats[i].p_fc)
        for label, i in (("robust", best), ("fragile", worst)):
            rows.append({"object": name, "config": label, "id": candidates[i].id,
                         "elbow_angle": candidates[i].meta.get("elbow_angle"),
                         "p_fc": stats[i].p_fc, "p_fc_lo": stats[i].p_fc_ci[0],
                         "p_fc_hi": stats[i].p_fc_ci[1], "q_mean": stats[i].q_mean,
                         "q_nominal": stats[i].q_nominal, "samples": samples})
        plot_contacts_pair(load_object(name).mesh, [stats[best].draws, stats[worst].draws],
                           [f"elbow {candidates[i].meta.get('elbow_angle', 0):.2f} rad: "
                            f"P(FC) = {stats[i].p_fc:.3f}" for i in (best, worst)],
                           out / f"fig7_{name}.png",
                           title=f"{name}: same contacts, two arm configurations, "
                                 f"sigma = {sigma:g}")
    _write_rows(out, "fig7.csv", rows)
    return rows


def fig9_10(which: str, out_dir: str | Path, *, samples: int = 1000, sigma: float = 0.0033,
            count: int = 10, seed: int = 0, processes: int = 1,
            engine: str = "pybullet", executor: Executor | None = None) -> list[dict]:
    """Figs. 9 and 10: success rate, mean quality (with its std) and the error
    (nominal - mean) of ``count`` grasps per object at ``sigma``. fig9: the shipped grasps
    (different contacts and arms); fig10: null-space variants of shipped grasp 0 (same
    contacts, different arms). Writes ``<which>.csv`` and ``<which>.png``."""
    from kinegrasp_env.toolkit.planner import GraspPlanner
    from kinegrasp_env.toolkit.plots import plot_success_quality
    from kinegrasp_env.world.objects import OBJECT_NAMES

    if which not in ("fig9", "fig10"):
        raise ValueError(f"unknown figure {which!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in OBJECT_NAMES:
        if which == "fig9":
            grasps = shipped_grasps(name)[:count]
        else:
            planner = GraspPlanner(name)
            try:
                grasps = planner.variants(shipped_grasps(name)[0], count)
            finally:
                planner.close()
        for g, s in zip(grasps, _evaluate_set(grasps, sigma, samples, seed, processes, engine,
                                                  executor=executor),
                        strict=True):
            rows.append({"object": name, "id": g.id, "p_fc": s.p_fc, "q_mean": s.q_mean,
                         "q_std": s.q_std, "q_nominal": s.q_nominal, "error": s.error,
                         "samples": samples})
    _write_rows(out, f"{which}.csv", rows)
    plot_success_quality(rows, out / f"{which}.png",
                         title=f"{which}: sigma = {sigma:g}, {samples} draws per grasp")
    return rows
