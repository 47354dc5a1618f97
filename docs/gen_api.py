"""Write the Python API reference pages (``reference/api/*.md``): the package's public face
(the names ``kinegrasp_env/__init__`` exports) and, for each room of the package, the public
names its ``__init__`` exports, each rendered by mkdocstrings from its docstring.

The lists come from the package itself (each room's lazy export table or ``__all__``), so a name a
room adds or drops shows up here at the next build.
"""

from __future__ import annotations

import importlib

import mkdocs_gen_files

import kinegrasp_env
from kinegrasp_env.lazy import defining_modules

ROOMS = ("sampling", "quality", "robot", "world", "closing", "physics", "montecarlo",
         "toolkit", "envs", "cli")
#: Rooms inside a room: documented on their parent's page, in a section of their own.
SUBROOMS = {"toolkit": ("report",)}


def exports(package: str) -> dict[str, str]:
    """Public name -> the dotted path of the module that defines it, for ``package``."""
    module = importlib.import_module(package)
    lazy = defining_modules(module)
    if lazy is not None:
        return {name: f"{package}.{sub}" for name, sub in lazy.items()}
    found = {}
    for name in getattr(module, "__all__", ()):
        value = getattr(module, name)
        found[name] = getattr(value, "__module__", package)
    return found


def room_page(package: str, title: str, names: dict[str, str], level: int = 1) -> str:
    lines = [f"{'#' * level} {title}", "", f"::: {package}", "    options:",
             "      members: false", "      show_root_heading: false", ""]
    for name, module in names.items():
        if name.startswith("__"):
            continue
        lines += [f"::: {module}.{name}", ""]
    return "\n".join(lines)


def first_line(module: str, name: str) -> str:
    """The first sentence of a public name's docstring."""
    doc = getattr(importlib.import_module(module), name).__doc__ or ""
    text = " ".join(doc.strip().split("\n\n")[0].split())
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


rooms = [room for room in ROOMS if importlib.util.find_spec(f"kinegrasp_env.{room}")]
index = ["# Python API", "",
         "Generated from the docstrings. Start from the names the package exports (the first "
         "page); each room of the package (a sub-package with one concern) has its own page "
         "with the public names its `__init__` exports. Imports point only down the layers "
         "(`cli`; `envs`, `toolkit`; `montecarlo`; `physics`, `closing`; `world`; `robot`; "
         "`quality`, `sampling`).", "",
         "| page | what it holds |", "|---|---|",
         "| [`kinegrasp_env`](kinegrasp_env.md) | the names a user starts from |"]
top = {name: module for name, module in exports("kinegrasp_env").items()
       if name not in ("ENV_IDS", "__version__")}
#: Where each room page renders a name: (module, name) -> room.
rendered = {(module, name): room for room in rooms
            for package in (room, *(f"{room}.{sub}" for sub in SUBROOMS.get(room, ())))
            for name, module in exports(f"kinegrasp_env.{package}").items()}
with mkdocs_gen_files.open("reference/api/kinegrasp_env.md", "w") as handle:
    handle.write(top_page(top, rendered))
for room in rooms:
    package = f"kinegrasp_env.{room}"
    doc = (importlib.import_module(package).__doc__ or "").strip().split("\n\n")[0]
    index.append(f"| [`{package}`]({room}.md) | {' '.join(doc.split()).replace('|', '/')} |")
    with mkdocs_gen_files.open(f"reference/api/{room}.md", "w") as handle:
        handle.write(room_page(package, package, exports(package)))
        for sub in SUBROOMS.get(room, ()):
            inner = f"{package}.{sub}"
            handle.write("\n" + room_page(inner, inner, exports(inner), level=2))
with mkdocs_gen_files.open("reference/api/index.md", "w") as handle:
    handle.write("\n".join(index) + "\n")
