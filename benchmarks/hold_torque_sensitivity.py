"""How much does P(hold) depend on the assumed torque limits? The holding test
(``kinegrasp validate``) of the shipped grasps at several multiples of the hand's motor
efforts (its description's: 2.1 N m proximal, 1.4 N m distal, stated assumptions), on the
same draws.

Per scale: P(hold) pooled over the grasps with a Wilson 95% interval, per object, the
outcomes (no grip, grip lost, dropped, held), each phase's held / run counts, the grip's own
shift of the object (median, max) and the net force of the pinned grip (median). Scales are
compared draw by draw with the 1x run (the same draws: paired): the discordant counts and an
exact two-sided McNemar p-value (scipy's binomial test), Holm-corrected over the scales.

    python benchmarks/hold_torque_sensitivity.py [--objects cube drill] [--sigma 0]
        [--samples 1] [--scales 0.5 1 2] [--processes 2] [--out benchmarks/results/...]

Results are cached per scale under ``--cache`` (a rerun resumes); the JSON goes to ``--out``,
the table into the physics guide (``--page``, between ``<!-- hold-torques:start -->`` and
``<!-- hold-torques:end -->``; ``--no-page`` prints it only).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from marked_section import write_between
from scipy.stats import binomtest

from kinegrasp_env.physics.protocol import HOLD_OUTCOMES
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.toolkit.validation import ValidationSettings, run_validation
from kinegrasp_env.toolkit.validation_draws import motors_summary
from kinegrasp_env.toolkit.validation_report import summarize
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import OBJECT_NAMES

ROOT = Path(__file__).resolve().parent
#: The physics guide's section this script writes.
START, END = "<!-- hold-torques:start -->", "<!-- hold-torques:end -->"


def scale_summary(results, settings) -> dict:
    summary = summarize(results, settings, resamples=200)
    held = np.concatenate([r.held for r in results])
    k, n = int(held.sum()), int(held.size)
    per_object = {}
    for name in dict.fromkeys(r.object for r in results):
        flags = np.concatenate([r.held for r in results if r.object == name])
        per_object[name] = {"held": int(flags.sum()), "draws": int(flags.size),
                            "p_hold": float(flags.mean())}
    pin = np.concatenate([r.pin_force for r in results])
    pin = pin[np.isfinite(pin)]
    efforts = [m["effort"] for m in motors_summary("kuka_sdh", settings.torque_scale)]
    return {"torque_scale": settings.torque_scale, "efforts_nm": list(dict.fromkeys(efforts)),
            "p_hold": k / n, "p_hold_ci": list(wilson_interval(k, n)), "held": k, "draws": n,
            "per_object": per_object, "outcomes": summary["outcomes"],
            "phases": summary["phases"], "grip_shift_mm": summary["grip_shift_mm"],
            "pin_force_n_median": round(float(np.median(pin)), 2) if pin.size else None}


def paired(base: np.ndarray, other: np.ndarray) -> dict:
    """Discordant pairs (held at 1x only, held at the other scale only) and McNemar's exact
    two-sided p-value."""
    only_base, only_other = int(np.sum(base & ~other)), int(np.sum(~base & other))
    m = only_base + only_other
    p = 1.0 if m == 0 else float(binomtest(only_base, m, 0.5).pvalue)
    return {"held_at_1x_only": only_base, "held_here_only": only_other, "mcnemar_p": p}


def holm(p_values: list[float]) -> list[float]:
    """Holm's step-down adjusted p-values."""
    order = np.argsort(p_values)
    adjusted, running = [0.0] * len(p_values), 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(p_values) - rank) * p_values[i]))
        adjusted[i] = running
    return adjusted


def markdown(rows: list[dict]) -> str:
    """The table of the physics guide: per torque scale its limits, P(hold), the outcomes,
    the grip's shift and the paired comparison with 1x."""
    lines = ["| torque scale | motor efforts N m | P(hold) [95% CI] | "
             + " | ".join(HOLD_OUTCOMES[1:]) + " | grip shift mm median / max | vs 1x |",
             "|---|---|---|" + "---|" * (len(HOLD_OUTCOMES) - 1) + "---|---|"]
    for row in rows:
        shift, pair = row["grip_shift_mm"]["released"], row["paired_with_1x"]
        lo, hi = row["p_hold_ci"]
        versus = "-" if pair is None else (f"{pair['held_at_1x_only']} / "
                                           f"{pair['held_here_only']}, Holm p "
                                           f"{pair['holm_p']:.2g}")
        shifts = "-" if shift is None else f"{shift['median']:.2f} / {shift['max']:.2f}"
        efforts = " / ".join(f"{e:g}" for e in row["efforts_nm"])
        lines.append(f"| {row['torque_scale']:g}x | {efforts} | "
                     f"{row['p_hold']:.3f} [{lo:.2f}, {hi:.2f}] | "
                     + " | ".join(str(row["outcomes"][k]) for k in HOLD_OUTCOMES[1:])
                     + f" | {shifts} | {versus} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", nargs="+", default=list(OBJECT_NAMES))
    parser.add_argument("--sigma", type=float, default=0.0)
    parser.add_argument("--samples", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scales", type=float, nargs="+", default=[0.5, 1.0, 2.0])
    parser.add_argument("--processes", type=int, default=1)
    parser.add_argument("--cache", default="out/hold_torque_sensitivity")
    parser.add_argument("--out", default=str(ROOT / "results" / "hold_torque_sensitivity.json"))
    parser.add_argument("--page", type=Path, default=ROOT.parent / "docs" / "guides" / "physics.md",
                        help="the page whose generated section gets the table")
    parser.add_argument("--no-page", action="store_true", help="print the table only")
    args = parser.parse_args()
    if 1.0 not in args.scales:
        parser.error("--scales must include 1 (the paired comparisons are against it)")
    grasps = [pair for name in args.objects for pair in enumerate(shipped_grasps(name))]
    rows, held = [], {}
    for scale in args.scales:
        settings = ValidationSettings(sigma=args.sigma, samples=args.samples, seed=args.seed,
                                      torque_scale=scale)
        results = run_validation(grasps, settings, Path(args.cache) / f"x{scale:g}",
                                 args.processes, progress=True)
        held[scale] = np.concatenate([r.held for r in results])
        rows.append(scale_summary(results, settings))
    others = [s for s in args.scales if s != 1.0]
    tests = [paired(held[1.0], held[s]) for s in others]
    for test, adjusted in zip(tests, holm([t["mcnemar_p"] for t in tests]), strict=True):
        test["holm_p"] = adjusted
    for row in rows:
        s = row["torque_scale"]
        row["paired_with_1x"] = None if s == 1.0 else tests[others.index(s)]
    out = {"objects": args.objects, "sigma": args.sigma, "samples": args.samples,
           "seed": args.seed, "grasps": len(grasps), "scales": rows}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    body = markdown(rows)
    print(f"{len(grasps)} grasps x {args.samples} draws, sigma {args.sigma:g}, seed {args.seed}")
    print(body)
    if not args.no_page:
        write_between(args.page, START, END, body)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
