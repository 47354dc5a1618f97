"""Write the Python API reference pages (``reference/api/*.md``): the package's public face
(the names ``kinegrasp_env/__init__`` exports) and, for each room of the package, the public
names its ``__init__`` exports, each rendered by mkdocstrings from its docstring.

Which page renders which name is ``api_layout.py``'s (the lists come from the package itself:
each room's lazy export table or ``__all__``, so a name a room adds or drops shows up here at the
next build). The docstring text copied onto the pages (the summaries of the tables) has its
Sphinx roles rewritten as the griffe extension ``sphinx_roles.py`` rewrites those mkdocstrings
renders.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import mkdocs_gen_files

import kinegrasp_env

DOCS = str(Path(__file__).resolve().parent)
if DOCS not in sys.path:  # the docs tooling's modules, beside this one
    sys.path.insert(0, DOCS)

from api_layout import exports, placement, room_packages, rooms, top_names  # noqa: E402
from sphinx_roles import References  # noqa: E402

REFERENCES = References.load()


def room_page(package: str, title: str, names: dict[str, str], level: int = 1) -> str:
    lines = [f"{'#' * level} {title}", "", f"::: {package}", "    options:",
             "      members: false", "      show_root_heading: false", ""]
    for name, module in names.items():
        if name.startswith("__"):
            continue
        lines += [f"::: {module}.{name}", ""]
    return "\n".join(lines)


def first_line(module: str, name: str) -> str:
    """The first sentence of a public name's docstring, its Sphinx roles as cross-references."""
    doc = getattr(importlib.import_module(module), name).__doc__ or ""
    text = " ".join(doc.strip().split("\n\n")[0].split())
    text = REFERENCES.markdown(text, REFERENCES.find(f"{module}.{name}"))
    return text.replace("|", "/")


def top_page(top: dict[str, str], rendered: dict[tuple[str, str], str]) -> str:
    """The package's public face: each exported name with its summary, linked to the room page
    that documents it (rendered here when no room page does)."""
    lines = ["# kinegrasp_env", "", "::: kinegrasp_env", "    options:", "      members: false",
             "      show_root_heading: false", "", "## Exported names", "",
             "| name | defined in | what it is |", "|---|---|---|"]
    own = []
    for name, module in top.items():
        room = rendered.get((module, name))
        if room is None:
            own.append((name, module))
            link = f"[`{name}`](#{module}.{name})"
        else:
            link = f"[`{name}`]({room}.md#{module}.{name})"
        lines.append(f"| {link} | `{module}` | {first_line(module, name)} |")
    lines += ["", "`ENV_IDS`: the registered environment IDs, "
              + ", ".join(f"`{e}`" for e in kinegrasp_env.ENV_IDS) + ".", ""]
    for name, module in own:
        lines += [f"::: {module}.{name}", ""]
    return "\n".join(lines)


index = ["# Python API", "",
         "Generated from the docstrings. Start from the names the package exports (the first "
         "page); each room of the package (a sub-package with one concern) has its own page "
         "with the public names its `__init__` exports. Imports point only down the layers "
         "(`cli`; `envs`, `toolkit`; `montecarlo`; `physics`, `closing`; `world`; `robot`; "
         "`quality`, `sampling`).", "",
         "| page | what it holds |", "|---|---|",
         "| [`kinegrasp_env`](kinegrasp_env.md) | the names a user starts from |"]
with mkdocs_gen_files.open("reference/api/kinegrasp_env.md", "w") as handle:
    handle.write(top_page(top_names(), placement()))
for room in rooms():
    package, *subs = room_packages(room)
    doc = (importlib.import_module(package).__doc__ or "").strip().split("\n\n")[0]
    doc = REFERENCES.markdown(" ".join(doc.split()), REFERENCES.find(package))
    index.append(f"| [`{package}`]({room}.md) | {doc.replace('|', '/')} |")
    with mkdocs_gen_files.open(f"reference/api/{room}.md", "w") as handle:
        handle.write(room_page(package, package, exports(package)))
        for inner in subs:
            handle.write("\n" + room_page(inner, inner, exports(inner), level=2))
with mkdocs_gen_files.open("reference/api/index.md", "w") as handle:
    handle.write("\n".join(index) + "\n")
