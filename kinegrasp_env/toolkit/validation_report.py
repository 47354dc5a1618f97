"""What ``kinegrasp validate`` writes: per-draw and per-grasp CSV tables, a JSON summary
(confusion matrices, Spearman correlations of P(FC) with P(hold) and their bootstrap
intervals) and a scatter plot, results before the figure, every file atomically."""

from __future__ import annotations

import csv
import io
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from kinegrasp_env.montecarlo.engines import OUTCOMES
from kinegrasp_env.toolkit.plots import safe_figure, save_figure
from kinegrasp_env.toolkit.validation import GraspDraws, GraspRow, ValidationSettings
from kinegrasp_env.toolkit.validation_stats import bootstrap_spearman, confusion
from kinegrasp_env.world.grasps import write_atomic

#: the confusion matrices of the summary: name -> (predicted, actual) per-draw flags
CONFUSIONS = {
    "kinematic_fc_vs_held": ("kin_fc", "held"),
    "physics_fc_vs_held": ("phys_fc", "held"),
    "kinematic_fc_vs_physics_fc": ("kin_fc", "phys_fc"),
}


def pooled(results: list[GraspDraws], attribute: str) -> np.ndarray:
    return np.concatenate([getattr(r, attribute) for r in results])


def summarize(results: list[GraspDraws], settings: ValidationSettings,
              bootstrap_seed: int = 0, resamples: int = 2000) -> dict:
    """The JSON summary: settings, per-grasp rows, pooled confusion matrices (rows: predicted
    False/True, columns: actual False/True) and, across grasps, Spearman's rho of P(FC)
    (each engine) with P(hold), with percentile bootstrap intervals over the grasps."""
    rows = [GraspRow.of(r) for r in results]
    p_hold = np.array([r.p_hold for r in rows])
    correlations = {}
    for name, column in (("kinematic", "p_fc_kinematic"), ("physics", "p_fc_physics")):
        p_fc = np.array([getattr(r, column) for r in rows])
        correlations[f"{name}_p_fc_vs_p_hold"] = bootstrap_spearman(
            p_fc, p_hold, bootstrap_seed, resamples).to_json()
    matrices = {name: confusion(pooled(results, a), pooled(results, b)).tolist()
                for name, (a, b) in CONFUSIONS.items()}
    return {"settings": asdict(settings), "grasps": [r.to_json() for r in rows],
            "draws": int(sum(r.held.size for r in results)),
            "confusion": matrices, "confusion_layout": "[[F,F],[F,T]],[[T,F],[T,T]]: rows "
            "predicted False/True, columns actual False/True",
            "spearman": correlations, "bootstrap_seed": bootstrap_seed}


def csv_text(header: list[str], rows) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue()


def draw_rows(results: list[GraspDraws]):
    for r in results:
        for i in range(r.held.size):
            yield (r.object, r.index, r.id, i, OUTCOMES[r.kin_outcome[i]],
                   f"{r.kin_quality[i]:.6g}", OUTCOMES[r.phys_outcome[i]],
                   f"{r.phys_quality[i]:.6g}", int(r.held[i]), f"{r.max_offset[i]:.6g}",
                   f"{r.lift_time[i]:.6g}")


def grasp_rows(summary: dict):
    for g in summary["grasps"]:
        yield (g["object"], g["index"], g["id"], g["samples"],
               *(f"{v:.6g}" for key in ("p_fc_kinematic", "p_fc_physics", "p_hold")
                 for v in (g[key], *g[f"{key}_ci"])))


def write_results(out_dir: str | Path, results: list[GraspDraws],
                  summary: dict) -> dict[str, Path]:
    """draws.csv, grasps.csv, summary.json, then scatter.png (a figure failure is a warning:
    the results are already written). Returns the paths written."""
    out = Path(out_dir)
    paths = {"draws": out / "draws.csv", "grasps": out / "grasps.csv",
             "summary": out / "summary.json"}
    write_atomic(paths["draws"], csv_text(
        ["object", "grasp", "id", "draw", "kinematic_outcome", "kinematic_q",
         "physics_outcome", "physics_q", "held", "max_offset_m", "lift_time_s"],
        draw_rows(results)))
    write_atomic(paths["grasps"], csv_text(
        ["object", "grasp", "id", "samples"] + [f"{key}{end}" for key in
         ("p_fc_kinematic", "p_fc_physics", "p_hold") for end in ("", "_lo", "_hi")],
        grasp_rows(summary)))
    write_atomic(paths["summary"], json.dumps(summary, indent=1))
    figure = safe_figure(lambda: plot_scatter(summary, out / "scatter.png"), out / "scatter.png")
    if figure is not None:
        paths["scatter"] = figure
    return paths


def plot_scatter(summary: dict, path: Path) -> Path:
    """P(hold) against P(FC) per grasp, kinematic and physics, with Wilson intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grasps = summary["grasps"]
    hold = np.array([g["p_hold"] for g in grasps])
    hold_err = np.abs(np.array([g["p_hold_ci"] for g in grasps]).T - hold)
    fig, ax = plt.subplots(figsize=(6, 5))
    for key, label, marker in (("kinematic", "kinematic closing", "o"),
                               ("physics", "physics closing", "s")):
        p = np.array([g[f"p_fc_{key}"] for g in grasps])
        err = np.abs(np.array([g[f"p_fc_{key}_ci"] for g in grasps]).T - p)
        rho = summary["spearman"][f"{key}_p_fc_vs_p_hold"]["rho"]
        text = "n/a" if rho is None else f"{rho:.2f}"
        ax.errorbar(p, hold, xerr=err, yerr=hold_err, fmt=marker, alpha=0.6, ms=4,
                    elinewidth=0.5, label=f"{label} (Spearman {text})")
    ax.plot([0, 1], [0, 1], color="grey", lw=0.5, ls="--")
    settings = summary["settings"]
    ax.set(xlabel="P(FC)", ylabel="P(hold) (lift, hold, shake)", xlim=(-0.03, 1.03),
           ylim=(-0.03, 1.03), title=f"{len(grasps)} grasps, sigma {settings['sigma']:g} rad, "
           f"{settings['samples']} draws each")
    ax.legend(loc="lower right", fontsize=8)
    return save_figure(fig, path)
