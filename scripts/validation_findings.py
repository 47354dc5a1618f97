"""The physics guide's validation figures, from the files `kinegrasp validate` writes.

    python scripts/validation_findings.py out/validate_0133 out/validate_0333 \
        --table1 out/table1_fast200 out/table1_physics200

Per folder (one sigma): draws per grasp, the median and largest half-width of the P(hold)
intervals, mean P(FC) kinematic / physics / P(hold) over the grasps, Spearman's rho (from
``summary.json``: the validate command's bootstrap), the per-draw confusion of kinematic force
closure with holding, the share of force-closure (and other) draws held, per object the share
of its force-closure draws held and how its force-closure draws ended (no grip, grip lost,
dropped, held; the grip's median shift and net pinned force), the held / run counts of each
phase, and within force closure the AUC of the kinematic Q and of the grip's net pinned force
for holding (Mann-Whitney: the probability that a held draw has a larger value than another).
``--table1 KIN PHYS``: two ``reproduce table1`` folders (the same seed and draws, kinematic
and physics engine): the largest and mean difference of P(FC) per cell and how many cells'
Wilson intervals overlap.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np
from scipy.stats import mannwhitneyu


def read_rows(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def findings(folder: Path) -> None:
    grasps = read_rows(folder / "grasps.csv")
    draws = read_rows(folder / "draws.csv")
    summary = json.loads((folder / "summary.json").read_text())
    half = np.array([(float(g["p_hold_hi"]) - float(g["p_hold_lo"])) / 2 for g in grasps])
    means = [np.mean([float(g[k]) for g in grasps])
             for k in ("p_fc_kinematic", "p_fc_physics", "p_hold")]
    fc = np.array([d["kinematic_outcome"] == "force_closure" for d in draws])
    held = np.array([d["hold_outcome"] == "held" for d in draws])
    outcome = np.array([d["hold_outcome"] for d in draws])
    objects = np.array([d["object"] for d in draws])
    q = np.array([float(d["kinematic_q"]) for d in draws])
    shift = np.array([float(d["grip_shift_mm"]) for d in draws])
    pin = np.array([float(d["pin_force_n"]) for d in draws])
    sigma = summary["settings"].get("sigma")
    print(f"{folder} (sigma {sigma}): {len(grasps)} grasps, {grasps[0]['samples']} draws each; "
          f"P(hold) interval half-width median {np.median(half):.3f}, max {half.max():.3f}")
    print(f"  mean P(FC) kinematic / physics / P(hold): {means[0]:.3f} / {means[1]:.3f} / "
          f"{means[2]:.3f}")
    for key, value in summary["spearman"].items():
        print(f"  Spearman {key}: {value}")
    confusion = [[int((~fc & ~held).sum()), int((~fc & held).sum())],
                 [int((fc & ~held).sum()), int((fc & held).sum())]]
    print(f"  kinematic FC vs held (rows FC no/yes, columns held no/yes): {confusion}")
    print(f"  held: {held[fc].mean():.1%} of force-closure draws, {held[~fc].mean():.1%} of "
          "the others")
    for name in dict.fromkeys(objects):
        sel = fc & (objects == name)
        ends = {str(k): int(np.sum(outcome[sel] == k)) for k in dict.fromkeys(outcome[sel])}
        print(f"  {name}: {held[sel].mean():.1%} of {int(sel.sum())} force-closure draws held; "
              f"outcomes {ends}; grip shift median {np.nanmedian(shift[sel]):.1f} mm, net "
              f"pinned grip force median {np.nanmedian(pin[sel]):.1f} N")
    print("  phases held / run: " + ", ".join(f"{k} {v['held']}/{v['run']}"
                                              for k, v in summary["phases"].items()))
    for label, values in (("Q", q), ("net pinned grip force", pin)):
        a, b = values[fc & held], values[fc & ~held & np.isfinite(values)]
        if len(a) and len(b):
            auc = mannwhitneyu(a, b).statistic / (len(a) * len(b))
            print(f"  within force closure, AUC of {label} for holding: {auc:.2f}")


def compare_tables(kinematic: Path, physics: Path) -> None:
    def cells(folder: Path) -> dict:
        return {(r["grasp"], r["sigma"]): r for r in read_rows(folder / "table1.csv")}

    a, b = cells(kinematic), cells(physics)
    diff = np.array([float(b[k]["p_fc"]) - float(a[k]["p_fc"]) for k in a])
    overlap = sum(float(a[k]["p_fc_lo"]) <= float(b[k]["p_fc_hi"])
                  and float(b[k]["p_fc_lo"]) <= float(a[k]["p_fc_hi"]) for k in a)
    sigmas = list(dict.fromkeys(k[1] for k in a))
    print("| grasp | " + " | ".join(f"sigma {x}" for x in sigmas) + " |")
    print("|---|" + "---|" * len(sigmas))
    for grasp in dict.fromkeys(k[0] for k in a):
        print(f"| {grasp} | " + " | ".join(f"{float(a[grasp, x]['p_fc']):.3f} / "
                                          f"{float(b[grasp, x]['p_fc']):.3f}" for x in sigmas)
              + " |")
    worst = list(a)[int(np.argmax(np.abs(diff)))]
    print(f"Table I, physics - kinematic P(FC) over {len(diff)} cells: mean {diff.mean():+.3f}, "
          f"largest {diff[np.argmax(np.abs(diff))]:+.3f} (grasp {worst[0]}, sigma {worst[1]}: "
          f"{a[worst]['p_fc']} vs {b[worst]['p_fc']}); intervals overlap in {overlap}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path, help="`kinegrasp validate --out` folders")
    parser.add_argument("--table1", nargs=2, type=Path, metavar=("KINEMATIC", "PHYSICS"),
                        help="two `reproduce table1 --out` folders to compare")
    args = parser.parse_args()
    for folder in args.folders:
        findings(folder)
    if args.table1:
        compare_tables(*args.table1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
