"""Write the benchmarks page (``reference/benchmarks.md``) from what the benchmark scripts
wrote: for every ``benchmarks/*.py``, its purpose (the script's docstring), the command, and
the tables of its JSON result ``benchmarks/results/<script>.json`` when one exists. A script
with no result file yet is listed as not run yet; no figure on the page is typed by hand.
"""

from __future__ import annotations

import ast
import json
import re
import sys
from pathlib import Path

import mkdocs_gen_files

DOCS = str(Path(__file__).resolve().parent)
if DOCS not in sys.path:  # the docs tooling's modules, beside this one
    sys.path.insert(0, DOCS)

from sphinx_roles import References  # noqa: E402

REFERENCES = References.load()

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "benchmarks"
RESULTS = SCRIPTS / "results"
#: Keys ``benchmarks/results_file.py`` adds to every result: the run's options and the
#: machine's facts, each rendered as a name/value table of its own after the figures.
META = ("settings", "machine")


def number(value: object) -> str:
    """A table cell for a JSON value: floats to 4 significant digits, the rest as JSON."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (int, str)):
        return str(value)
    return json.dumps(value, separators=(", ", ": "))[:120]


def cell(value: object) -> str:
    return " ".join(number(value).split()).replace("|", "\\|")


def table(rows: list[tuple[str, dict]], first: str) -> list[str]:
    """A Markdown table: one row per (label, record), columns the union of the records' keys."""
    columns: list[str] = []
    for _, record in rows:
        columns += [key for key in record if key not in columns]
    lines = [f"| {first} | " + " | ".join(cell(c) for c in columns) + " |",
             "|---" * (len(columns) + 1) + "|"]
    for label, record in rows:
        lines.append(f"| {cell(label)} | " + " | ".join(cell(record.get(c, "")) for c in columns)
                     + " |")
    return [*lines, ""]


def render(result: object) -> list[str]:
    """Tables of a JSON result: scalars as name/value rows, records (dicts) as table rows."""
    if isinstance(result, list):
        records = [r for r in result if isinstance(r, dict)]
        if records:
            return table([(str(i), flat(r)) for i, r in enumerate(records)], "#")
        return [f"`{cell(result)}`", ""]
    if not isinstance(result, dict):
        return [f"`{cell(result)}`", ""]
    meta = {k: result[k] for k in META if isinstance(result.get(k), dict)}
    result = {k: v for k, v in result.items() if k not in meta}
    scalars = [(k, {"value": v}) for k, v in result.items() if not isinstance(v, (dict, list))]
    records = [(k, flat(v)) for k, v in result.items() if isinstance(v, dict)]
    lines = table(scalars, "figure") if scalars else []
    if records:
        lines += table(records, "figure")
    for key, value in result.items():
        if isinstance(value, list):
            lines += [f"**{key}**", "", *render(value)]
    for key, value in meta.items():
        lines += [f"**{key}**", "",
                  *table([(k, {"value": v}) for k, v in flat(value).items()], "name")]
    return lines


def flat(record: dict, prefix: str = "") -> dict:
    """A record with nested dicts flattened into ``outer.inner`` keys."""
    out = {}
    for key, value in record.items():
        if isinstance(value, dict):
            out.update(flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def summary(script: Path) -> str:
    """The first paragraph of the script's docstring, reST literals as Markdown code and
    Sphinx roles as cross-references (``sphinx_roles.py``)."""
    doc = ast.get_docstring(ast.parse(script.read_text())) or ""
    text = " ".join(doc.split("\n\n")[0].split())
    return REFERENCES.markdown(re.sub(r"``([^`]+)``", r"`\1`", text))


def json_option(script: Path) -> str | None:
    """The option the script writes its JSON result with, if it has one."""
    source = script.read_text()
    if "from results_file import" in source:  # benchmarks/results_file.add_options
        return "--json-out"
    for option in ("--json-out", "--json"):
        if f'"{option}"' in source:
            return option
    return None


def benchmark_scripts() -> list[Path]:
    """The scripts of ``benchmarks/``, sorted: its modules that run as a program (a
    ``__main__`` block); the modules they share are not benchmarks."""
    return [script for script in sorted(SCRIPTS.glob("*.py"))
            if 'if __name__ == "__main__":' in script.read_text()]


def page() -> str:
    lines = ["# Benchmarks", "",
             "Speed and agreement scripts in `benchmarks/`. Each section below is rendered from "
             "the JSON result the script wrote into `benchmarks/results/<script>.json` on the "
             "machine and at the date of its last run; ratios are measured within one run. "
             "A script without a result file is listed as not run yet.", ""]
    for script in benchmark_scripts():
        result = RESULTS / f"{script.stem}.json"
        option = json_option(script)
        command = f"python benchmarks/{script.name}"
        if option:
            command += f" {option} benchmarks/results/{script.stem}.json"
        lines += [f"## {script.stem}", "", summary(script), "", "```bash", command, "```", ""]
        if result.is_file():
            lines += render(json.loads(result.read_text()))
        elif option:
            lines += ['!!! note "Not run yet"',
                      f"    No `benchmarks/results/{script.stem}.json`: run the command above.",
                      ""]
        else:
            lines += ['!!! note "Not run yet"',
                      "    This script prints its figures and writes no JSON result yet.", ""]
    return "\n".join(lines) + "\n"


with mkdocs_gen_files.open("reference/benchmarks.md", "w") as handle:
    handle.write(page())
