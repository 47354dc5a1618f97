"""The layout of the Python API reference: which page renders which object. ``gen_api.py``
writes the pages from it; ``sphinx_roles.py`` (the griffe extension that turns the docstrings'
Sphinx roles into links) links only to what it says is rendered.

The lists come from the package itself (each room's lazy export table or ``__all__``), so a name a
room adds or drops shows up here at the next build.
"""

from __future__ import annotations

import importlib
import importlib.util

from kinegrasp_env.lazy import defining_modules

PACKAGE = "kinegrasp_env"
ROOMS = ("sampling", "quality", "robot", "world", "closing", "physics", "montecarlo",
         "toolkit", "envs", "cli")
#: Rooms inside a room: documented on their parent's page, in a section of their own.
SUBROOMS = {"toolkit": ("report",)}
#: Names the package exports that the top page lists in prose, not as rendered objects.
UNRENDERED_TOP = ("ENV_IDS", "__version__")


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


def rooms() -> list[str]:
    """The rooms that exist (each has a page ``reference/api/<room>.md``)."""
    return [room for room in ROOMS if importlib.util.find_spec(f"{PACKAGE}.{room}")]


def room_packages(room: str) -> list[str]:
    """The packages a room's page documents, in page order: the room, then its subrooms."""
    return [f"{PACKAGE}.{room}", *(f"{PACKAGE}.{room}.{sub}" for sub in SUBROOMS.get(room, ()))]


def top_names() -> dict[str, str]:
    """The names the package exports (those the top page tables) -> their defining module."""
    return {name: module for name, module in exports(PACKAGE).items()
            if name not in UNRENDERED_TOP}


def placement() -> dict[tuple[str, str], str]:
    """Where each room page renders a name: (defining module, name) -> room."""
    return {(module, name): room for room in rooms() for package in room_packages(room)
            for name, module in exports(package).items()}


def directives() -> dict[str, bool]:
    """Every ``::: identifier`` the API pages hold -> whether it renders its members (the
    packages themselves are rendered for their docstring only: ``members: false``)."""
    found = {PACKAGE: False}
    for room in rooms():
        for package in room_packages(room):
            found[package] = False
            found.update({f"{module}.{name}": True
                          for name, module in exports(package).items()
                          if not name.startswith("__")})
    placed = placement()
    found.update({f"{module}.{name}": True for name, module in top_names().items()
                  if (module, name) not in placed})
    return found


def public_paths() -> dict[str, str]:
    """Each exported name under the package's public path -> where it is defined, e.g.
    ``kinegrasp_env.quality.ferrari_canny`` -> ``kinegrasp_env.quality.epsilon.ferrari_canny``
    (the rooms' exports are lazy: a static reading of the package does not see them)."""
    found = {}
    for package in [PACKAGE, *(p for room in rooms() for p in room_packages(room))]:
        found.update({f"{package}.{name}": f"{module}.{name}"
                      for name, module in exports(package).items()
                      if f"{package}.{name}" != f"{module}.{name}"})
    return found
