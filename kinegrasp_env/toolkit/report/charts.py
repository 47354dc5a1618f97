"""The report's 2-D charts as plotly figures (plain dicts): Q's histogram over the
force-closure draws, the outcome counts, P(FC) against sigma and P(FC) along the elbow's
self-motion, both with Wilson intervals."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from kinegrasp_env.montecarlo.draws import OUTCOMES
from kinegrasp_env.toolkit.plots import covariance_ellipse
from kinegrasp_env.toolkit.report.plotly import layout
from kinegrasp_env.toolkit.report.scene import OUTCOME_COLOURS

HISTOGRAM_BINS = 40


def _vline(x: float, label: str, colour: str, dash: str, y_label: float) -> tuple[dict, dict]:
    shape = {"type": "line", "xref": "x", "yref": "paper", "x0": x, "x1": x, "y0": 0, "y1": 1,
             "line": {"color": colour, "width": 2, "dash": dash}}
    note = {"xref": "x", "yref": "paper", "x": x, "y": y_label, "text": label,
            "showarrow": False, "xanchor": "left", "font": {"color": colour},
            "bgcolor": "rgba(255,255,255,0.8)"}
    return shape, note


def quality_histogram(quality: np.ndarray, q_mean: float, q_nominal: float,
                      bins: int = HISTOGRAM_BINS) -> dict:
    """Histogram of Q over the force-closure draws ``quality`` (k,), with the mean and the
    nominal Q marked. Bins are computed here (np.histogram), so the page holds ``bins``
    counts, not k values."""
    quality = np.asarray(quality, dtype=float)
    shapes, notes = [], []
    data = []
    if quality.size:
        upper = max(float(quality.max()), q_nominal if math.isfinite(q_nominal) else 0.0)
        counts, edges = np.histogram(quality, bins=bins, range=(0.0, upper * 1.0001 or 1.0))
        data.append({"type": "bar", "name": "force-closure draws",
                     "x": ((edges[:-1] + edges[1:]) / 2).tolist(), "y": counts.tolist(),
                     "width": float(edges[1] - edges[0]), "marker": {"color": "#2ca02c"},
                     "hovertemplate": "Q %{x:.5f}: %{y} draws<extra></extra>"})
    for value, label, colour, dash, y in ((q_mean, "mean", "#1f1f1f", "dash", 0.97),
                                          (q_nominal, "nominal", "#9467bd", "solid", 0.87)):
        if math.isfinite(value):
            shape, note = _vline(value, f"{label} {value:.5f}", colour, dash, y)
            shapes.append(shape)
            notes.append(note)
    axes = {"xaxis": {"title": {"text": "Ferrari-Canny Q"}, "rangemode": "tozero"},
            "yaxis": {"title": {"text": "draws"}}}
    if not quality.size:  # no bars: say so, rather than an empty frame of made-up ranges
        notes.append({"xref": "paper", "yref": "paper", "x": 0.5, "y": 0.5,
                      "showarrow": False, "font": {"size": 14, "color": "#555555"},
                      "text": "no force-closure draw: Q has no distribution to show"})
        axes = {name: {**axis, "showticklabels": False, "showgrid": False,
                       "zeroline": False} for name, axis in axes.items()}
    return {"data": data, "layout": layout(
        title={"text": f"Q over the {quality.size} force-closure draws", "x": 0.01,
               "font": {"size": 14}},
        **axes, shapes=shapes, annotations=notes,
        showlegend=False, margin={"l": 60, "r": 20, "t": 40, "b": 50})}


def outcome_bars(outcomes: dict[str, int]) -> dict:
    """Horizontal bars of the outcome counts, with their percentages."""
    total = max(1, sum(outcomes.values()))
    names = list(OUTCOMES)
    counts = [int(outcomes.get(n, 0)) for n in names]
    return {"data": [{"type": "bar", "orientation": "h", "y": [n.replace("_", " ") for n in names],
                      "x": counts, "marker": {"color": [OUTCOME_COLOURS[n] for n in names]},
                      "text": [f"{c} ({100 * c / total:.1f}%)" for c in counts],
                      "textposition": "auto", "hoverinfo": "text"}],
            "layout": layout(title={"text": f"outcomes of {total} draws", "x": 0.01,
                                    "font": {"size": 14}},
                             xaxis={"title": {"text": "draws"}}, yaxis={"automargin": True},
                             showlegend=False, margin={"l": 120, "r": 20, "t": 40, "b": 50})}


def pfc_curve(points: Sequence[tuple[float, float, tuple[float, float]]], label: str) -> dict:
    """P(FC) against sigma (radians), with the Wilson 95% intervals as error bars;
    ``points``: (sigma, P(FC), its interval) per run, sigma the largest of a run's per-joint
    values."""
    points = sorted(points, key=lambda point: point[0])
    return {"data": [{"type": "scatter", "mode": "lines+markers", "name": label,
                      "x": [point[0] for point in points],
                      "y": [point[1] for point in points],
                      "error_y": {"type": "data", "symmetric": False,
                                  "array": [hi - v for _, v, (_, hi) in points],
                                  "arrayminus": [v - lo for _, v, (lo, _) in points]},
                      "hovertemplate": "sigma %{x:.4g} rad: P(FC) %{y:.4f}<extra></extra>"}],
            "layout": layout(title={"text": "P(force closure) against joint noise (95% "
                                            "Wilson intervals)", "x": 0.01,
                                    "font": {"size": 14}},
                             xaxis={"title": {"text": "sigma [rad]"}},
                             yaxis={"title": {"text": "P(FC)"}, "range": [-0.02, 1.02]},
                             showlegend=True, margin={"l": 60, "r": 20, "t": 40, "b": 50})}


def elbow_curve(curve: Sequence[dict], nominal_psi: float, best_psi: float,
                source: str = "selection draws, 95% Wilson intervals") -> dict:
    """P(FC) against the elbow angle psi (radians) with its 95% intervals as error bars
    (``curve``: dicts of ``psi``, ``p_fc``, ``p_fc_ci``, as ``ElbowPoint.to_json()``), the
    nominal and the best elbow angle marked by vertical lines; ``source`` says where the
    values and intervals come from (in the title)."""
    points = sorted(curve, key=lambda c: c["psi"])
    p = [c["p_fc"] for c in points]
    shapes, notes = [], []
    for value, label, colour, dash, y in ((nominal_psi, "nominal", "#d62728", "dash", 0.97),
                                          (best_psi, "best", "#2ca02c", "solid", 0.87)):
        shape, text = _vline(value, f"{label} {value:+.3f} rad", colour, dash, y)
        shapes.append(shape)
        notes.append(text)
    return {"data": [{"type": "scatter", "mode": "lines+markers", "name": "P(FC)",
                      "x": [c["psi"] for c in points], "y": p,
                      "error_y": {"type": "data", "symmetric": False,
                                  "array": [c["p_fc_ci"][1] - v for c, v in zip(points, p,
                                                                               strict=True)],
                                  "arrayminus": [v - c["p_fc_ci"][0] for c, v in zip(
                                      points, p, strict=True)]},
                      "hovertemplate": "psi %{x:.3f} rad: P(FC) %{y:.4f}<extra></extra>"}],
            "layout": layout(title={"text": f"P(force closure) along the self-motion "
                                            f"({source})", "x": 0.01,
                                    "font": {"size": 14}},
                             xaxis={"title": {"text": "elbow angle psi [rad]"},
                                    "zeroline": False},
                             yaxis={"title": {"text": "P(FC)"}, "range": [-0.02, 1.02]},
                             shapes=shapes, annotations=notes, showlegend=False,
                             margin={"l": 60, "r": 20, "t": 40, "b": 50})}


def fragility_chart(picture: dict, noun: str = "elbow") -> dict:
    """The batch's palm deviations in the two most fragile directions, force closure grey,
    lost red, with the nominal and the best configuration's 2-s.d. error ellipses
    (``picture``: as ``ReweightEvidence.picture()`` gives it: ``points`` (m, 2), ``fc``
    (m,), ``ellipses`` {label: (2, 2) covariance}, ``labels`` (2,), ``spread`` (2,));
    ``noun``: what the configurations are (``elbow``, ``branch``: a 6-joint arm's IK
    branches)."""
    pts = np.asarray(picture["points"], dtype=float)
    fc = np.asarray(picture["fc"], dtype=bool)
    data = [{"type": "scattergl", "mode": "markers", "name": name,
             "x": pts[mask, 0].round(4).tolist(), "y": pts[mask, 1].round(4).tolist(),
             "marker": {"size": 3, "color": colour, "opacity": 0.6}, "hoverinfo": "skip"}
            for name, mask, colour in (("force closure", fc, "#aaaaaa"),
                                       ("lost", ~fc, "#d62728"))]
    for (label, cov), colour in zip(picture["ellipses"].items(), ("#d62728", "#2ca02c"),
                                    strict=False):
        ring = covariance_ellipse(np.zeros(2), np.asarray(cov, dtype=float))
        data.append({"type": "scatter", "mode": "lines", "name": f"{label} {noun}, 2 s.d.",
                     "x": ring[:, 0].round(4).tolist(), "y": ring[:, 1].round(4).tolist(),
                     "line": {"color": colour, "width": 3}})
    (xl, yl), (s1, s2) = picture["labels"], picture["spread"]
    return {"data": data,
            "layout": layout(title={"text": f"Why this {noun}: the directions in which "
                                            "force closure is lost soonest", "x": 0.01,
                                    "font": {"size": 14}},
                             xaxis={"title": {"text": f"fragile direction 1 ({xl}; failures "
                                                      f"x{s1:.1f} spread) [s.d.]"}},
                             yaxis={"title": {"text": f"fragile direction 2 ({yl}; "
                                                      f"x{s2:.1f}) [s.d.]"},
                                    "scaleanchor": "x"},
                             margin={"l": 60, "r": 20, "t": 40, "b": 50})}
