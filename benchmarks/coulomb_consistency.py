"""Coulomb consistency: the friction coefficient the quality code says a grasp needs, checked
in pybullet and in MuJoCo (the grasp resists at 1.5 mu*, slips at 0.67 mu*).

For each test grasp of ``benchmarks/coulomb/grasps.py`` (a box pinched by two fingers on
opposite faces under a force or a torque, a box tripod, a triangular frustum squeezed by three
fingers, with and without a twist; fingers pressing with 10 N along the normals, the object
free, gravity off):

* mu* -- the smallest mu at which contact forces with the fingers' normal forces, each in the
  project's m-edge friction cone (``quality.wrench_matrix``), balance the disturbance wrench:
  one linear program (SciPy HiGHS), at m = 8 (the project's default) and m = 32 (within 0.5%
  of Coulomb's circular cone; the 8-edge cone's mu* is at most 1/cos(pi/8) = 1.082 times
  Coulomb's);
* mu*_FC (three contacts) -- the smallest mu at which ``quality.ferrari_canny`` > 0 (m = 8),
  by bisection (0: in force closure at every mu > 0, the normal forces balance by themselves);
* in each simulator (``benchmarks/coulomb/scenes.py``: spheres on slide joints pressing
  along the normals, load ramped over 0.3 s, 1 s in all, 1 ms steps; slipped when the object
  moved more than 1 mm or turned more than 1 degree): the object's displacement and rotation
  at mu = 1.5 mu* and at mu = 0.67 mu*, and the simulator's own critical mu, bisected
  between those two (``--bisect`` steps).

    python benchmarks/coulomb_consistency.py [--bisect 7] [--simulators pybullet mujoco]
        [--json-out benchmarks/results/coulomb_consistency.json] [--no-readme]

It also writes its table into README.md (between ``<!-- coulomb-consistency:start -->`` and
``<!-- coulomb-consistency:end -->``).

About 1 s per grasp and simulator without bisection, ~5 s with 7 steps.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from coulomb.grasps import CoulombGrasp, closure_mu, coulomb_grasps, resist_mu
from coulomb.scenes import (
    SIMULATORS,
    SLIP_ANGLE,
    SLIP_DISTANCE,
    TEST_TIME,
    TIME_STEP,
)
from marked_section import write_between

#: Friction factors of the two checks (resist at HIGH mu*, slip at LOW mu*).
HIGH, LOW = 1.5, 0.67
#: The README section this script writes.
START, END = "<!-- coulomb-consistency:start -->", "<!-- coulomb-consistency:end -->"


def simulated_critical_mu(simulate, grasp: CoulombGrasp, low: float, high: float,
                          steps: int) -> float:
    """The simulator's critical mu between ``low`` (slips) and ``high`` (resists), bisected
    ``steps`` times: the midpoint of the last bracket."""
    for _ in range(steps):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if simulate(grasp, mid).slipped else (low, mid)
    return 0.5 * (low + high)


def grasp_row(grasp: CoulombGrasp, simulators: list[str], bisect: int) -> dict:
    """Everything the benchmark reports of one grasp (JSON-ready)."""
    mu = resist_mu(grasp, 8)
    row: dict = {"description": grasp.description, "contacts": len(grasp.points),
                 "mu_star": mu, "mu_star_m32": resist_mu(grasp, 32),
                 "mu_fc": closure_mu(grasp, 8) if len(grasp.points) >= 3 else None}
    for name in simulators:
        simulate = SIMULATORS[name]
        high, low = simulate(grasp, HIGH * mu), simulate(grasp, LOW * mu)
        record = {"resisted_at_1.5": not high.slipped,
                  "disp_mm_at_1.5": high.displacement * 1e3,
                  "turn_deg_at_1.5": math.degrees(high.rotation),
                  "slipped_at_0.67": low.slipped,
                  "disp_mm_at_0.67": low.displacement * 1e3,
                  "turn_deg_at_0.67": math.degrees(low.rotation)}
        if bisect and low.slipped and not high.slipped:
            critical = simulated_critical_mu(simulate, grasp, LOW * mu, HIGH * mu, bisect)
            record["sim_mu_star"] = critical
            record["sim_over_mu_star"] = critical / mu
        row[name] = record
    return row


def table(rows: dict[str, dict], simulators: list[str]) -> str:
    """The printed table: one line per grasp and simulator."""
    head = (f"{'grasp':16s} {'k':>1s} {'mu*':>7s} {'mu*32':>7s} {'mu*FC':>7s} {'sim':9s} "
            f"{'resist@1.5':>10s} {'mm':>8s} {'deg':>6s} {'slip@0.67':>9s} {'mm':>9s} "
            f"{'deg':>6s} {'sim mu*':>8s} {'ratio':>6s}")
    lines = [head, "-" * len(head)]
    for name, row in rows.items():
        fc = "-" if row["mu_fc"] is None else f"{row['mu_fc']:.4f}"
        for sim in simulators:
            r = row[sim]
            critical = r.get("sim_mu_star")
            lines.append(
                f"{name:16s} {row['contacts']:1d} {row['mu_star']:7.4f} "
                f"{row['mu_star_m32']:7.4f} {fc:>7s} {sim:9s} "
                f"{'yes' if r['resisted_at_1.5'] else 'NO':>10s} {r['disp_mm_at_1.5']:8.4f} "
                f"{r['turn_deg_at_1.5']:6.3f} {'yes' if r['slipped_at_0.67'] else 'NO':>9s} "
                f"{r['disp_mm_at_0.67']:9.1f} {r['turn_deg_at_0.67']:6.2f} "
                + ("       -      -" if critical is None
                   else f"{critical:8.4f} {r['sim_over_mu_star']:6.3f}"))
    return "\n".join(lines)


def markdown(rows: dict[str, dict], simulators: list[str]) -> str:
    """The README table: per grasp and simulator, resisted at 1.5 mu* (displacement),
    slipped at 0.67 mu*, the simulator's critical mu."""
    lines = ["| grasp | k | mu* | mu*32 | mu*FC | simulator | resists at 1.5 mu* | "
             "slips at 0.67 mu* | simulated critical mu |", "|---" * 9 + "|"]
    for name, row in rows.items():
        fc = "-" if row["mu_fc"] is None else f"{row['mu_fc']:.3f}"
        for sim in simulators:
            r = row[sim]
            critical = r.get("sim_mu_star")
            lines.append(
                f"| {name} | {row['contacts']} | {row['mu_star']:.4f} | "
                f"{row['mu_star_m32']:.4f} | {fc} | {sim} | "
                f"{'yes' if r['resisted_at_1.5'] else 'NO'} ({r['disp_mm_at_1.5']:.3f} mm, "
                f"{r['turn_deg_at_1.5']:.2f} deg) | {'yes' if r['slipped_at_0.67'] else 'NO'} | "
                + ("-" if critical is None else f"{critical:.4f}") + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--simulators", nargs="+", default=list(SIMULATORS),
                        choices=list(SIMULATORS))
    parser.add_argument("--bisect", type=int, default=7,
                        help="bisection steps of each simulator's critical mu (0: none)")
    parser.add_argument("--json-out", type=Path,
                        default=Path(__file__).resolve().parent / "results"
                        / "coulomb_consistency.json")
    parser.add_argument("--readme", type=Path,
                        default=Path(__file__).resolve().parents[1] / "docs/guides/physics.md",
                        help="write the table into this file between its markers")
    parser.add_argument("--no-readme", action="store_true")
    args = parser.parse_args(argv)
    if args.bisect < 0:
        parser.error(f"--bisect must be >= 0, got {args.bisect}")
    rows: dict[str, dict] = {}
    start = time.perf_counter()
    for grasp in coulomb_grasps():
        rows[grasp.name] = grasp_row(grasp, args.simulators, args.bisect)
        print(f"[{time.perf_counter() - start:6.1f} s] {grasp.name} done", file=sys.stderr)
    print(table(rows, args.simulators))
    passed = all(row[s]["resisted_at_1.5"] and row[s]["slipped_at_0.67"]
                 for row in rows.values() for s in args.simulators)
    print(f"\nresist at {HIGH} mu* and slip at {LOW} mu* in every grasp and simulator: "
          f"{'yes' if passed else 'NO'} (slip: > {SLIP_DISTANCE * 1e3:g} mm or "
          f"> {math.degrees(SLIP_ANGLE):g} deg after {TEST_TIME:g} s)")
    result = {"time_step_s": TIME_STEP, "test_time_s": TEST_TIME,
              "slip_distance_mm": SLIP_DISTANCE * 1e3, "slip_angle_deg": math.degrees(SLIP_ANGLE),
              "all_resist_high_slip_low": passed}
    for name, row in rows.items():
        for sim in args.simulators:
            flat = {k: v for k, v in row.items() if k not in SIMULATORS}
            result[f"{name} / {sim}"] = {**flat, **row[sim]}
    args.json_out.parent.mkdir(parents=True, exist_ok=True)
    args.json_out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {args.json_out}", file=sys.stderr)
    if not args.no_readme:
        write_between(args.readme, START, END, markdown(rows, args.simulators))
    return 0 if passed else 1


if __name__ == "__main__":
    raise SystemExit(main())
