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
