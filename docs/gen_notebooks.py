"""Put the notebooks (``notebooks/*.ipynb``, with their committed outputs) into the site,
rendered by mkdocs-jupyter, and write their index page from each notebook's title cell."""

from __future__ import annotations

import json
from pathlib import Path

import mkdocs_gen_files

ROOT = Path(__file__).resolve().parents[1]


def title_and_summary(path: Path) -> tuple[str, str]:
    """The first Markdown cell's heading and its first paragraph after it."""
    cells = json.loads(path.read_text())["cells"]
    text = next(("".join(c["source"]) for c in cells if c["cell_type"] == "markdown"), "")
    lines = [line.strip() for line in text.splitlines()]
    title = next((line.lstrip("# ") for line in lines if line.startswith("#")), path.stem)
    body = [line for line in lines if line and not line.startswith("#")]
    summary = " ".join(body[:3]) if body else ""
    return title, summary


notebooks = sorted((ROOT / "notebooks").glob("*.ipynb"))
index = ["# Notebooks", "",
         "The paper's experiments and further studies, runnable top to bottom; shown here with "
         "the outputs of their last full run. They are generated and executed by "
         "`python notebooks/build_notebooks.py --execute [01 02 ...]`; every sample count is "
         "scaled by `KINEGRASP_NB_SCALE` (1.0 = the run shown).", "",
         "| notebook | what it shows |", "|---|---|"]
for path in notebooks:
    title, summary = title_and_summary(path)
    index.append(f"| [{title}]({path.name}) | {summary.replace('|', '/')} |")
    with mkdocs_gen_files.open(f"notebooks/{path.name}", "wb") as handle:
        handle.write(path.read_bytes())
with mkdocs_gen_files.open("notebooks/index.md", "w") as handle:
    handle.write("\n".join(index) + "\n")
