"""The paper's experiments as functions that write tables and figures (Table I, ...)."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from kinegrasp_env.endeffector import PAPER_SIGMAS
from kinegrasp_env.evaluate import evaluate_grasp
from kinegrasp_env.grasps import shipped_grasps, write_atomic
from kinegrasp_env.noise import JointNoise

TABLE1_COLUMNS = ("grasp", "sigma", "q_nominal", "q_mean", "q_var", "p_fc", "p_fc_lo", "p_fc_hi",
                  "samples")


def table1(object_name: str, samples: int, out_dir: str | Path, *, grasps: int = 5,
           sigmas: tuple[float, ...] = PAPER_SIGMAS, seed: int = 0, processes: int = 1,
           noise: str = "gaussian", progress: bool = False) -> list[dict]:
    """Table I: mean, variance of Q and P(FC) for the first ``grasps`` shipped grasps at each
    sigma. Writes ``table1.csv``, ``table1.md`` and ``pfc_vs_sigma.png`` into ``out_dir``."""
    chosen = shipped_grasps(object_name)[:grasps]
    rows = []
    for grasp in chosen:
        for sigma in sigmas:
            stats = evaluate_grasp(grasp, JointNoise(sigma, noise), samples, seed,
                                   processes=processes, progress=progress)
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
    from kinegrasp_env.plots import plot_pfc_vs_sigma

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
