"""Two simulators, one holding test: ``kinegrasp validate --simulator mujoco`` against
``--simulator pybullet`` on the same draws, draw by draw and grasp by grasp.

For each built-in object, the shipped grasps ``--grasp`` (default all 12) get ``--samples``
draws each at joint noise ``--sigma`` (default 0.0133 rad) and seed ``--seed``: the same
configurations in both simulators (the CLI's draws of that seed). Each simulator runs the
same protocol (``kinegrasp_env.physics.protocol``: the object pinned while the hand closes and
grips, released, then rest, six gravity directions, lift). Reported:

* draw by draw, held / not held: the confusion table (rows pybullet, columns MuJoCo) per
  object and in all, and the share of draws on which they agree (Wilson 95% interval);
* the outcomes' cross table (start collision, no grip, grip lost, grip unsteady, dropped,
  held), so a disagreement says where in the protocol the two part;
* per grasp the P(hold) pair;
* every disagreeing draw: its two outcomes, the first failed phase in each, and the grip's
  shift of the object in each;
* what both support: the grasps held in every draw by both simulators, those held by
  neither, and the disputed rest.

The validate runs are cached in ``--out`` (a rerun resumes). The summary is written as JSON
(``--json-out``), as a Markdown section of README.md (the agreement, the confusion per object,
what both support) between ``<!-- simulator-agreement:start -->`` and
``<!-- simulator-agreement:end -->`` (``--readme``), and the per-grasp and per-draw tables into
the physics guide between ``<!-- simulator-agreement-detail:start -->`` and
``<!-- simulator-agreement-detail:end -->`` (``--page``; ``--no-readme`` writes neither).

    python benchmarks/simulator_agreement.py [--objects cube drill] [--grasp 0 1 2]
        [--samples 3] [--sigma 0.0133] [--seed 0] [--out out/simulator_agreement]

About 1-4 s per draw and simulator on one core (144 draws x 2 at the defaults: 11 min
measured on a loaded 2-core machine).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

from marked_section import write_between

from kinegrasp_env.physics.protocol import HOLD_OUTCOMES, PHASES
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.world.objects import OBJECT_NAMES

ROOT = Path(__file__).resolve().parents[1]
SIMULATORS = ("pybullet", "mujoco")
START, END = "<!-- simulator-agreement:start -->", "<!-- simulator-agreement:end -->"
DETAIL_START, DETAIL_END = ("<!-- simulator-agreement-detail:start -->",
                            "<!-- simulator-agreement-detail:end -->")
#: A grip shift above this (mm) marks a disagreement that follows an unsteady release.
SHIFT_MM = 5.0


def run_validate(simulator: str, obj: str, args, out: Path) -> Path:
    """``kinegrasp validate`` of one object in one simulator (cached in ``out``); its
    draws.csv."""
    folder = out / simulator / obj
    folder.parent.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "kinegrasp_env.cli", "validate", "--object", obj,
               "--grasp", *map(str, args.grasp), "--sigma", str(args.sigma), "--samples",
               str(args.samples), "--seed", str(args.seed), "--simulator", simulator,
               "--out", str(folder)]
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    print(f"  {simulator:8s} {obj:12s} {time.perf_counter() - start:6.1f} s", file=sys.stderr)
    return folder / "draws.csv"


def read_draws(path: Path) -> dict[tuple[str, int, int], dict]:
    """(object, grasp, draw) -> {outcome, first failed phase, grip shift mm}."""
    rows = {}
    with path.open() as handle:
        for row in csv.DictReader(handle):
            failed = next((p for p in PHASES if row.get(p) == "failed"), None)
            shift = row.get("grip_shift_mm", "nan")
            rows[(row["object"], int(row["grasp"]), int(row["draw"]))] = {
                "outcome": row["hold_outcome"], "first_failed": failed,
                "grip_shift_mm": None if shift in ("", "nan") else float(shift)}
    return rows


def confusion(pairs: list[tuple[dict, dict]]) -> list[list[int]]:
    """[[neither held, MuJoCo only], [pybullet only, both]] (rows pybullet)."""
    table = [[0, 0], [0, 0]]
    for a, b in pairs:
        table[a["outcome"] == "held"][b["outcome"] == "held"] += 1
    return table


def summarize(draws: dict[str, dict], objects: list[str]) -> dict:
    """The JSON summary of the paired draws (module docstring)."""
    keys = sorted(draws["pybullet"])
    missing = [k for k in keys if k not in draws["mujoco"]]
    if missing:
        raise RuntimeError(f"MuJoCo has no draw {missing[0]} that pybullet has")
    pairs = {k: (draws["pybullet"][k], draws["mujoco"][k]) for k in keys}
    agree = sum((a["outcome"] == "held") == (b["outcome"] == "held") for a, b in pairs.values())
    lo, hi = wilson_interval(agree, len(pairs))
    cross = {o: {p: 0 for p in HOLD_OUTCOMES} for o in HOLD_OUTCOMES}
    for a, b in pairs.values():
        cross[a["outcome"]][b["outcome"]] += 1
    per_grasp = {}
    for obj in objects:
        for grasp in sorted({k[1] for k in keys if k[0] == obj}):
            group = [pairs[k] for k in keys if k[:2] == (obj, grasp)]
            per_grasp[f"{obj} {grasp}"] = {
                "n": len(group),
                "p_hold_pybullet": sum(a["outcome"] == "held" for a, _ in group) / len(group),
                "p_hold_mujoco": sum(b["outcome"] == "held" for _, b in group) / len(group)}
    both = [g for g, r in per_grasp.items() if r["p_hold_pybullet"] == r["p_hold_mujoco"] == 1]
    neither = [g for g, r in per_grasp.items()
               if r["p_hold_pybullet"] == r["p_hold_mujoco"] == 0]
    disputed = [g for g in per_grasp if g not in both and g not in neither]
    return {
        "draws": len(pairs), "agree": agree, "agree_share": agree / len(pairs),
        "agree_ci95": [lo, hi],
        "confusion_all": confusion(list(pairs.values())),
        "confusion_layout": "rows pybullet not held / held, columns MuJoCo not held / held",
        "confusion_by_object": {o: confusion([p for k, p in pairs.items() if k[0] == o])
                                for o in objects},
        "outcomes_pybullet_rows_mujoco_columns": cross,
        "per_grasp": per_grasp,
        "held_by_both_every_draw": both, "held_by_neither": neither, "disputed": disputed,
        "disagreements": [
            {"object": k[0], "grasp": k[1], "draw": k[2], "pybullet": a["outcome"],
             "mujoco": b["outcome"], "pybullet_first_failed": a["first_failed"],
             "mujoco_first_failed": b["first_failed"],
             "pybullet_grip_shift_mm": a["grip_shift_mm"],
             "mujoco_grip_shift_mm": b["grip_shift_mm"]}
            for k, (a, b) in pairs.items()
            if (a["outcome"] == "held") != (b["outcome"] == "held")],
    }


def markdown(summary: dict, args) -> str:
    """The README section's body (between the markers): the agreement, the confusion per
    object and what both simulators support."""
    s = summary
    lines = [
        f"`python benchmarks/simulator_agreement.py` (sigma {args.sigma}, seed {args.seed}, "
        f"{args.samples} draws per grasp, shipped grasps {', '.join(map(str, args.grasp))}): "
        f"the same draws in both simulators; held / not held agree on {s['agree']} of "
        f"{s['draws']} draws ({100 * s['agree_share']:.0f}%, 95% interval "
        f"{100 * s['agree_ci95'][0]:.0f}-{100 * s['agree_ci95'][1]:.0f}%).", "",
        "| object | both not held | MuJoCo only | pybullet only | both held |",
        "|---|---|---|---|---|"]
    for obj, ((nn, nm), (pn, pm)) in s["confusion_by_object"].items():
        lines.append(f"| {obj} | {nn} | {nm} | {pn} | {pm} |")
    (nn, nm), (pn, pm) = s["confusion_all"]
    lines += [f"| all | {nn} | {nm} | {pn} | {pm} |", "",
              "What both simulators support: held in every draw by both: "
              + (", ".join(s["held_by_both_every_draw"]) or "none")
              + "; held in no draw by either: " + (", ".join(s["held_by_neither"]) or "none")
              + "; disputed (no conclusion): " + (", ".join(s["disputed"]) or "none") + "."]
    return "\n".join(lines)


def detail_markdown(summary: dict) -> str:
    """The physics guide's section: per grasp the P(hold) pair, the outcomes' cross table
    and every disagreeing draw."""
    s = summary
    lines = ["| grasp | P(hold) pybullet | P(hold) MuJoCo |", "|---|---|---|"]
    for grasp, r in s["per_grasp"].items():
        lines.append(f"| {grasp} | {r['p_hold_pybullet']:.2f} | {r['p_hold_mujoco']:.2f} |")
    cross = s["outcomes_pybullet_rows_mujoco_columns"]
    used = [o for o in HOLD_OUTCOMES
            if any(cross[o][p] or cross[p][o] for p in HOLD_OUTCOMES)]
    lines += ["", "Outcomes (rows pybullet, columns MuJoCo):", "",
              "| pybullet \\ MuJoCo | " + " | ".join(used) + " |",
              "|---" * (len(used) + 1) + "|"]
    lines += [f"| {o} | " + " | ".join(str(cross[o][p]) for p in used) + " |" for o in used]
    moved = [d for d in s["disagreements"]
             if max(d["pybullet_grip_shift_mm"] or 0.0, d["mujoco_grip_shift_mm"] or 0.0)
             > SHIFT_MM]
    lines += ["", f"The {len(s['disagreements'])} disagreeing draws ({len(moved)} of them "
              f"after a grip that moved the object by more than {SHIFT_MM:g} mm on release in "
              "at least one simulator):", "",
              "| draw | pybullet | MuJoCo | first failed phase (pybullet / MuJoCo) | "
              "grip shift mm (pybullet / MuJoCo) |", "|---|---|---|---|---|"]
    for d in s["disagreements"]:
        shifts = " / ".join("-" if v is None else f"{v:.1f}"
                            for v in (d["pybullet_grip_shift_mm"], d["mujoco_grip_shift_mm"]))
        lines.append(f"| {d['object']} {d['grasp']} #{d['draw']} | {d['pybullet']} | "
                     f"{d['mujoco']} | {d['pybullet_first_failed'] or '-'} / "
                     f"{d['mujoco_first_failed'] or '-'} | {shifts} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=list(OBJECT_NAMES),
                        choices=list(OBJECT_NAMES))
    parser.add_argument("--grasp", nargs="+", type=int, default=list(range(12)))
    parser.add_argument("--samples", type=int, default=3)
    parser.add_argument("--sigma", type=float, default=0.0133)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "simulator_agreement")
    parser.add_argument("--json-out", type=Path,
                        default=ROOT / "benchmarks" / "results" / "simulator_agreement.json")
    parser.add_argument("--readme", type=Path, default=ROOT / "README.md")
    parser.add_argument("--page", type=Path, default=ROOT / "docs" / "guides" / "physics.md",
                        help="the page that gets the per-grasp and per-draw tables")
    parser.add_argument("--no-readme", action="store_true", help="print only")
    args = parser.parse_args(argv)
    if args.samples < 1:
        parser.error(f"--samples must be >= 1, got {args.samples}")
    draws: dict[str, dict] = {s: {} for s in SIMULATORS}
    for obj in args.objects:
        for simulator in SIMULATORS:
            draws[simulator].update(read_draws(run_validate(simulator, obj, args, args.out)))
    summary = summarize(draws, args.objects)
    summary["settings"] = {"sigma": args.sigma, "seed": args.seed, "samples": args.samples,
                           "grasps": args.grasp, "objects": args.objects}
    body, detail = markdown(summary, args), detail_markdown(summary)
    print(body + "\n\n" + detail)
    args.json_out.parent.mkdir(parents=True, exist_ok=True)
    args.json_out.write_text(json.dumps(summary, indent=1) + "\n")
    if not args.no_readme:
        write_between(args.readme, START, END, body)
        write_between(args.page, DETAIL_START, DETAIL_END, detail)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
