"""What ``kinegrasp validate`` writes: per-draw and per-grasp CSV tables, a JSON summary and a
scatter plot, results before the figure, every file atomically.

The summary's keys: ``settings`` (the validation settings), ``protocol`` (the holding test's
constants: thresholds in metres and radians, durations in seconds; ``motors``: the hand's
closing motors it ran with, their efforts x ``torque_scale``), ``grasps`` (per grasp:
``p_fc_kinematic``, ``p_fc_physics``, ``p_hold`` with ``_ci`` Wilson 95% intervals;
``outcomes``: draws per holding outcome; ``phases``: per phase ``{"run", "held"}`` draw
counts; ``draw_outcomes``, ``grip_shift_mm``, ``grip_turn_deg``, ``pin_force_n`` (the net
force of the pinned grip on the object, what the pin holds: not zero even for balanced joint
torques, as the pin shares the force components along the joints' axes with the hand): per
draw, in draw order, None where not reached), ``draws``, ``outcomes`` and ``phases`` pooled over
the grasps, ``grip_shift_mm`` (median and max over the released draws, and over those
whose kinematic outcome is force closure), ``confusion`` (per-draw matrices),
``spearman`` (rho of P(FC) with P(hold) across grasps, bootstrap interval)."""

from __future__ import annotations

import csv
import io
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.montecarlo.draws import OUTCOMES
from kinegrasp_env.physics.protocol import HOLD_OUTCOMES, PHASES, HoldProtocol
from kinegrasp_env.toolkit.plots import safe_figure, save_figure
from kinegrasp_env.toolkit.validation import GraspDraws, GraspRow, ValidationSettings
from kinegrasp_env.toolkit.validation_stats import bootstrap_spearman, confusion

#: the confusion matrices of the summary: name -> (predicted, actual) per-draw flags
CONFUSIONS = {
    "kinematic_fc_vs_held": ("kin_fc", "held"),
    "physics_fc_vs_held": ("phys_fc", "held"),
    "kinematic_fc_vs_physics_fc": ("kin_fc", "phys_fc"),
}


def pooled(results: list[GraspDraws], attribute: str) -> np.ndarray:
    return np.concatenate([getattr(r, attribute) for r in results])


def summarize(results: list[GraspDraws], settings: ValidationSettings,
              bootstrap_seed: int = 0, resamples: int = 2000,
              robot: dict | None = None) -> dict:
    """The JSON summary: settings, per-grasp rows, pooled confusion matrices (rows: predicted
    False/True, columns: actual False/True) and, across grasps, Spearman's rho of P(FC)
    (each engine) with P(hold), with percentile bootstrap intervals over the grasps.

    ``robot``: the robot's ``{"name", "motors"}`` (:func:`~kinegrasp_env.toolkit.
    validation_draws.motors_summary`); its name goes into ``settings`` as ``robot`` and its
    motors into ``protocol`` as ``motors``."""
    protocol = settings.protocol
    rows = [GraspRow.of(r, protocol.phases) for r in results]
    p_hold = np.array([r.p_hold for r in rows])
    correlations = {}
    for name, column in (("kinematic", "p_fc_kinematic"), ("physics", "p_fc_physics")):
        p_fc = np.array([getattr(r, column) for r in rows])
        correlations[f"{name}_p_fc_vs_p_hold"] = bootstrap_spearman(
            p_fc, p_hold, bootstrap_seed, resamples).to_json()
    matrices = {name: confusion(pooled(results, a), pooled(results, b)).tolist()
                for name, (a, b) in CONFUSIONS.items()}
    outcomes = {name: sum(r.outcomes[name] for r in rows) for name in HOLD_OUTCOMES}
    phases = {name: {key: sum(r.phases[name][key] for r in rows) for key in ("run", "held")}
              for name in protocol.phases}
    limits = {} if robot is None else {"motors": robot["motors"]}
    return {"settings": asdict(settings) if robot is None
            else {"robot": robot["name"], **asdict(settings)},
            "protocol": {**asdict(protocol), "phases": list(protocol.phases), **limits},
            "grasps": [r.to_json() for r in rows],
            "draws": int(sum(len(r) for r in results)), "outcomes": outcomes, "phases": phases,
            "grip_shift_mm": shift_stats(results),
            "confusion": matrices, "confusion_layout": "[[F,F],[F,T]],[[T,F],[T,T]]: rows "
            "predicted False/True, columns actual False/True",
            "spearman": correlations, "bootstrap_seed": bootstrap_seed}


def shift_stats(results: list[GraspDraws]) -> dict:
    """Median and max grip shift (mm) over the released draws, and over those of them in
    kinematic force closure (None: no such draw)."""
    if not results:
        return {"released": None, "force_closure": None}
    shift = pooled(results, "grip_shift")
    fc = pooled(results, "kin_fc")

    def stats(values: np.ndarray) -> dict | None:
        values = values[np.isfinite(values)]
        if not values.size:
            return None
        return {"n": int(values.size), "median": round(float(np.median(values)) * 1e3, 2),
                "max": round(float(values.max()) * 1e3, 2)}
    return {"released": stats(shift), "force_closure": stats(shift[fc])}


def csv_text(header: list[str], rows) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue()


PHASE_CODES = {1: "held", 0: "failed", -1: "not_run"}


def draw_rows(results: list[GraspDraws], protocol: HoldProtocol):
    for r in results:
        margin = r.hold.margin(protocol)
        for i in range(len(r)):
            yield (r.object, r.index, r.id, i, OUTCOMES[r.kin_outcome[i]],
                   f"{r.kin_quality[i]:.6g}", OUTCOMES[r.phys_outcome[i]],
                   f"{r.phys_quality[i]:.6g}", HOLD_OUTCOMES[r.hold_outcome[i]],
                   f"{r.grip_shift[i] * 1e3:.4g}", f"{np.degrees(r.grip_turn[i]):.4g}",
                   *(f"{v:.4g}" for v in r.forces_gripped[i]),
                   *(f"{v:.4g}" for v in r.forces_released[i]), f"{r.pin_force[i]:.4g}",
                   *(PHASE_CODES[int(v)] for v in r.phase_held[i]),
                   *(f"{v * 1e3:.4g}" for v in r.phase_shift[i]), f"{margin[i]:.4g}")


def grasp_rows(summary: dict):
    for g in summary["grasps"]:
        yield (g["object"], g["index"], g["id"], g["samples"],
               *(f"{v:.6g}" for key in ("p_fc_kinematic", "p_fc_physics", "p_hold")
                 for v in (g[key], *g[f"{key}_ci"])))


def write_results(out_dir: str | Path, results: list[GraspDraws], summary: dict, *,
                  protocol: HoldProtocol) -> dict[str, Path]:
    """draws.csv (its last column each draw's :func:`~kinegrasp_env.physics.protocol.
    hold_margin` under ``protocol``, the one the draws ran), grasps.csv, summary.json, then
    scatter.png (a figure failure is a warning: the results are already written). Returns
    the paths written."""
    out = Path(out_dir)
    fingers = results[0].forces_gripped.shape[1] if results else 3
    paths = {"draws": out / "draws.csv", "grasps": out / "grasps.csv",
             "summary": out / "summary.json"}
    write_atomic(paths["draws"], csv_text(
        ["object", "grasp", "id", "draw", "kinematic_outcome", "kinematic_q",
         "physics_outcome", "physics_q", "hold_outcome", "grip_shift_mm", "grip_turn_deg"]
        + [f"force_{when}_f{k + 1}_n" for when in ("gripped", "released")
           for k in range(fingers)]
        + ["pin_force_n"]
        + list(PHASES) + [f"{name}_max_shift_mm" for name in PHASES] + ["hold_margin"],
        draw_rows(results, protocol)))
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
    fig, ax = plt.subplots(figsize=(6, 5.6))
    # the kinematic markers hollow and larger, so that a physics marker on the same spot
    # leaves them visible
    for key, label, style in (("kinematic", "kinematic closing",
                               {"fmt": "o", "ms": 7, "mfc": "none", "mew": 1.2}),
                              ("physics", "physics closing", {"fmt": "s", "ms": 4})):
        p = np.array([g[f"p_fc_{key}"] for g in grasps])
        err = np.abs(np.array([g[f"p_fc_{key}_ci"] for g in grasps]).T - p)
        rho = summary["spearman"][f"{key}_p_fc_vs_p_hold"]["rho"]
        text = "n/a" if rho is None else f"{rho:.2f}"
        ax.errorbar(p, hold, xerr=err, yerr=hold_err, alpha=0.7, elinewidth=0.5,
                    label=f"{label} (Spearman {text})", **style)
    ax.plot([0, 1], [0, 1], color="grey", lw=0.5, ls="--")
    settings = summary["settings"]
    objects = ", ".join(dict.fromkeys(g["object"] for g in grasps))
    robot = f"{settings['robot']}, " if "robot" in settings else ""
    ax.set(xlabel="P(FC)", ylabel="P(hold) (grip, six gravity directions, lift)",
           xlim=(-0.03, 1.03), ylim=(-0.03, 1.03),
           title=f"{robot}{objects}: holding test in {settings['simulator']}\n"
           f"{len(grasps)} grasps, sigma {settings['sigma']:g} rad, "
           f"{settings['samples']} draws each")
    # below the axes: inside, it covered the corners where the points gather (P(FC) 1)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8,
              frameon=False)
    fig.tight_layout()
    return save_figure(fig, path)
