"""Figures of the elbow search (matplotlib, Agg backend; each PNG written atomically by
:func:`~kinegrasp_env.toolkit.plots.save_figure`): P(FC) along a 7-joint arm's self-motion or
over a 6-joint arm's IK branches, and a re-weighted batch's fragile palm directions against
each configuration's error ellipse."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinegrasp_env.toolkit.plots import covariance_ellipse, few_ticks, pyplot, save_figure


def plot_elbow_curve(curve: list[dict], nominal_psi: float, best_psi: float, path: str | Path,
                     title: str = "", source: str = "selection draws") -> Path:
    """P(FC) with its 95% interval along the self-motion (``curve``: dicts of psi [rad], p_fc,
    p_fc_ci; estimated on ``source``), the nominal and the best elbow angle marked."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    psi = np.array([c["psi"] for c in curve])
    p = np.array([c["p_fc"] for c in curve])
    lo = np.array([c["p_fc_ci"][0] for c in curve])
    hi = np.array([c["p_fc_ci"][1] for c in curve])
    ax.errorbar(psi, p, yerr=[np.maximum(p - lo, 0), np.maximum(hi - p, 0)], fmt="o-", ms=3,
                color="C0", ecolor="0.6", capsize=2, label=f"P(FC), {source}")
    ax.axvline(nominal_psi, color="C3", ls="--", label=f"nominal {nominal_psi:.2f} rad")
    ax.axvline(best_psi, color="C2", ls="-", label=f"best {best_psi:.2f} rad")
    ax.set_xlabel("elbow angle psi [rad]")
    ax.set_ylabel("P(force closure)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def plot_branches(result: dict, path: str | Path, title: str = "",
                  picture: dict | None = None) -> Path:
    """P(FC) of each IK branch of a 6-joint arm's grasp (``result``: ``BranchResult.
    to_json()``): the selection draws' (or, with ``reweight``, the batch's re-weighted)
    estimate with its 95% interval per branch, the fresh draws' beside it where a branch
    has them, the nominal and the chosen branch marked; with a re-weighted run's
    ``picture``, a second panel: the batch's fragile directions and both branches' error
    ellipses (:func:`draw_fragility`)."""
    plt = pyplot()
    curve = result["curve"]
    width = max(4.5, 1.2 * len(curve) + 2.5)
    if picture is None:
        fig, ax = plt.subplots(figsize=(width, 4))
    else:
        fig, (ax, right) = plt.subplots(1, 2, figsize=(width + 5.5, 4.4))
        draw_fragility(right, picture, "branch")
    x = np.arange(len(curve))
    p = np.array([c["p_fc"] for c in curve])
    lo = np.array([c["p_fc_ci"][0] for c in curve])
    hi = np.array([c["p_fc_ci"][1] for c in curve])
    ax.bar(x - 0.18, p, 0.36, color="C0",
           label=("P(FC), re-weighted batch" if "reweight" in result
                  else "P(FC), selection draws"),
           yerr=[np.maximum(p - lo, 0), np.maximum(hi - p, 0)], ecolor="0.4", capsize=3)
    fresh = [i for i, c in enumerate(curve) if "fresh_p_fc" in c]
    ax.bar(x[fresh] + 0.18, [curve[i]["fresh_p_fc"] for i in fresh], 0.36, color="C1",
           label="P(FC), fresh draws")
    labels = [f"{c['branch']}\n{c['label'].replace(' ', chr(10))}" for c in curve]
    ax.set_xticks(x, labels, fontsize=7)
    marks = [(result["nominal_branch"], "nominal", "C3"), (result["best_branch"], "chosen", "C2")]
    if marks[0][0] == marks[1][0]:
        marks = [(marks[0][0], "nominal = chosen", "C2")]
    at = {c["branch"]: i for i, c in enumerate(curve)}  # a search may leave a branch out
    for branch, name, colour in marks:
        ax.get_xticklabels()[at[branch]].set_color(colour)
        ax.annotate(name, (at[branch], 1.02), ha="center", color=colour, fontsize=8,
                    xycoords=("data", "axes fraction"))
    ax.set_ylim(0, 1)
    ax.set_xlabel("IK branch (sign of det J and of the joints that tell the branches apart)")
    ax.set_ylabel("P(force closure)")
    ax.set_title(title, pad=16)
    ax.legend(fontsize=8, loc="lower right")
    return save_figure(fig, path)


def plot_elbow_fragility(curve: list[dict], nominal_psi: float, best_psi: float,
                         picture: dict, path: str | Path, title: str = "") -> Path:
    """Two panels. Left: P(FC) with its 95% band along the self-motion (``curve`` as
    :func:`plot_elbow_curve`'s). Right: the batch's palm deviations in the two most fragile
    directions (``picture``: ``points`` (m, 2), ``fc`` (m,), ``ellipses`` {label: (2, 2)
    covariance}, ``labels`` (2,), ``spread`` (2,)), force closure grey, failures red, and each
    elbow's 2-s.d. error ellipse: the elbow whose ellipse is shorter along the fragile
    direction fails less."""
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 4.6))
    psi = np.array([c["psi"] for c in curve])
    p = np.array([c["p_fc"] for c in curve])
    lo = np.array([c["p_fc_ci"][0] for c in curve])
    hi = np.array([c["p_fc_ci"][1] for c in curve])
    left.fill_between(psi, lo, hi, color="C0", alpha=0.2, label="95% interval")
    left.plot(psi, p, "o-", ms=3, color="C0", label="P(FC), re-weighted")
    left.axvline(nominal_psi, color="C3", ls="--", label=f"nominal {nominal_psi:.2f} rad")
    left.axvline(best_psi, color="C2", label=f"best {best_psi:.2f} rad")
    left.set_xlabel("elbow angle psi [rad]")
    left.set_ylabel("P(force closure)")
    left.xaxis.set_major_locator(few_ticks(6))  # the default's many ticks ran into each other
    left.legend(fontsize=8)
    draw_fragility(right, picture, "elbow")
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)


def draw_fragility(ax, picture: dict, noun: str) -> None:
    """On ``ax``: a batch's palm deviations in the two most fragile directions (``picture``:
    ``points`` (m, 2), ``fc`` (m,), ``ellipses`` {label: (2, 2) covariance}, ``labels``
    (2,), ``spread`` (2,); :meth:`~kinegrasp_env.toolkit.reweight_evidence.
    ReweightEvidence.picture`), force closure grey, failures red, and each configuration's
    2-s.d. error ellipse, labelled "<label> ``noun``" (``elbow``, ``branch``)."""
    pts, fc = np.asarray(picture["points"]), np.asarray(picture["fc"], dtype=bool)
    ax.scatter(pts[fc, 0], pts[fc, 1], s=3, color="0.75", label="force closure")
    ax.scatter(pts[~fc, 0], pts[~fc, 1], s=4, color="C3", alpha=0.6, label="lost")
    for (label, cov), color in zip(picture["ellipses"].items(), ("C3", "C2"), strict=False):
        ring = covariance_ellipse(np.zeros(2), np.asarray(cov))
        ax.plot(ring[:, 0], ring[:, 1], color=color, lw=2, label=f"{label} {noun}, 2 s.d.")
    xl, yl = picture["labels"]
    s1, s2 = picture["spread"]
    ax.set_xlabel(f"fragile direction 1 ({xl}; failures x{s1:.1f} spread) [s.d.]")
    ax.set_ylabel(f"fragile direction 2 ({yl}; x{s2:.1f}) [s.d.]")
    ax.set_aspect("equal", adjustable="datalim")
    # beside the axes: inside, it covered the deviations it explains
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
