"""The paper's numbers beside this project's, cell by cell, as markdown.

Run: ``python scripts/paper_side_by_side.py --table1 out/paper/table1 --fig7 out/tour/fig7
--fig10 out/paper/fig10 [--out FILE]``: the folders ``kinegrasp reproduce table1|fig7|fig10``
wrote (any of them may be left out). The paper's values come from ``docs/paper_values.yaml``,
each with its source; a cell whose paper value is not there says "not available here". The
project's numbers are read from the CSVs as they are: nothing is computed here beyond
formatting, so the table shows what the commands printed.
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
MISSING = "not available here"


def read_rows(path: Path) -> list[dict]:
    """A CSV's rows (strings), or a one-line error naming the missing file."""
    if not path.is_file():
        raise SystemExit(f"paper_side_by_side: {path} not found (run the reproduce command "
                         "that writes it first)")
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def num(text: str | None, digits: int = 3, style: str = "f") -> str:
    """A CSV number as text ("n/a" for empty or NaN)."""
    if text in (None, ""):
        return "n/a"
    value = float(text)
    return "n/a" if math.isnan(value) else f"{value:.{digits}{style}}"


def paper(value, source: str | None, sources: dict) -> str:
    """A paper value with its source marker, or :data:`MISSING`."""
    if value is None:
        return MISSING
    return f"{value:.2f} [{source}]" if source in sources else f"{value:.2f}"


def table1_section(rows: list[dict], spec: dict) -> list[str]:
    """Table I: per grasp and sigma, the paper's and this project's Q mean, Q variance and
    P(FC) (with its Wilson 95% interval)."""
    cells = spec.get("cells") or {}
    samples = {r["samples"] for r in rows}
    lines = [f"**Table I** ({spec['object']}, grasps 0-{spec['grasps'] - 1} here, "
             f"{'/'.join(sorted(samples))} draws per cell here; Q moments over the "
             "force-closure draws)", "",
             "| grasp | sigma (rad) | Q mean: paper | here | Q variance: paper | here | "
             "P(FC): paper | here [95% CI] |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        theirs = cells.get(f"{r['grasp']}@{r['sigma']}", {}) if cells else {}
        lines.append(
            f"| {r['grasp']} | {float(r['sigma']):g} | {theirs.get('q_mean', MISSING)} | "
            f"{num(r['q_mean'], 4, 'g')} | {theirs.get('q_var', MISSING)} | "
            f"{num(r['q_var'], 3, 'g')} | {theirs.get('p_fc', MISSING)} | "
            f"{num(r['p_fc'])} [{num(r['p_fc_lo'])}, {num(r['p_fc_hi'])}] |")
    return lines


def _pair(rows: list[dict], name: str, p_fc: str, lo: str, hi: str) -> dict[str, str]:
    """robust / fragile P(FC) text and the paired gap of one object's chosen pair."""
    chosen = {r["config"]: r for r in rows if r["object"] == name and r.get("config")}
    if set(chosen) != {"robust", "fragile"}:
        return {}
    out = {k: f"{num(r[p_fc])} [{num(r[lo])}, {num(r[hi])}] (id {r['id']})"
           for k, r in chosen.items()}
    r = chosen["fragile"]
    out["gap"] = (f"{float(r['gap']):+.3f} (no discordant draw)" if r["gap_lo"] == r["gap_hi"]
                  else f"{float(r['gap']):+.3f} [{float(r['gap_lo']):+.3f}, "
                       f"{float(r['gap_hi']):+.3f}]")
    out["samples"] = r.get("fresh_samples") or r["samples"]
    out["sigma"] = r.get("sigma") or "?"
    out["moments"] = {k: f"{num(c['q_mean'], 4, 'g')} / {num(c['q_var'], 3, 'g')} / "
                         f"{num(c['q_skew'], 3, 'g')}"
                      for k, c in chosen.items() if "q_var" in c}
    return out


def pairs_section(fig7: list[dict] | None, fig10: list[dict] | None, values: dict,
                  sources: dict) -> list[str]:
    """Two arm configurations with the same contacts: the paper's pair and Fig. 7's and
    Fig. 10's here, each chosen on selection draws and reported on fresh draws."""
    names = sorted({r["object"] for r in (fig7 or []) + (fig10 or [])})
    pairs = values.get("pairs") or {}
    lines = ["**Same contacts, two arm configurations** (P(FC) of the more and the less "
             "robust; here chosen on one set of draws and reported on as many fresh draws, "
             "95% Wilson intervals, the gap paired on the same draws)", "",
             "| object | quantity | paper | Fig. 7 here | Fig. 10 here |", "|---|---|---|---|---|"]
    for name in names:
        seven = _pair(fig7 or [], name, "p_fc", "p_fc_lo", "p_fc_hi")
        ten = _pair(fig10 or [], name, "fresh_p_fc", "fresh_p_fc_lo", "fresh_p_fc_hi")
        theirs = pairs.get(name, {})
        src = theirs.get("source")
        for key, label in (("robust", "robust P(FC)"), ("fragile", "fragile P(FC)")):
            lines.append(f"| {name} | {label} | {paper(theirs.get(key + '_p_fc'), src, sources)}"
                         f" | {seven.get(key, '-')} | {ten.get(key, '-')} |")
        gap = (theirs["robust_p_fc"] - theirs["fragile_p_fc"]
               if "robust_p_fc" in theirs and "fragile_p_fc" in theirs else None)
        lines.append(f"| {name} | robust - fragile | {paper(gap, src, sources)} | "
                     f"{seven.get('gap', '-')} | {ten.get('gap', '-')} |")
        for key in ("robust", "fragile"):
            if key in seven.get("moments", {}):
                moments = values.get("fig7_q_moments") or MISSING
                lines.append(f"| {name} | Q mean / var / skew, {key} | {moments} | "
                             f"{seven['moments'][key]} | - |")
        lines.append(f"| {name} | sigma (rad), fresh draws per configuration | {MISSING} | "
                     f"{seven.get('sigma', '-')}, {seven.get('samples', '-')} | "
                     f"{ten.get('sigma', '-')}, {ten.get('samples', '-')} |")
    return lines


def side_by_side(table1: Path | None, fig7: Path | None, fig10: Path | None,
                 values_path: Path = VALUES) -> str:
    """The whole markdown: the sections whose folders are given, the sources, the
    differences."""
    values = yaml.safe_load(values_path.read_text())
    sources = values.get("sources") or {}
    where = values_path.relative_to(ROOT) if values_path.is_relative_to(ROOT) else values_path
    parts = [f"The paper: {values['paper']}. Its values below are those in `{where}` "
             f"(sources in brackets); \"{MISSING}\" marks a cell whose paper value could not "
             "be found.", ""]
    if table1 is not None:
        parts += [*table1_section(read_rows(table1 / "table1.csv"), values["table1"]), ""]
    if fig7 is not None or fig10 is not None:
        parts += [*pairs_section(read_rows(fig7 / "fig7.csv") if fig7 else None,
                                 read_rows(fig10 / "fig10.csv") if fig10 else None, values,
                                 sources), ""]
    if values.get("fig9") is None:
        parts += [f"Fig. 9 (ten grasps per object): the paper's values are {MISSING}.", ""]
    parts += ["Sources:", ""]
    parts += [f"- [{k}] {' '.join(v.split())}" for k, v in sources.items()] + [""]
    parts += ["What differs between the paper's runs and these:", ""]
    parts += [f"- **{k}**: {' '.join(v.split())}" for k, v in values["differences"].items()]
    return "\n".join(parts) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table1", type=Path, help="`reproduce table1`'s output folder")
    parser.add_argument("--fig7", type=Path, help="`reproduce fig7`'s output folder")
    parser.add_argument("--fig10", type=Path, help="`reproduce fig10`'s output folder")
    parser.add_argument("--values", type=Path, default=VALUES, help="the paper's values")
    parser.add_argument("--out", type=Path, help="write the markdown here (default: stdout)")
    args = parser.parse_args(argv)
    text = side_by_side(args.table1, args.fig7, args.fig10, args.values)
    if args.out:
        args.out.write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
