"""Where the meshes a robot's URDF references lie, resolved as URDF readers do.

A mesh path is relative to the URDF's folder, absolute (or ``file://``), or
``package://NAME/rest``: through the description's ``packages`` when they name NAME, else a
folder NAME beside the URDF or beside any folder above it (or a folder above it named NAME).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path


class MeshNotFound(ValueError):
    """A mesh the URDF references that is not found: ``key`` is the description key to fix
    (``packages`` for a ``package://`` path, else ``urdf``)."""

    def __init__(self, key: str, problem: str):
        super().__init__(problem)
        self.key = key


@dataclass(frozen=True)
class MeshFile:
    """A mesh the URDF references: ``link``'s ``filename`` (as written), found at ``path``."""

    link: str
    filename: str
    path: Path


def resolve_mesh(filename: str, urdf: Path, packages: dict[str, Path]) -> Path | None:
    """Where a URDF's mesh ``filename`` lies, or None when no candidate file exists."""
    if filename.startswith("file://"):
        filename = filename[len("file://"):]
    if filename.startswith("package://"):
        pkg, _, rest = filename[len("package://"):].partition("/")
        if pkg in packages:
            candidates = [packages[pkg] / rest]
        else:
            folders = [urdf.parent, *urdf.parent.parents]
            candidates = [c for d in folders
                          for c in ((d / pkg / rest),) + (((d / rest),) if d.name == pkg else ())]
    else:
        candidates = [Path(filename) if Path(filename).is_absolute() else urdf.parent / filename]
    return next((c.resolve() for c in candidates if c.is_file()), None)


def urdf_meshes(urdf: Path, packages: dict[str, Path]) -> tuple[MeshFile, ...]:
    """Every mesh file the links of ``urdf`` reference, resolved.

    Raises:
        MeshNotFound: a mesh file that is not found (named).
    """
    out = []
    for link in ET.parse(urdf).getroot().findall("link"):
        for mesh in link.iter("mesh"):
            filename = mesh.get("filename", "")
            found = resolve_mesh(filename, urdf, packages)
            if found is None:
                key = "packages" if filename.startswith("package://") else "urdf"
                raise MeshNotFound(key, f"mesh {filename!r} of link {link.get('name')!r} in "
                                   f"{urdf.name} not found")
            out.append(MeshFile(link.get("name"), filename, found))
    return tuple(out)


def collision_links(urdf: Path) -> frozenset[str]:
    """The names of the links of ``urdf`` that have collision geometry (a ``<collision>``
    element with a ``<geometry>``)."""
    return frozenset(link.get("name") for link in ET.parse(urdf).getroot().findall("link")
                     if any(c.find("geometry") is not None for c in link.findall("collision")))
