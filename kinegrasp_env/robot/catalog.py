"""The robot catalog: the built-in robots and the ones a user adds.

Built in (``assets/robots``): ``kuka_sdh`` (the default: the KUKA iiwa with the SDH-like
hand) and ``panda`` (the Franka Panda with its parallel-jaw hand). A user's robots live in
``<data_root>/robots`` (:func:`kinegrasp_env.paths.data_root`: ``$KINEGRASP_HOME`` or the
platform's user data folder), one folder per robot, named as the robot:

- ``robot.yaml``: the description (:mod:`kinegrasp_env.robot.description`), its ``urdf``
  pointing inside the folder, no ``packages`` (none needed);
- ``source.yaml``: the user's description file, byte for byte;
- ``files/``: the URDF and every mesh it references (OBJ material files too): a
  ``package://NAME/...`` mesh in the folder ``NAME`` beside the URDF, a relative one where
  it was (below the URDF's folder); the copied URDF is rewritten only for meshes given by
  an absolute path or one climbing above its folder (:func:`_copy_plan`), so pybullet loads
  it as it is, and for collision shapes on a link fixed below a finger's moving link, which
  go onto that link (:mod:`~kinegrasp_env.robot.fixed_collisions`: the file is then
  written anew, its comments kept); the user's files are never changed;
- ``entry.json``: the name, the source file, the copied files and the collision shapes
  moved (``moved_collisions``: pad link -> finger link).

An entry appears complete or not at all: it is written in a hidden folder (``.tmp-...``) and
renamed into place after the copy is read back and checked.
"""

from __future__ import annotations

import difflib
import json
import posixpath
import shutil
import tempfile
from pathlib import Path

from kinegrasp_env.assets import asset_path
from kinegrasp_env.paths import data_root
from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.robot.description import (
    RobotDescription,
    RobotDescriptionError,
    load_description,
)
from kinegrasp_env.robot.fixed_collisions import move_fixed_collisions

#: Built-in robots: name -> the description's path parts under ``assets/``.
BUILTIN: dict[str, tuple[str, ...]] = {
    "kuka_sdh": ("robots", "kuka_sdh.yaml"),
    "panda": ("robots", "panda", "panda.yaml"),
}
ENTRY_FILE = "entry.json"
DESCRIPTION_FILE = "robot.yaml"
SOURCE_FILE = "source.yaml"
FORMAT_VERSION = 1


def robots_dir() -> Path:
    """The folder holding one sub-folder per user robot (not created here)."""
    return data_root() / "robots"


def user_names() -> tuple[str, ...]:
    """Names of the user's robots, sorted."""
    root = robots_dir()
    if not root.is_dir():
        return ()
    return tuple(sorted(p.name for p in root.iterdir()
                        if not p.name.startswith(".") and (p / DESCRIPTION_FILE).is_file()))


def robot_names() -> tuple[str, ...]:
    """Every robot: the built-in ones, then the user's."""
    return (*BUILTIN, *user_names())


def description_path(name: str) -> Path:
    """The description file of robot ``name``.

    Raises:
        RobotDescriptionError: no robot of that name.
    """
    if name in BUILTIN:
        return asset_path(*BUILTIN[name])
    if isinstance(name, str) and not name.startswith(".") and "/" not in name:
        path = robots_dir() / name / DESCRIPTION_FILE
        if path.is_file():
            return path
    raise unknown_robot(name)


def unknown_robot(name) -> RobotDescriptionError:
    """The one-line error of a name that is no catalog robot (the nearest name suggested)."""
    names = robot_names()
    close = difflib.get_close_matches(str(name), names, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return RobotDescriptionError(f"unknown robot {name!r}{hint}; known robots: "
                                 f"{', '.join(names)}")


def check_robot_name(robot) -> str:
    """``robot`` when it names a catalog robot, else :func:`unknown_robot`'s error."""
    if not isinstance(robot, str) or robot not in robot_names():
        raise unknown_robot(robot)
    return robot


#: Descriptions read in this process: path -> (the files' stamps, the description).
_READ: dict[Path, tuple[tuple, RobotDescription]] = {}


def _stamp(*paths: Path) -> tuple:
    """What tells a file changed: each path's modification time (ns) and size."""
    return tuple((s.st_mtime_ns, s.st_size) for s in (p.stat() for p in paths))


def load_robot(name: str = DEFAULT_ROBOT) -> RobotDescription:
    """The checked description of a built-in or user robot, read once per process while its
    description and URDF files stay unchanged.

    Raises:
        RobotDescriptionError: unknown name, or an entry that no longer checks out.
    """
    path = description_path(name)
    held = _READ.get(path)
    try:
        if held is not None and held[0] == _stamp(path, held[1].urdf):
            return held[1]
    except OSError:
        pass  # a file gone: read again, which names it
    description = load_description(path)
    _READ[path] = (_stamp(path, description.urdf), description)
    return description


def as_description(robot: str | RobotDescription) -> RobotDescription:
    """``robot`` itself, or the description of the catalog robot it names (:func:`load_robot`).

    Raises:
        TypeError: neither a name nor a description (one line, naming the value).
        RobotDescriptionError: an unknown name.
    """
    if isinstance(robot, RobotDescription):
        return robot
    if isinstance(robot, str):
        return load_robot(robot)
    raise TypeError(f"robot must be a catalog robot's name or a RobotDescription, got "
                    f"{type(robot).__name__} {robot!r:.60}")


def catalog_rows() -> list[dict]:
    """One row per robot: name, source (built-in/user), arm DOF, hand joints, palm link,
    fingertips, contact model, description file."""
    rows = []
    for name in robot_names():
        try:
            d = load_robot(name)
        except RobotDescriptionError as exc:
            raise RobotDescriptionError(f"robot {name!r} no longer checks out ({exc}); remove "
                                        f"it with `kinegrasp robots remove {name}`") from None
        rows.append({"name": name, "source": "built-in" if name in BUILTIN else "user",
                     "arm_dof": d.arm_dof, "hand_joints": list(d.hand_joints),
                     "palm_link": d.palm_link, "fingertips": list(d.fingertip_links),
                     "contact_model": d.contact_model, "description": str(d.path)})
    return rows


def _copy_plan(description: RobotDescription) -> tuple[dict[str, Path], dict[str, str]]:
    """What goes into an entry's ``files/`` folder: (destination relative to it -> source
    file, mesh filename as written -> the filename the copied URDF gives instead).

    A ``package://NAME/rest`` mesh goes to ``NAME/rest`` (a package folder beside the URDF:
    found by this module's resolver and by pybullet alike); a relative path that stays below
    the URDF's folder keeps its place; any other (absolute, ``file://``, or climbing above the
    URDF's folder with ``..``) goes to ``external/<k>/<file name>`` and is rewritten. An OBJ
    mesh's material files (``mtllib``) that exist go beside its copy, and so do the texture
    images they name (:data:`TEXTURE_STATEMENTS`): without them pybullet prints a warning on
    stdout for every mesh it loads.

    Raises:
        RobotDescriptionError: two different files would land on one destination.
    """
    plan: dict[str, Path] = {}
    rewrites: dict[str, str] = {}

    def put(dest: str, source: Path) -> None:
        if plan.setdefault(dest, source) != source:
            raise RobotDescriptionError(f"{description.path.name}: urdf: {plan[dest]} and "
                                        f"{source} would both be copied to {dest}")

    for mesh in description.meshes:
        written = mesh.filename
        if written.startswith("package://"):
            dest = posixpath.normpath(written[len("package://"):])
        else:
            dest = posixpath.normpath(written.removeprefix("file://"))
            if posixpath.isabs(dest) or dest.startswith(".."):
                dest = rewrites.get(written) or f"external/{len(rewrites)}/{mesh.path.name}"
                rewrites[written] = dest
        put(dest, mesh.path)
        if mesh.path.suffix.lower() == ".obj":
            for mtl_dest, mtl in _beside(dest, mesh.path, _referenced(mesh.path, ("mtllib",))):
                put(mtl_dest, mtl)
                for image_dest, image in _beside(mtl_dest, mtl,
                                                 _referenced(mtl, TEXTURE_STATEMENTS)):
                    put(image_dest, image)
    return plan, rewrites


def _beside(dest: str, source: Path, names: list[str]) -> list[tuple[str, Path]]:
    """(destination, file) of each file ``names`` that a file copied from ``source`` to
    ``dest`` names relative to its own folder and that exists; a name that is absolute or
    climbs above the copy's folder stays as written (the copy does not move it)."""
    out = []
    for name in names:
        target = posixpath.normpath(posixpath.join(posixpath.dirname(dest), name))
        found = source.parent / name
        if not posixpath.isabs(name) and not target.startswith("..") and found.is_file():
            out.append((target, found.resolve()))
    return out


#: The statements of an OBJ material file that name a texture image (its last word).
TEXTURE_STATEMENTS = ("map_Ka", "map_Kd", "map_Ks", "map_Ns", "map_d", "map_bump", "bump",
                      "disp", "decal", "norm")


def _referenced(path: Path, statements: tuple[str, ...]) -> list[str]:
    """The file names that lines of ``path`` (an OBJ mesh or material file) starting with
    one of ``statements`` name (each line's last word: options may come before it)."""
    names = []
    for line in path.read_text(errors="replace").splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] in statements:
            names.append(words[-1] if words[0] != "mtllib" else line.split(None, 1)[1].strip())
    return names


def add_robot(path: str | Path, *, force: bool = False) -> tuple[RobotDescription, Path]:
    """Check the description at ``path`` and copy it, its URDF and meshes into the catalog.

    Args:
        path: the user's description YAML.
        force: replace a user robot of the same name.

    Returns:
        (the stored robot's description, its folder).

    Raises:
        RobotDescriptionError: a bad description, a built-in name, or a name taken (without
            ``force``); the catalog is untouched.
    """
    import yaml

    source = Path(path)
    pads: list[tuple[str, str]] = []
    description = load_description(source, fixed_pads=pads)
    name = description.name
    if name in BUILTIN:
        raise RobotDescriptionError(f"{source.name}: name: {name!r} is a built-in robot; "
                                    "choose another name")
    folder = robots_dir() / name
    if folder.exists() and not force:
        raise RobotDescriptionError(f"{source.name}: name: a robot {name!r} is already in the "
                                    f"catalog ({folder}); remove it first or use --force")
    plan, rewrites = _copy_plan(description)
    robots_dir().mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".tmp-{name}-", dir=robots_dir()))
    try:
        for dest, f in plan.items():
            target = tmp / "files" / dest
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(f, target)
        text = description.urdf.read_text()
        for written, dest in rewrites.items():
            text = text.replace(f'"{written}"', f'"{dest}"').replace(f"'{written}'", f"'{dest}'")
        if pads:
            text = move_fixed_collisions(text, description.model, pads)
        urdf_copy = tmp / "files" / description.urdf.name
        urdf_copy.parent.mkdir(exist_ok=True)  # a URDF of primitives alone copies no mesh
        urdf_copy.write_text(text)
        shutil.copyfile(source, tmp / SOURCE_FILE)
        data = yaml.safe_load(source.read_text())
        data["urdf"] = urdf_copy.relative_to(tmp).as_posix()
        data.pop("packages", None)  # the package folders lie beside the copied URDF
        (tmp / DESCRIPTION_FILE).write_text(yaml.safe_dump(data, sort_keys=False))
        (tmp / ENTRY_FILE).write_text(json.dumps({
            "format": FORMAT_VERSION, "name": name, "source": str(source.resolve()),
            "files": sorted(p.relative_to(tmp).as_posix() for p in tmp.rglob("*")
                            if p.is_file()),
            "moved_collisions": dict(pads)}, indent=1))
        try:
            load_description(tmp / DESCRIPTION_FILE)
        except RobotDescriptionError as exc:
            raise RobotDescriptionError(f"{source.name}: its files could not be copied "
                                        f"consistently ({exc})") from None
        if folder.exists():
            shutil.rmtree(folder)
        tmp.rename(folder)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return load_description(folder / DESCRIPTION_FILE), folder


def moved_collisions(folder: Path) -> dict[str, str]:
    """A user robot's collision shapes moved by ``robots add``: pad link -> the finger link
    they went onto (:mod:`~kinegrasp_env.robot.fixed_collisions`); empty for none."""
    entry = json.loads((Path(folder) / ENTRY_FILE).read_text())
    return dict(entry.get("moved_collisions", {}))


def remove_robot(name: str) -> Path:
    """Delete a user robot's folder; returns it.

    Raises:
        RobotDescriptionError: a built-in or unknown name.
    """
    if name in BUILTIN:
        raise RobotDescriptionError(f"{name!r} is a built-in robot and cannot be removed")
    path = description_path(name)
    shutil.rmtree(path.parent)
    return path.parent
