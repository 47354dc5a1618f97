"""The user's object catalog: importing a mesh or URDF, removing an entry.

:func:`import_object` checks the settings, name and density
(:mod:`~kinegrasp_env.world.import_settings`), reads the file
(:mod:`~kinegrasp_env.world.meshfile`), scales it to metres, cleans it and checks that the
hand could hold it (:mod:`~kinegrasp_env.world.meshprep`), moves it to the object frame
(origin at the centre of its base), decomposes it into convex parts with CoACD
(:mod:`~kinegrasp_env.world.decompose`), measures the parts' deviation from the mesh
(:mod:`~kinegrasp_env.world.deviation`), builds the fast engine's distance grid
(:mod:`~kinegrasp_env.world.sdf`) and stores everything as one entry
(:mod:`~kinegrasp_env.world.store`).

Atomicity: the entry is built in a hidden folder inside the catalog folder and renamed into
place at the end, so a half-imported object never appears (a killed import leaves only a
hidden ``.tmp-<name>-<pid>-*`` folder, removed by the next import once its process is gone).
Replacing an entry (``force``) renames the old one aside (``.old-...``) first and deletes it
after; removing one renames it to ``.rm-...`` and deletes that.

Re-import: an entry is keyed by the SHA-256 of the files read and the settings; importing
the same files with the same settings (the scale to within
:data:`~kinegrasp_env.world.import_settings.SCALE_RTOL`, relative) reuses the entry, other
settings need ``force``.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import tempfile
import time
import uuid
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import trimesh

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.world import objects, sdf
from kinegrasp_env.world.decompose import (
    COACD_SEED,
    HULL_TOLERANCE,
    MAX_HULL_VERTICES,
    decompose,
    mass_properties,
)
from kinegrasp_env.world.deviation import deviation
from kinegrasp_env.world.import_settings import (
    UP_ROTATIONS,
    ImportSettings,
    check_density,
    check_name,
    default_name,
    entry_key,
    same_import,
    source_digest,
)
from kinegrasp_env.world.meshfile import MeshError, SourceMesh, load_source
from kinegrasp_env.world.meshprep import (
    check_not_tiny,
    check_size,
    check_solid,
    clean_mesh,
    object_frame,
    open_edges,
)
from kinegrasp_env.world.store import (
    ENTRY_FILE,
    FORMAT_VERSION,
    MESH_FILE,
    PARTS_FILE,
    CatalogError,
    catalog_dir,
    imported_folder,
    imported_names,
    read_entry,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ImportResult:
    """What :func:`import_object` did.

    Attributes:
        name: the object's name.
        folder: its entry folder.
        reused: True when an entry of the same files and settings was already there.
        seconds: wall time of the import (0 when reused).
        entry: the entry's ``entry.json``.
    """

    name: str
    folder: Path
    reused: bool
    seconds: float
    entry: dict


#: The stages of an import after reading and cleaning the mesh, in order (``progress``).
STAGES = ("convex decomposition (CoACD; the long stage)",
          "deviation of the parts from the mesh", "distance grid of the fast engine")


def set_density(folder: Path, entry: dict, density: float) -> dict:
    """The entry with its ``density`` (kg/m^3) set, rewritten in place (atomically)."""
    entry = {**entry, "density": density}
    write_atomic(folder / ENTRY_FILE, json.dumps(entry, indent=1))
    forget()
    return entry


def import_object(path: str | Path, name: str | None = None,
                  settings: ImportSettings | None = None, force: bool = False,
                  progress: Callable[[int, str], None] | None = None,
                  density: float | None = None) -> ImportResult:
    """Import a mesh file or URDF as catalog object ``name`` (default: from the file name).

    ``progress(k, stage)`` is called as stage ``k`` of :data:`STAGES` begins (for a progress
    display; an open or non-manifold mesh is logged as a warning before, by
    :func:`prepare`). ``density`` (kg/m^3; default the catalog's
    :data:`~kinegrasp_env.world.objects.DEFAULT_DENSITY`) gives the object's mass with its
    volume; it is no import setting: given for an entry already imported from the same files
    with the same settings, it is set on that entry (nothing else is redone).

    Raises:
        MeshError: the file cannot be read, is not a solid, or is too large or too small for
            the hand (the message suggests ``--scale``/``--units``).
        CatalogError: bad name, settings or density, or ``name`` exists with other files or
            settings and ``force`` is False.
    """
    start = time.perf_counter()
    settings = (settings or ImportSettings()).check()
    density = check_density(density)
    name = check_name(default_name(path) if name is None else name)
    source = load_source(path)
    digest = source_digest(source)
    key = entry_key(digest, settings)
    existing = imported_folder(name)
    if existing is not None and not force:
        entry = read_entry(existing)
        if same_import(entry, digest, settings):
            if density is not None and entry.get("density") != density:
                entry = set_density(existing, entry, density)
            return ImportResult(name, existing, True, 0.0, entry)
        stored = entry.get("settings", {})
        given = {k: stored.get(k, v) for k, v in asdict(ImportSettings()).items()}
        raise CatalogError(f"object {name!r} already exists (from "
                           f"{entry.get('source', {}).get('path', '?')}, settings {given}); "
                           "add --force to replace it, or give another --name")
    prepared = prepare(source, settings.scale, Path(path), settings.up)
    root = catalog_dir()
    root.mkdir(parents=True, exist_ok=True)
    remove_stale(root)
    work = Path(tempfile.mkdtemp(prefix=f".tmp-{name}-{os.getpid()}-", dir=root))
    try:
        entry = build_entry(source, prepared, name, key, settings, work, Path(path),
                            progress or (lambda k, stage: None))
        if density is not None:
            entry["density"] = density
        entry["import_seconds"] = round(time.perf_counter() - start, 3)
        (work / ENTRY_FILE).write_text(json.dumps(entry, indent=1))
        publish(work, root / name)
    finally:
        if work.exists():
            shutil.rmtree(work, ignore_errors=True)
    forget()
    return ImportResult(name, root / name, False, entry["import_seconds"], entry)


@dataclass(frozen=True)
class Prepared:
    """A mesh ready to decompose.

    Attributes:
        mesh: cleaned, metres, object frame.
        thickness: its smallest width (metres).
        frame: (4, 4) move from the scaled source frame to the object frame (the up
            axis turned into +z, then the translation to the base centre).
    """

    mesh: trimesh.Trimesh
    thickness: float
    frame: np.ndarray


def prepare(source: SourceMesh, scale: float, path: Path, up: str = "z") -> Prepared:
    """Scale, turn (``up``: the file's up axis becomes +z), clean, check and place the
    source mesh; :class:`MeshError` naming ``path`` when it is no solid or does not suit the
    hand."""
    rotation = UP_ROTATIONS[up]
    try:
        vertices = source.vertices * scale @ rotation.T
        used = vertices[np.unique(source.faces)] if len(source.faces) else vertices
        if len(used):
            check_not_tiny(np.ptp(used, axis=0), scale)
        mesh = clean_mesh(vertices, source.faces)
        width = check_solid(mesh)
        check_size(mesh, width, scale)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None
    boundary, nonmanifold = open_edges(mesh)
    if boundary or nonmanifold:
        log.warning("%s: the mesh is not closed (%d edges on a hole or an open border, %d "
                    "shared by more than two faces); the decomposition first remeshes it into "
                    "a closed solid, which is slow (minutes for a few triangles) and can give "
                    "many small parts that fill the holes or thicken an open surface; check "
                    "the result with `kinegrasp objects show NAME --plot parts.png`, or close "
                    "the mesh first for a truer object", path, boundary, nonmanifold)
    frame = object_frame(mesh)
    mesh.apply_transform(frame)
    turn = np.eye(4)
    turn[:3, :3] = rotation
    return Prepared(mesh, width, frame @ turn)


def build_entry(source: SourceMesh, prepared: Prepared, name: str, key: str,
                settings: ImportSettings, work: Path, path: Path,
                progress: Callable[[int, str], None]) -> dict:
    """Decompose, measure and write the entry's files into ``work`` (``progress(k, stage)``
    as each of :data:`STAGES` begins); returns the ``entry.json`` contents."""
    mesh, width, frame = prepared.mesh, prepared.thickness, prepared.frame
    mesh.export(work / MESH_FILE, file_type="obj", include_normals=False,
                include_texture=False)
    progress(0, STAGES[0])
    parts = decompose(mesh, settings.threshold, settings.max_parts)
    if not parts:
        raise MeshError(f"{path}: the convex decomposition found no solid part")
    com, r_max, volume = mass_properties(parts)
    progress(1, STAGES[1])
    dev = deviation(mesh, parts)
    (work / PARTS_FILE).write_text(json.dumps({"parts": [p.tolist() for p in parts]}))
    obj = objects.object_from_parts(name, mesh, parts, com, r_max)
    progress(2, STAGES[2])
    grid_name = sdf.grid_file_name(obj)
    sdf.save_grid(sdf.build_grid(obj), work / grid_name)
    to_object = frame.copy()
    to_object[:3, :3] *= settings.scale
    return {
        "format": FORMAT_VERSION, "name": name, "key": key,
        "source": {"path": str(path.resolve()), "description": source.description,
                   "sha256": source_digest(source)},
        "settings": {**asdict(settings), "seed": COACD_SEED,
                     "max_hull_vertices": MAX_HULL_VERTICES, "hull_tolerance": HULL_TOLERANCE},
        "source_to_object": to_object.tolist(), "pose": None,
        "center_of_mass": com.tolist(), "r_max": r_max, "volume": volume,
        "size": np.asarray(mesh.extents, dtype=float).tolist(), "thickness": width,
        "faces": len(mesh.faces), "parts": len(parts), "deviation": dev.to_dict(),
        "grid": grid_name, "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        # unique per import: the entry's version (world.store.entry_digest) changes with every
        # re-import, even one within the same second with the same settings
        "import_id": uuid.uuid4().hex,
        "versions": versions(),
    }


def versions() -> dict:
    """Versions of the libraries an entry depends on (for the record)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for package in ("coacd", "trimesh"):
        with contextlib.suppress(PackageNotFoundError):
            out[package] = version(package)
    return out


def publish(work: Path, final: Path) -> None:
    """Rename the finished folder ``work`` to ``final``, replacing an existing entry (moved
    aside first, deleted after)."""
    old = None
    if final.exists():
        old = final.with_name(f".old-{final.name}-{os.getpid()}-{work.name[-8:]}")
        os.rename(final, old)
    os.rename(work, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def remove_object(name: str) -> Path:
    """Delete an imported object's entry (renamed aside, then deleted); returns its folder.

    Raises:
        CatalogError: a built-in or unknown name, or an object placed copies stand for.
    """
    if name in objects.OBJECT_NAMES:
        raise CatalogError(f"{name!r} is a built-in object and cannot be removed")
    folder = imported_folder(name)
    if folder is None:
        imported = objects.object_names()[len(objects.OBJECT_NAMES):]
        raise CatalogError(f"no imported object named {name!r}; imported: "
                           f"{', '.join(imported) or 'none'}")
    placed = [other for other in imported_names()
              if other != name and _stands_for(other) == name]
    if placed:
        raise CatalogError(f"{name!r} is the object that the placed object(s) "
                           f"{', '.join(placed)} stand for; remove them first "
                           f"(`kinegrasp objects remove {placed[0]}`)")
    trash = folder.with_name(f".rm-{name}-{os.getpid()}-{time.time_ns()}")
    os.rename(folder, trash)
    shutil.rmtree(trash, ignore_errors=True)
    forget()
    return folder


def _stands_for(name: str) -> str | None:
    """The object a placed copy ``name`` stands for (None: not a placed copy, or an entry
    that cannot be read, which does not keep another object from being removed)."""
    try:
        return read_entry(imported_folder(name)).get("base")
    except CatalogError:
        return None


def remove_stale(root: Path) -> None:
    """Delete hidden work folders left by imports whose process is gone; put back an entry
    whose replacement was interrupted between its two renames."""
    for folder in root.glob(".*-*-*-*"):
        kind, _, rest = folder.name[1:].partition("-")
        fields = rest.rsplit("-", 2)
        if kind not in ("tmp", "old", "rm") or len(fields) != 3 or not fields[1].isdigit() \
                or process_alive(int(fields[1])):
            continue
        name = fields[0]
        if kind == "old" and not (root / name).exists():
            os.rename(folder, root / name)
        else:
            shutil.rmtree(folder, ignore_errors=True)


def process_alive(pid: int) -> bool:
    """Whether a process with this id runs (this user's or not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def forget() -> None:
    """Drop this process's cached objects and grids (after the catalog changed; they are
    keyed by the entry's version, so this only frees memory)."""
    objects.imported_object.cache_clear()
    sdf.grid_of.cache_clear()
