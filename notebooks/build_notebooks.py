"""Write the notebooks (sources only) and optionally execute them in place.

Run: ``python notebooks/build_notebooks.py [--execute]``. Each notebook reads its sample
counts through ``KINEGRASP_NB_SCALE`` (1.0 = the full run whose outputs are committed;
the tests execute them with a small scale).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent

SETUP = '''import os
import numpy as np
import matplotlib.pyplot as plt

SCALE = float(os.environ.get("KINEGRASP_NB_SCALE", "1.0"))  # 1.0: the committed full run


def n(full: int, least: int = 10) -> int:
    """A sample count scaled by KINEGRASP_NB_SCALE."""
    return max(least, int(round(full * SCALE)))'''

NOTEBOOKS = {
    "01_end_effector_noise.ipynb": [
        ("md", """# 01 - End-effector noise (paper Figs. 2 and 3)

Joint noise propagates through the kinematics: the same end-effector position reached with
two different arm configurations has differently shaped noise clouds. Planar 2- and 3-link
arms reach (2, 2) in two configurations each under Gaussian joint noise sigma = 0.0175 rad;
the sampled clouds are compared with the closed-form covariance
(`PlanarArm.exact_moments`)."""),
        ("code", SETUP),
        ("code", '''from kinegrasp_env.noise import JointNoise
from kinegrasp_env.planar import PlanarArm
from kinegrasp_env.plots import covariance_ellipse
from kinegrasp_env.stats import moments

TARGET = np.array([2.0, 2.0])
noise = JointNoise(0.0175)


def two_link_ik(l1, l2, target, elbow):
    """Analytic IK of a 2-link planar arm; elbow = +1 or -1 picks the branch."""
    x, y = target
    c2 = (x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    q2 = elbow * np.arccos(np.clip(c2, -1, 1))
    q1 = np.arctan2(y, x) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
    return np.array([q1, q2])


arms = {}
# 2-link arm, link lengths 1.8 m and 1.2 m (the paper does not state its lengths)
two = PlanarArm((1.8, 1.2))
arms["2-link"] = (two, [two_link_ik(1.8, 1.2, TARGET, +1), two_link_ik(1.8, 1.2, TARGET, -1)])
# 3-link arm, 1.2 m each: first joint fixed at two angles, the last two solve the rest
three = PlanarArm((1.2, 1.2, 1.2))
configs = []
for q1 in (0.3, 1.2):
    base = 1.2 * np.array([np.cos(q1), np.sin(q1)])
    rest = two_link_ik(1.2, 1.2, TARGET - base, +1)
    configs.append(np.array([q1, rest[0] - q1, rest[1]]))
arms["3-link"] = (three, configs)
for name, (arm, qs) in arms.items():
    for q in qs:
        assert np.allclose(arm.joint_positions(q)[-1], TARGET, atol=1e-9), name'''),
        ("code", '''rng = np.random.default_rng(0)
samples = n(5000, 200)
fig, axes = plt.subplots(1, 2, figsize=(11, 5))
table = []
for ax, (name, (arm, qs)) in zip(axes, arms.items()):
    covs = []
    for q, colour in zip(qs, ("tab:blue", "tab:orange")):
        pts = arm.sample(q, noise, samples, rng)
        mom = moments(pts)
        exact_mean, exact_cov = arm.exact_moments(q, noise)
        covs.append(exact_cov)
        joints = arm.joint_positions(q)
        ax.plot(joints[:, 0], joints[:, 1], "-o", color=colour, lw=2)
        ax.scatter(pts[:, 0], pts[:, 1], s=1, alpha=0.3, color=colour)
        ellipse = covariance_ellipse(mom.mean, mom.cov, n_std=2.0)
        ax.plot(ellipse[:, 0], ellipse[:, 1], color="k", lw=1)
        table.append((name, f"q = {np.round(q, 3)}: max |sampled - closed-form covariance| =",
                      np.abs(mom.cov - exact_cov).max()))
    diff = np.linalg.norm(covs[0] - covs[1], "fro")
    ax.set_title(f"{name}: ||Sigma_1 - Sigma_2||_F = {diff:.6f}")
    ax.set_aspect("equal")
    table.append((name, "Frobenius difference of the two configurations' covariances =", diff))
plt.show()
for row in table:
    print(*row)'''),
        ("md", """The paper reports Frobenius differences of 0.000437 (2-link) and 0.0014 (3-link) for
link lengths it does not state; ours (lengths above) are printed in the titles. Same order of
magnitude; the exact values depend on the lengths and configurations. The sampled covariance
matches the closed form to the sampling error printed next to each configuration."""),
        ("md", """## Convergence of the estimators (Fig. 3)

Errors of the sample mean, covariance and skewness against a large-sample ground truth, as a
function of the number of draws, at the paper's four noise levels, for the 2-link arm and the
KUKA's palm position (`kinegrasp convergence` makes the same figure from the command line)."""),
        ("code", '''from kinegrasp_env.endeffector import (DEFAULT_KUKA_Q0, DEFAULT_PLANAR_LINKS,
                                       DEFAULT_PLANAR_Q0, PAPER_SIGMAS, kuka_convergence,
                                       planar_convergence)
from kinegrasp_env.plots import plot_convergence

sizes = np.unique(np.round(np.logspace(1, np.log10(n(5000, 50)), 8)).astype(int))
arm = PlanarArm(DEFAULT_PLANAR_LINKS)
curves = {"2-link planar arm": {}, "KUKA iiwa": {}}
for i, sigma in enumerate(PAPER_SIGMAS):
    curves["2-link planar arm"][sigma] = planar_convergence(
        arm, DEFAULT_PLANAR_Q0, sigma, sizes=sizes, trials=n(10, 3), truth_samples=n(100000, 2000),
        seed=np.random.default_rng([0, i]))
    curves["KUKA iiwa"][sigma] = kuka_convergence(
        DEFAULT_KUKA_Q0, sigma, sizes=sizes, trials=n(10, 3), truth_samples=n(100000, 2000),
        seed=np.random.default_rng([1, i]))
path = plot_convergence(curves, "convergence.png")
from IPython.display import Image
Image(filename=str(path))'''),
    ],
    "02_grasp_quality_convergence.ipynb": [
        ("md", """# 02 - Convergence of the grasp-quality estimators (paper Fig. 6)

How many Monte Carlo draws does P(force closure) or the mean Ferrari-Canny quality need?
Five shipped spray-flask grasps at sigma = 0.0133 rad, evaluated with the fast engine
(draw-by-draw equal to the pybullet reference, see the README). For each grasp the running
estimate after n draws is compared with the estimate from all draws; errors are averaged over
the grasps. The Wilson 95% interval shows the sampling uncertainty of one grasp, and plain
Monte Carlo is compared with antithetic and Sobol sampling over independent seeds."""),
        ("code", SETUP),
        ("code", '''from kinegrasp_env.engine import FORCE_CLOSURE
from kinegrasp_env.evaluate import evaluate_grasp
from kinegrasp_env.grasps import shipped_grasps
from kinegrasp_env.noise import JointNoise
from kinegrasp_env.stats import wilson_interval

noise = JointNoise(0.0133)
total = n(20000, 400)
grasps = shipped_grasps("spray_flask")[:5]
runs = [evaluate_grasp(g, noise, total, seed=0, engine="fast", processes=2, return_draws=True)
        for g in grasps]
sizes = np.unique(np.round(np.logspace(1, np.log10(total), 25)).astype(int))
err_p, err_q = [], []
for stats in runs:
    fc = stats.draws.outcome == FORCE_CLOSURE
    q = np.where(fc, stats.draws.quality, 0.0)
    run_p = np.cumsum(fc) / np.arange(1, total + 1)
    run_q = np.cumsum(q) / np.maximum(np.cumsum(fc), 1)
    err_p.append(np.abs(run_p[sizes - 1] - stats.p_fc))
    err_q.append(np.abs(run_q[sizes - 1] - stats.q_mean) / stats.q_mean)
fig, ax = plt.subplots(1, 2, figsize=(11, 4))
ax[0].loglog(sizes, np.mean(err_p, axis=0), "o-", label="|P(FC)_n - P(FC)_all|")
ax[0].loglog(sizes, 0.5 / np.sqrt(sizes), "k--", label="0.5 / sqrt(n)")
ax[1].loglog(sizes, np.mean(err_q, axis=0), "o-", label="relative error of mean Q")
for a in ax:
    a.set_xlabel("draws n"); a.legend(); a.grid(True, which="both", alpha=0.3)
plt.show()
for g, stats in zip(grasps, runs):
    print(f"grasp {g.id}: P(FC) = {stats.p_fc:.4f} {np.round(stats.p_fc_ci, 4)}, "
          f"mean Q = {stats.q_mean:.5f}, nominal Q = {stats.q_nominal:.5f}")'''),
        ("code", '''stats = runs[0]
fc = stats.draws.outcome == FORCE_CLOSURE
k = np.cumsum(fc)[sizes - 1]
lo_hi = np.array([wilson_interval(int(c), int(m)) for c, m in zip(k, sizes)])
plt.semilogx(sizes, k / sizes, "o-", label="running P(FC), grasp 0")
plt.fill_between(sizes, lo_hi[:, 0], lo_hi[:, 1], alpha=0.3, label="Wilson 95% interval")
plt.axhline(stats.p_fc, color="k", lw=0.8)
plt.xlabel("draws n"); plt.ylabel("P(FC)"); plt.legend(); plt.show()'''),
        ("md", """## Plain Monte Carlo against variance reduction

Each sampler estimates P(FC) of grasp 0 with n draws, over independent seeds; the spread of the
estimates is the estimator's standard error."""),
        ("code", '''seeds = range(n(20, 4))
per_run = n(1000, 100)
spread = {}
for method in ("mc", "antithetic", "sobol"):
    est = [evaluate_grasp(grasps[0], noise, per_run, seed=s, engine="fast", method=method).p_fc
           for s in seeds]
    spread[method] = (np.mean(est), np.std(est, ddof=1))
    print(f"{method:10s}: mean {spread[method][0]:.4f}, std over seeds {spread[method][1]:.4f}")'''),
    ],
}


def build(execute: bool) -> list[Path]:
    written = []
    for name, cells in NOTEBOOKS.items():
        nb = new_notebook(cells=[new_markdown_cell(src) if kind == "md" else new_code_cell(src)
                                 for kind, src in cells])
        nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                     "language": "python"}
        path = HERE / name
        if execute:
            from nbclient import NotebookClient

            NotebookClient(nb, timeout=1800, resources={"metadata": {"path": str(HERE)}}).execute()
        nbformat.write(nb, path)
        written.append(path)
    return written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--execute", action="store_true", help="run them and keep the outputs")
    args = parser.parse_args()
    for path in build(args.execute):
        print(path)


if __name__ == "__main__":
    main()
