"""The holding test of the shipped grasps at sigma 0, as the physics guide shows it.

    kinegrasp validate --object cube --sigma 0 --samples 1 --out out/hold_sigma0/cube
    kinegrasp validate --object drill --sigma 0 --samples 1 --out out/hold_sigma0/drill
    python scripts/hold_sigma0_table.py out/hold_sigma0/cube out/hold_sigma0/drill

Reads each folder's ``draws.csv`` (one draw per grasp: the nominal grasp) and writes, into
``docs/guides/physics.md`` between ``<!-- hold-sigma0:start -->`` and
``<!-- hold-sigma0:end -->`` (``--page``; ``--print`` only prints): per grasp its kinematic
and physics outcome, the holding outcome, the grip's own shift and turn of the object on
release, the force the pin carried, each phase's result; then per object the held / run
count of each phase, and the largest grip shift over the grasps in force closure whose grip
stood.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from marked_section import write_between  # noqa: E402

from kinegrasp_env.physics.protocol import GRAVITY_PHASES, REST_PHASE  # noqa: E402

START, END = "<!-- hold-sigma0:start -->", "<!-- hold-sigma0:end -->"
PHASE_COLUMNS = (REST_PHASE, *GRAVITY_PHASES, "lift")
#: A grip that lost a contact, or none at all: no reference pose, no shift bound applies.
NO_STANDING_GRIP = ("no_grip", "grip_lost", "start_collision")


def mark(value: str) -> str:
    """One phase's digit: 1 held, 0 failed, - not run."""
    return {"held": "1", "not_run": "-"}.get(value, "0")


def closed(outcome: str) -> str:
    """yes for a force-closure outcome, else the outcome."""
    return "yes" if outcome == "force_closure" else outcome


def table(folders: list[Path]) -> str:
    """The Markdown of the module docstring."""
    lines = ["| grasp | FC kinematic / physics | outcome | grip shift mm | grip turn deg | "
             "pin force N | phases held |", "|---|---|---|---|---|---|---|"]
    notes = []
    for folder in folders:
        rows = list(csv.DictReader((folder / "draws.csv").open(newline="")))
        counts = {p: [0, 0] for p in PHASE_COLUMNS}
        standing = []
        for r in rows:
            lines.append(
                f"| {r['object']} {r['grasp']} | {closed(r['kinematic_outcome'])} / "
                f"{closed(r['physics_outcome'])} | {r['hold_outcome']} | "
                f"{float(r['grip_shift_mm']):.2f} | {float(r['grip_turn_deg']):.2f} | "
                f"{float(r['pin_force_n']):.1f} | `"
                + "".join(mark(r[p]) for p in PHASE_COLUMNS) + "` |")
            for p in PHASE_COLUMNS:
                if r[p] != "not_run":
                    counts[p][1] += 1
                    counts[p][0] += r[p] == "held"
            if (r["physics_outcome"] == "force_closure"
                    and r["hold_outcome"] not in NO_STANDING_GRIP):
                standing.append(float(r["grip_shift_mm"]))
        name = rows[0]["object"]
        held = sum(r["hold_outcome"] == "held" for r in rows)
        phases = ", ".join(f"{p} {h}/{n}" for p, (h, n) in counts.items())
        notes.append(f"{name}: {held} of {len(rows)} held; phases held / run: {phases}; "
                     f"largest grip shift over the {len(standing)} force-closure grasps whose "
                     f"grip stood: {max(standing, default=float('nan')):.2f} mm.")
    legend = ("Phases held: one digit per phase in the order rest, gravity +x, -x, +y, -y, +z, "
              "-z, lift (1 held, 0 failed, - not run).")
    return "\n".join(lines) + "\n\n" + legend + "\n\n" + "\n\n".join(notes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="+", type=Path, help="`kinegrasp validate --out` folders")
    parser.add_argument("--page", type=Path, default=ROOT / "docs" / "guides" / "physics.md")
    parser.add_argument("--print", action="store_true", help="print only")
    args = parser.parse_args()
    body = table(args.folders)
    print(body)
    if not args.print:
        write_between(args.page, START, END, body)


if __name__ == "__main__":
    main()
