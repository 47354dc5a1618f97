"""Figures (matplotlib, Agg backend: works headless). Every function writes a PNG atomically."""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from kinegrasp_env.atomic_files import file_mode
from kinegrasp_env.sampling.stats import ConvergenceCurve

log = logging.getLogger(__name__)


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: str | Path, dpi: int = 120) -> Path:
    """Save ``fig`` to ``path`` through a temporary file and a rename; closes the figure."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=path.suffix or ".png", dir=path.parent)
    os.fchmod(fd, file_mode(path))  # the umask's mode, not mkstemp's private 0600
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
        pyplot().close(fig)
    return path


def safe_figure(draw: Callable[[], Path], path: str | Path) -> Path | None:
    """Run ``draw()`` (which writes the figure ``path``); if it fails, log one warning line
    and return None instead of raising: a figure must never lose results already computed
    (callers write their tables first). The figure is written atomically or not at all; an
    older figure at ``path`` is removed then, as it would not show these results."""
    try:
        return draw()
    except Exception as exc:  # any plotting failure becomes a warning
        first_line = (str(exc).splitlines() or [""])[0]
        log.warning("figure %s not written (%s: %s); the results are written", path,
                    type(exc).__name__, first_line)
        Path(path).unlink(missing_ok=True)
        return None


def covariance_ellipse(mean: np.ndarray, cov: np.ndarray, n_std: float = 2.0,
                       points: int = 100) -> np.ndarray:
    """(points, 2) outline of the n_std-sigma ellipse of a 2-D Gaussian."""
    vals, vecs = np.linalg.eigh(cov)
    t = np.linspace(0, 2 * np.pi, points)
    circle = np.stack([np.cos(t), np.sin(t)], axis=1)
    return mean + n_std * (circle * np.sqrt(np.maximum(vals, 0))) @ vecs.T


def plot_planar(joints: np.ndarray, samples: np.ndarray, mean: np.ndarray, cov: np.ndarray,
                path: str | Path, title: str = "") -> Path:
    """Planar arm (nominal joints (k+1, 2)), sampled end effectors (n, 2), 2-sigma ellipse."""
    plt = pyplot()
    fig, (ax_arm, ax_zoom) = plt.subplots(1, 2, figsize=(10, 4.6))
    for ax in (ax_arm, ax_zoom):
        ax.plot(joints[:, 0], joints[:, 1], "-o", color="0.3", lw=3, ms=5, label="nominal arm")
        ax.scatter(samples[:, 0], samples[:, 1], s=2, alpha=0.25, color="tab:blue",
                   label="sampled end effector")
        ell = covariance_ellipse(mean, cov)
        ax.plot(ell[:, 0], ell[:, 1], color="tab:red", lw=1.5, label="2-sigma covariance")
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    half = 4.0 * float(np.sqrt(np.max(np.linalg.eigvalsh(cov)))) + 1e-9
    ax_zoom.set_xlim(mean[0] - half, mean[0] + half)
    ax_zoom.set_ylim(mean[1] - half, mean[1] + half)
    ax_zoom.set_title("end-effector cloud (zoom)")
    ax_arm.set_title(title or "planar arm under joint noise")
    ax_arm.legend(loc="best", fontsize=8)
    return save_figure(fig, path)


def plot_convergence(curves: Mapping[str, Mapping[float, ConvergenceCurve]],
                     path: str | Path) -> Path:
    """Fig. 3: one row per arm, columns = error of mean, covariance, skewness vs samples.

    Args:
        curves: arm label -> {sigma: ConvergenceCurve}.
    """
    plt = pyplot()
    rows = len(curves)
    fig, axes = plt.subplots(rows, 3, figsize=(13, 3.6 * rows), squeeze=False)
    for r, (label, by_sigma) in enumerate(curves.items()):
        for sigma, curve in sorted(by_sigma.items()):
            for c, (values, name) in enumerate(
                ((curve.mean_error, "mean: L2 error [m]"),
                 (curve.cov_error, "covariance: Frobenius error [m^2]"),
                 (curve.skew_error, "skewness: L2 error"))):
                ax = axes[r, c]
                ax.loglog(curve.sizes, values, "-o", ms=3, label=f"sigma = {sigma:g}")
                ax.set_title(f"{label}: {name}", fontsize=9)
                ax.set_xlabel("samples")
                ax.grid(True, which="both", alpha=0.3)
        axes[r, 0].legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


FINGER_COLOURS = ("tab:red", "tab:green", "tab:blue")


def plot_contacts(mesh, draws, path: str | Path, title: str = "", max_normals: int = 300,
                  normal_length: float = 0.01) -> Path:
    """Contact points (and some normals) of Monte Carlo draws on the object, by finger
    (the paper's Figs. 7-8). ``draws`` is a DrawBatch; ``mesh`` a trimesh in the object
    frame."""
    plt = pyplot()
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    v = mesh.vertices
    ax.plot_trisurf(v[:, 0], v[:, 1], v[:, 2], triangles=mesh.faces, color="0.8", alpha=0.25,
                    linewidth=0)
    valid = draws.finger >= 0
    rng = np.random.default_rng(0)
    for finger, colour in enumerate(FINGER_COLOURS):
        sel = valid & (draws.finger == finger)
        if not sel.any():  # a hand with fewer fingers: no empty legend entry
            continue
        pts, nrm = draws.points[sel], draws.normals[sel]
        ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=3, color=colour, alpha=0.5,
                   label=f"finger {finger + 1}")
        if len(pts):
            pick = rng.choice(len(pts), size=min(max_normals, len(pts)), replace=False)
            ax.quiver(pts[pick, 0], pts[pick, 1], pts[pick, 2], nrm[pick, 0], nrm[pick, 1],
                      nrm[pick, 2], length=normal_length, color=colour, linewidth=0.5)
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title(title, fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper left", fontsize=8, title="contacts, some with their normals",
                  title_fontsize=7)
    else:  # no draw touched: an empty legend box (and matplotlib's warning) said nothing
        ax.text2D(0.5, 0.95, "no contact in any draw", transform=ax.transAxes,
                  ha="center", fontsize=9)
    return save_figure(fig, path)


def _pfc_lines(ax, rows: list[dict]) -> None:
    """P(FC) with its 95% interval against sigma, one line per grasp."""
    for grasp in sorted({r["grasp"] for r in rows}):
        sub = sorted((r for r in rows if r["grasp"] == grasp), key=lambda r: r["sigma"])
        sig = np.array([r["sigma"] for r in sub])
        p = np.array([r["p_fc"] for r in sub])
        lo = np.array([r["p_fc_lo"] for r in sub])
        hi = np.array([r["p_fc_hi"] for r in sub])
        ax.errorbar(sig, p, yerr=[p - lo, hi - p], marker="o", capsize=3,
                    label=f"grasp {sub[0].get('id', grasp)}")
    ax.set_xlabel("joint noise sigma [rad]")
    ax.set_ylabel("P(force closure)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def plot_pfc_vs_sigma(rows: list[dict], path: str | Path, title: str = "") -> Path:
    """P(FC) with its 95% interval against sigma, one line per grasp (rows from table1)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    _pfc_lines(ax, rows)
    ax.set_title(title)
    return save_figure(fig, path)


def plot_sweep(rows: list[dict], path: str | Path, title: str = "") -> Path:
    """A sweep's P(FC) against sigma: one panel per object, one line per grasp."""
    plt = pyplot()
    objects = list(dict.fromkeys(r["object"] for r in rows))
    fig, axes = plt.subplots(1, len(objects), figsize=(5 * len(objects), 4), squeeze=False)
    for ax, name in zip(axes[0], objects, strict=True):
        _pfc_lines(ax, [r for r in rows if r["object"] == name])
        ax.set_title(name)
    fig.suptitle(title, y=1.02)
    return save_figure(fig, path)


def plot_contacts_pair(mesh, draws_list, labels, path: str | Path, title: str = "") -> Path:
    """Side-by-side contact scatters (Fig. 7): one 3-D panel per DrawBatch."""
    plt = pyplot()
    fig = plt.figure(figsize=(12, 5.5))
    v = mesh.vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    for panel, (draws, label) in enumerate(zip(draws_list, labels, strict=True), 1):
        ax = fig.add_subplot(1, len(draws_list), panel, projection="3d")
        ax.plot_trisurf(v[:, 0], v[:, 1], v[:, 2], triangles=mesh.faces, color="0.8",
                        alpha=0.2, linewidth=0)
        for finger, colour in enumerate(FINGER_COLOURS):
            sel = draws.finger == finger
            if not sel.any():  # a hand with fewer fingers: no empty legend entry
                continue
            pts, nrm = draws.points[sel], draws.normals[sel]
            ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=3, color=colour, alpha=0.5,
                       label=f"finger {finger + 1}")
            step = max(1, len(pts) // 150)
            ax.quiver(pts[::step, 0], pts[::step, 1], pts[::step, 2], nrm[::step, 0],
                      nrm[::step, 1], nrm[::step, 2], length=0.01, color=colour, linewidth=0.4)
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
            setter(c - half, c + half)
        ax.set_title(label, fontsize=9)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(title)
    return save_figure(fig, path)


def plot_success_quality(rows: list[dict], path: str | Path, title: str = "") -> Path:
    """Figs. 9-10: per object, P(FC) bars (with their 95% intervals where the rows carry
    ``p_fc_lo`` and ``p_fc_hi``) and mean Q (+- std) against nominal Q per grasp."""
    plt = pyplot()
    objects = list(dict.fromkeys(r["object"] for r in rows))
    fig, axes = plt.subplots(2, len(objects), figsize=(3.6 * len(objects), 6), squeeze=False)
    for c, name in enumerate(objects):
        sub = [r for r in rows if r["object"] == name]
        x = np.arange(len(sub))
        p = np.array([r["p_fc"] for r in sub], dtype=float)
        spread = None
        if all("p_fc_lo" in r and "p_fc_hi" in r for r in sub):
            spread = np.array([[r["p_fc"] - r["p_fc_lo"] for r in sub],
                               [r["p_fc_hi"] - r["p_fc"] for r in sub]], dtype=float)
        axes[0, c].bar(x, p, color="tab:blue", yerr=spread, capsize=3 if spread is not None
                       else 0, error_kw={"ecolor": "0.25", "lw": 1})
        axes[0, c].set_ylim(0, 1.02)
        axes[0, c].set_title(name)
        axes[0, c].set_ylabel("success rate P(FC)")
        mean = np.array([r["q_mean"] for r in sub], dtype=float)
        std = np.nan_to_num(np.array([r["q_std"] for r in sub], dtype=float))
        axes[1, c].errorbar(x, mean, yerr=std, fmt="o", capsize=3, label="mean Q +- std")
        axes[1, c].plot(x, [r["q_nominal"] for r in sub], "k_", ms=12, label="nominal Q")
        axes[1, c].set_xlabel("grasp")
        axes[1, c].set_ylabel("Ferrari-Canny Q")
        for ax in axes[:, c]:
            ax.set_xticks(x, [r["id"] for r in sub], fontsize=7, rotation=45)
    axes[1, 0].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)


def few_ticks(count: int):
    """A matplotlib locator of at most ``count`` round ticks."""
    from matplotlib.ticker import MaxNLocator

    return MaxNLocator(count)


def plot_sensitivity(result: dict, path: str | Path, title: str = "") -> Path:
    """Bars per noise source (``result``: ``Sensitivity.to_json()``): left, the first-order
    and total Sobol indices of force closure with their intervals; right, P(FC) with the
    source alone and with all but it, the line at P(FC) with every source."""
    plt = pyplot()
    rows = result["sources"]
    names = [r["source"] for r in rows]
    x = np.arange(len(names))
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    for offset, key, label, color in ((-0.2, "first", "first order S", "C0"),
                                      (0.2, "total", "total ST", "C1")):
        value = np.array([np.nan if r[key] is None else r[key] for r in rows], dtype=float)
        ci = np.array([[np.nan, np.nan] if r[f"{key}_ci"][0] is None else r[f"{key}_ci"]
                       for r in rows], dtype=float)
        err = np.nan_to_num(np.abs(ci.T - value))
        left.bar(x + offset, np.nan_to_num(value), 0.4, yerr=err, capsize=3, color=color,
                 label=label)
    left.axhline(0, color="0.3", lw=0.8)
    if all(r["total"] is None and r["first"] is None for r in rows):  # drawn as 0 otherwise
        left.text(0.5, 0.5, "indices undefined:\nforce closure does not vary over these draws"
                  if result.get("variance") == 0 else "indices undefined",
                  transform=left.transAxes, ha="center", va="center", fontsize=9)
    turn = len(names) > 4  # many factors (an arm's joints): slanted names, legends inside
    ticks = {"rotation": 50, "ha": "right", "rotation_mode": "anchor"} if turn else {}
    place = ({"loc": "upper left", "framealpha": 0.8} if turn else
             {"loc": "upper center", "bbox_to_anchor": (0.5, -0.1)})
    left.set_xticks(x, names, **ticks)
    left.set_ylabel("Sobol index of force closure")
    left.legend(fontsize=8, ncol=2, **place)
    # blue and orange (not green and red: a pair most colour-blind readers cannot tell)
    for offset, key, label, color in ((-0.2, "p_alone", "source alone", "#0072B2"),
                                      (0.2, "p_without", "all but the source", "#E69F00")):
        value = np.array([r[key] for r in rows], dtype=float)
        ci = np.array([r[f"{key}_ci"] for r in rows], dtype=float)
        right.bar(x + offset, value, 0.4, yerr=np.abs(ci.T - value), capsize=3, color=color,
                  label=label)
    right.axhline(result["p_all"], color="k", ls="--", lw=1,
                  label=f"all sources {result['p_all']:.3f}")
    right.set_xticks(x, names, **ticks)
    right.set_ylim(0, 1.22 if turn else 1.05)
    right.set_ylabel("P(force closure)")
    right.legend(fontsize=8, ncol=3, **place)
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)
