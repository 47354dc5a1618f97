"""The paper's numbers beside this project's, cell by cell, as markdown.

Run: ``python scripts/paper_side_by_side.py --table1 out/paper/table1 --fig7 out/paper/fig7
--fig10 out/paper/fig10 [--physics out/paper/table1_physics100 --physics-kinematic
out/paper/table1_fast100] [--fig7-physics out/paper/fig7_physics100 --fig7-kinematic
out/paper/fig7_fast100] [--only summary pairs] [--out FILE]``: the folders ``kinegrasp
reproduce table1|fig7|fig10`` wrote (any of them may be left out). ``--physics`` is a
``reproduce table1 --engine physics`` run and ``--physics-kinematic`` the kinematic run at its
draw count and seed (the same draws), likewise ``--fig7-physics`` and ``--fig7-kinematic``
for ``reproduce fig7``. The paper's values come from ``docs/paper_values.yaml``, each with its
source; a cell whose paper value the paper does not give says so. The project's numbers are
read from the CSVs as they are: nothing is computed here beyond formatting, the
differences of two shown numbers, and the per-noise-level summaries over Table I's five
grasps (mean, lowest and highest of the shown cells).
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
VALUES = ROOT / "docs" / "paper_values.yaml"
NOT_GIVEN = "not given"
SECTIONS = ("table1", "summary", "pairs", "notes")


def read_rows(path: Path) -> list[dict]:
    """A CSV's rows (strings), or a one-line error naming the missing file."""
    if not path.is_file():
        raise SystemExit(f"paper_side_by_side: {path} not found (run the reproduce command "
                         "that writes it first)")
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def num(text: str | float | None, digits: int = 3, style: str = "f") -> str:
    """A CSV number as text ("n/a" for empty or NaN)."""
    if text is None or text == "":
        return "n/a"
    value = float(text)
    return "n/a" if math.isnan(value) else f"{value:.{digits}{style}}"


def _key(sigma: str | float) -> str:
    """A noise level as a lookup key (CSV text and YAML floats alike)."""
    return f"{float(sigma):g}"


def _by_cell(rows: list[dict] | None) -> dict[tuple[int, str], dict]:
    """Table I rows keyed by (grasp, sigma)."""
    return {(int(r["grasp"]), _key(r["sigma"])): r for r in rows or []}


def _samples(rows: list[dict] | None) -> str:
    """The draw count(s) of a run's rows, as text."""
    return "/".join(sorted({r["samples"] for r in rows or []}, key=int)) or "-"


def paper_cells(spec: dict) -> dict[tuple[int, str], dict[str, float]]:
    """The paper's Table I cells keyed by (paper grasp number, sigma)."""
    names = spec.get("quantities") or ["q_mean", "q_var", "p_fc"]
    return {(int(grasp), _key(sigma)): dict(zip(names, values, strict=True))
            for grasp, per_sigma in (spec.get("cells") or {}).items()
            for sigma, values in per_sigma.items()}


def table1_section(rows: list[dict], spec: dict, physics: list[dict] | None = None,
                   same: list[dict] | None = None) -> list[str]:
    """Table I: per grasp and sigma, the paper's and this project's Q mean, Q variance and
    P(FC) (with its Wilson 95% interval), and with a physics run, its P(FC) beside the
    kinematic engine's on the same draws."""
    theirs = paper_cells(spec)
    phys, kin = _by_cell(physics), _by_cell(same)
    head = ("| grasp: paper / here | sigma (rad) | Q mean: paper | here | Q variance: paper | "
            "here | P(FC): paper | here [95% CI] |")
    rule = "|---|---|---|---|---|---|---|---|"
    if physics:
        head += " P(FC) here, physics / kinematic, same draws |"
        rule += "---|"
    lines = [f"**Table I** ({spec['object']}; paper: its Table I, Sec. IV-B.4, "
             f"{spec.get('samples', '?')} draws per cell, grasps 1-{spec['grasps']}; here: "
             f"shipped grasps 0-{spec['grasps'] - 1}, {_samples(rows)} draws per cell, "
             "kinematic engine"
             + (f", physics engine {_samples(physics)} draws per cell" if physics else "")
             + "; rows pair the two grasp sets by position only, they are different grasps; "
             "Q moments over the force-closure draws)", "", head, rule]
    for r in rows:
        grasp, sigma = int(r["grasp"]), _key(r["sigma"])
        paper = theirs.get((grasp + 1, sigma), {})
        line = (f"| {grasp + 1} / {grasp} | {sigma} | {num(paper.get('q_mean'), 6)} | "
                f"{num(r['q_mean'], 4, 'g')} | {num(paper.get('q_var'), 6)} | "
                f"{num(r['q_var'], 3, 'g')} | {num(paper.get('p_fc'), 4)} | "
                f"{num(r['p_fc'])} [{num(r['p_fc_lo'])}, {num(r['p_fc_hi'])}] |")
        if physics:
            p, k = phys.get((grasp, sigma)), kin.get((grasp, sigma))
            line += (f" {num(p['p_fc']) if p else '-'} / {num(k['p_fc']) if k else '-'} |")
        lines.append(line)
    return lines


def _spread(values: list[float], digits: int = 3, style: str = "f") -> str:
    """mean (lowest-highest) of some shown numbers."""
    values = [v for v in values if not math.isnan(v)]
    if not values:
        return "-"
    return (f"{num(sum(values) / len(values), digits, style)} "
            f"({num(min(values), digits, style)}-{num(max(values), digits, style)})")


def summary_section(rows: list[dict], spec: dict, physics: list[dict] | None = None,
                    same: list[dict] | None = None) -> list[str]:
    """Per noise level, over the five grasps of each side: P(FC) and Q mean, mean (lowest-
    highest); with a physics run, its P(FC) and the kinematic engine's on the same draws."""
    theirs = paper_cells(spec)
    sigmas = [_key(s) for s in spec["sigmas"]]
    head = "| sigma (rad) | P(FC): paper | here, kinematic |"
    rule = "|---|---|---|"
    if physics:
        head += (f" here, physics ({_samples(physics)} draws) | here, kinematic, same "
                 f"{_samples(same)} draws |")
        rule += "---|---|"
    head += " Q mean: paper | here, kinematic |"
    rule += "---|---|"
    lines = [f"**Table I, per noise level** ({spec['object']}, mean over the "
             f"{spec['grasps']} grasps of each side, lowest-highest in brackets; here "
             f"{_samples(rows)} draws per cell unless stated)", "", head, rule]
    for sigma in sigmas:
        paper = [c for (_, s), c in theirs.items() if s == sigma]
        here = [r for r in rows if _key(r["sigma"]) == sigma]
        line = (f"| {sigma} | {_spread([c['p_fc'] for c in paper])} | "
                f"{_spread([float(r['p_fc']) for r in here])} |")
        if physics:
            for run in (physics, same or []):
                shown = [float(r["p_fc"]) for r in run if _key(r["sigma"]) == sigma]
                line += f" {_spread(shown)} |"
        line += (f" {_spread([c['q_mean'] for c in paper], 3, 'g')} | "
                 f"{_spread([float(r['q_mean']) for r in here], 3, 'g')} |")
        lines.append(line)
    return lines


def _pair(rows: list[dict], name: str) -> dict:
    """robust / fragile P(FC) text (fresh draws), the paired gap and the Q moments of one
    object's chosen pair."""
    chosen = {r["config"]: r for r in rows if r["object"] == name and r.get("config")}
    if set(chosen) != {"robust", "fragile"}:
        return {}
    out = {k: f"{num(r['fresh_p_fc'])} [{num(r['fresh_p_fc_lo'])}, "
              f"{num(r['fresh_p_fc_hi'])}] (id {r['id']}, {variant_words(r)})"
           for k, r in chosen.items()}
    r = chosen["fragile"]
    out["gap"] = (f"{float(r['gap']):+.3f} (no discordant draw)" if r["gap_lo"] == r["gap_hi"]
                  else f"{float(r['gap']):+.3f} [{float(r['gap_lo']):+.3f}, "
                       f"{float(r['gap_hi']):+.3f}]")
    out["samples"] = r.get("fresh_samples") or r["samples"]
    out["sigma"] = r.get("sigma") or "?"
    for key, digits in (("q_mean", 4), ("q_var", 3), ("q_skew", 3)):
        if all(c.get(f"fresh_{key}") not in (None, "") for c in chosen.values()):
            out[key] = " / ".join(num(chosen[c][f"fresh_{key}"], digits, "g")
                                  for c in ("robust", "fragile"))
    return out


def variant_words(row: dict) -> str:
    """A variant row's configuration: its elbow angle (radians) or its IK branch."""
    if row.get("ik_branch"):
        return f"IK branch {row['ik_branch']}"
    return f"elbow {float(row['elbow_angle']):+.2f} rad"


def _listed(values: list | None, digits: int, absent: str = NOT_GIVEN) -> str:
    """The paper's two values in the text's order, or ``absent``."""
    if not values:
        return absent
    return " / ".join(f"{v:.{digits}f}" for v in values) + " (as listed)"


def pairs_section(fig7: list[dict] | None, fig10: list[dict] | None, values: dict,
                  physics: list[dict] | None = None, kinematic: list[dict] | None = None,
                  paper_rows_only: bool = False) -> list[str]:
    """Two arm configurations with the same contacts: the paper's Fig. 7 pair and Fig. 7's
    and Fig. 10's here, each chosen on selection draws and reported on fresh draws; with a
    physics run of Fig. 7, its pair and the kinematic engine's at the same draw count.
    ``paper_rows_only``: only the rows with a paper value."""
    spec = values.get("fig7") or {}
    pairs = spec.get("objects") or {}
    names = sorted({r["object"] for r in (fig7 or []) + (fig10 or [])} | set(pairs))
    head = "| object | quantity | paper (Fig. 7) | Fig. 7 here | Fig. 10 here |"
    rule = "|---|---|---|---|---|"
    if physics:
        head += " Fig. 7 here, physics | Fig. 7 here, kinematic, same seed and draw count |"
        rule += "---|---|"
    lines = [f"**Same contacts, two arm configurations** (P(FC) of the more and the less "
             f"robust; paper: the text on its Fig. 7, Sec. IV-B.3, {spec.get('samples', '?')} "
             "draws each; here chosen on one set of draws and reported on as many fresh draws, "
             "95% Wilson intervals, the gap paired on the same draws; Q moments robust / "
             "fragile here, over the force-closure draws)", "", head, rule]
    for name in names:
        runs = [_pair(fig7 or [], name), _pair(fig10 or [], name)]
        if physics:
            runs += [_pair(physics, name), _pair(kinematic or [], name)]
        if name not in pairs and paper_rows_only:
            continue
        absent = NOT_GIVEN if name in pairs else "not in its Fig. 7"
        paper = pairs.get(name, {})
        robust, fragile = paper.get("robust_p_fc"), paper.get("fragile_p_fc")
        gap = (f"{robust - fragile:+.2f}" if robust is not None and fragile is not None
               else absent)
        rows = [("robust P(FC)", num(robust, 2) if robust is not None else absent,
                 "robust"),
                ("fragile P(FC)", num(fragile, 2) if fragile is not None else absent,
                 "fragile"),
                ("robust - fragile", gap, "gap"),
                ("Q mean", _listed(paper.get("q_mean"), 4, absent), "q_mean"),
                ("Q variance", _listed(paper.get("q_var"), 4, absent), "q_var"),
                ("Q skewness", absent, "q_skew")]
        for label, theirs, key in rows:
            if key.startswith("q_") and not any(key in run for run in runs):
                continue
            if paper_rows_only and theirs == absent:
                continue
            lines.append(f"| {name} | {label} | {theirs} | "
                         + " | ".join(run.get(key, "-") for run in runs) + " |")
        sigma = spec.get("sigma")
        theirs = (f"{sigma if sigma is not None else NOT_GIVEN}, {spec.get('samples', '?')}"
                  if name in pairs else absent)
        lines.append(f"| {name} | sigma (rad), fresh draws per configuration | {theirs} | "
                     + " | ".join(f"{run.get('sigma', '-')}, {run.get('samples', '-')}"
                                  for run in runs) + " |")
    return lines


def side_by_side(table1: Path | None, fig7: Path | None, fig10: Path | None,
                 values_path: Path = VALUES, *, physics: Path | None = None,
                 physics_kinematic: Path | None = None, fig7_physics: Path | None = None,
                 fig7_kinematic: Path | None = None, only: tuple[str, ...] = SECTIONS,
                 paper_rows_only: bool = False) -> str:
    """The markdown: the sections whose folders are given (of those in ``only``), the
    sources, the differences."""
    values = yaml.safe_load(values_path.read_text())
    sources = values.get("sources") or {}
    where = values_path.relative_to(ROOT) if values_path.is_relative_to(ROOT) else values_path
    parts = [f"The paper: {values['paper']}. Its values below are read from its text "
             f"(`{where}`, each with the table or figure and section it comes from); "
             f"\"{NOT_GIVEN}\" marks a value the paper does not state.", ""]
    if table1 is not None:
        rows = read_rows(table1 / "table1.csv")
        phys = read_rows(physics / "table1.csv") if physics else None
        same = read_rows(physics_kinematic / "table1.csv") if physics_kinematic else None
        if "table1" in only:
            parts += [*table1_section(rows, values["table1"], phys, same), ""]
        if "summary" in only:
            parts += [*summary_section(rows, values["table1"], phys, same), ""]
    if "pairs" in only and (fig7 is not None or fig10 is not None):
        parts += [*pairs_section(
            read_rows(fig7 / "fig7.csv") if fig7 else None,
            read_rows(fig10 / "fig10.csv") if fig10 else None, values,
            read_rows(fig7_physics / "fig7.csv") if fig7_physics else None,
            read_rows(fig7_kinematic / "fig7.csv") if fig7_kinematic else None,
            paper_rows_only), ""]
    if "notes" in only:
        if values.get("fig9") is None and values.get("fig10") is None:
            parts += ["Figs. 9 and 10 (ten grasps per object): the paper shows them as plots "
                      f"only; their values are {NOT_GIVEN} in its text.", ""]
        parts += ["Sources:", ""]
        parts += [f"- [{k}] {' '.join(v.split())}" for k, v in sources.items()] + [""]
        parts += ["What differs between the paper's runs and these:", ""]
        parts += [f"- **{k}**: {' '.join(v.split())}" for k, v in values["differences"].items()]
    return "\n".join(parts).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table1", type=Path, help="`reproduce table1`'s output folder")
    parser.add_argument("--physics", type=Path,
                        help="`reproduce table1 --engine physics`'s output folder")
    parser.add_argument("--physics-kinematic", type=Path,
                        help="`reproduce table1` at the physics run's draw count and seed")
    parser.add_argument("--fig7", type=Path, help="`reproduce fig7`'s output folder")
    parser.add_argument("--fig7-physics", type=Path,
                        help="`reproduce fig7 --engine physics`'s output folder")
    parser.add_argument("--fig7-kinematic", type=Path,
                        help="`reproduce fig7` at the physics run's draw count and seed")
    parser.add_argument("--fig10", type=Path, help="`reproduce fig10`'s output folder")
    parser.add_argument("--values", type=Path, default=VALUES, help="the paper's values")
    parser.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS),
                        help="the sections to write (default: all)")
    parser.add_argument("--paper-rows-only", action="store_true",
                        help="in the pairs table, only the rows with a paper value")
    parser.add_argument("--out", type=Path, help="write the markdown here (default: stdout)")
    args = parser.parse_args(argv)
    text = side_by_side(args.table1, args.fig7, args.fig10, args.values,
                        physics=args.physics, physics_kinematic=args.physics_kinematic,
                        fig7_physics=args.fig7_physics, fig7_kinematic=args.fig7_kinematic,
                        only=tuple(args.only), paper_rows_only=args.paper_rows_only)
    if args.out:
        args.out.write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
