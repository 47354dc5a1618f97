"""Object commands: ``objects`` (list the built-in and imported objects), ``objects add``
(import a mesh or URDF), ``objects remove`` and ``objects show`` (draw the mesh and its parts).
"""

from __future__ import annotations

import json
import sys

from kinegrasp_env.cli.common import (
    CLIError,
    finite_float,
    plural,
    positive_float,
    positive_int,
    reported,
)
from kinegrasp_env.cli.output_paths import output_file
from kinegrasp_env.cli.placement import add_place_command, placement_note


def cmd_list(args) -> int:
    from kinegrasp_env.world.catalog_cache import cached_catalog
    from kinegrasp_env.world.store import CatalogError

    with reported(CatalogError):  # an unreadable entry (the message says how to fix it)
        rows = cached_catalog()
    if args.json:
        print(json.dumps(rows))
        return 0
    width = max(12, *(len(r["name"]) for r in rows))
    print(f"{'name':<{width}} {'size x, y, z [m]':<26} {'r_max [m]':>9} {'parts':>5}  "
          f"{'deviation [mm]: lost max/mean, added max/mean':<46} source")
    for r in rows:
        size = ", ".join(f"{v:.3f}" for v in r["size"])
        up = "" if r["up"] == "z" else f"; up axis {r['up']} (turned to z)"
        print(f"{r['name']:<{width}} {size:<26} {r['r_max']:>9.4f} {r['parts']:>5}  "
              f"{deviation_text(r['deviation']):<46} {r['source']}{up}{placement_note(r)}")
    return 0


def deviation_text(dev: dict | None) -> str:
    """``lost max/mean, added max/mean`` in millimetres (``exact`` for built-in objects)."""
    if dev is None:
        return "exact (parts = mesh)"
    mm = {k: 1000.0 * v for k, v in dev.items() if k != "samples"}
    return (f"{mm['missing_max']:.2f}/{mm['missing_mean']:.2f}, "
            f"{mm['added_max']:.2f}/{mm['added_mean']:.2f}")


def import_settings(args):
    """The :class:`~kinegrasp_env.world.import_settings.ImportSettings` of ``objects add``."""
    from kinegrasp_env.world.import_settings import UNITS, ImportSettings

    if args.scale is not None and args.units is not None:
        raise CLIError("give --scale or --units, not both")
    scale = UNITS[args.units] if args.units else (
        positive_float(args.scale, "--scale") if args.scale is not None else 1.0)
    threshold = finite_float(args.threshold, "--threshold")
    if not 0.01 <= threshold <= 1.0:
        raise CLIError(f"--threshold must be between 0.01 and 1, got {args.threshold}")
    return ImportSettings(scale, threshold, positive_int(args.max_parts, "--max-parts"),
                          args.up)


def cmd_add(args) -> int:
    from kinegrasp_env.world.importer import STAGES, CatalogError, MeshError, import_object

    settings = import_settings(args)
    if sys.stderr.isatty():  # a person waiting (off a terminal: a line per stage begun)
        print(f"importing {args.path} (scale {settings.scale:g}, up axis {settings.up}, "
              f"threshold {settings.threshold:g}, at most {settings.max_parts} parts)",
              file=sys.stderr)
    density = None if args.density is None else positive_float(args.density, "--density")
    with reported(MeshError, CatalogError), StageProgress(STAGES) as progress:
        result = import_object(args.path, args.name, settings, force=args.force,
                               progress=progress, density=density)
    entry = result.entry
    if result.reused:
        done = ("density set to " f"{density:g} kg/m^3" if density is not None
                else "nothing to do")
        print(f"{result.name}: already imported from this file with these settings "
              f"(entry {result.folder}); {done}")
        return 0
    size = ", ".join(f"{v:.3f}" for v in entry["size"])
    print(f"{result.name}: {plural(entry['parts'], 'convex part')}, size {size} m, r_max "
          f"{entry['r_max']:.4f} m, imported in {result.seconds:.1f} s")
    print(f"  deviation from the mesh [mm]: lost max/mean, added max/mean "
          f"{deviation_text(entry['deviation'])}")
    print(f"  stored in {result.folder}; use it with --object {result.name}")
    return 0


class StageProgress:
    """Progress of an import's stages on stderr: on a terminal one bar (stage k of n, what
    it is, the time it has run, refreshed every second: the decomposition can take
    minutes); elsewhere one line as each stage begins. Call it with ``(k, stage)``."""

    def __init__(self, stages: tuple[str, ...]) -> None:
        self.stages = stages
        self.bar = None
        self.stop = None

    def __call__(self, k: int, stage: str) -> None:
        if not sys.stderr.isatty():
            print(f"  stage {k + 1}/{len(self.stages)}: {stage}", file=sys.stderr, flush=True)
            return
        if self.bar is None:
            self._start()
        self.bar.n = k
        self.bar.set_description_str(f"  stage {k + 1}/{len(self.stages)}: {stage}")

    def _start(self) -> None:
        import threading

        from tqdm import tqdm

        self.bar = tqdm(total=len(self.stages), file=sys.stderr, leave=False,
                        bar_format="{desc} |{bar}| {elapsed} elapsed")
        self.stop = threading.Event()

        def tick() -> None:
            while not self.stop.wait(1.0):
                self.bar.refresh()

        threading.Thread(target=tick, daemon=True).start()

    def __enter__(self) -> StageProgress:
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.stop.set()
            self.bar.close()


def cmd_remove(args) -> int:
    from kinegrasp_env.world.importer import CatalogError, remove_object

    with reported(CatalogError):  # a built-in or unknown name
        folder = remove_object(args.name)
    print(f"{args.name} removed ({folder})")
    return 0


def cmd_show(args) -> int:
    from kinegrasp_env.toolkit.object_figure import plot_object
    from kinegrasp_env.world.objects import load_object

    output_file(args.plot, "--plot")
    with reported(ValueError):  # unknown name, unreadable entry
        obj = load_object(args.name)
    path = plot_object(obj, args.plot,
                       title=f"{obj.name}: {plural(len(obj.parts), 'convex part')}")
    print(f"{obj.name}: mesh and {plural(len(obj.parts), 'part')} drawn in {path}")
    return 0


#: ``objects add``'s defaults: equal to ``world.decompose.DEFAULT_THRESHOLD`` and
#: ``DEFAULT_MAX_PARTS`` (tested), copied so that building the parser imports no trimesh.
DEFAULT_THRESHOLD, DEFAULT_MAX_PARTS = 0.05, 32


def add_commands(sub) -> None:
    """Register ``objects`` and its actions ``add``, ``remove``, ``show``, ``place``."""
    p = sub.add_parser("objects", help="list the built-in and imported objects; import "
                       "(add), remove, draw (show) or place one (position, support table)")
    p.add_argument("--json", action="store_true", help="print the catalog as JSON")
    p.set_defaults(func=cmd_list)
    actions = p.add_subparsers(dest="action", metavar="{add,remove,show,place}")

    a = actions.add_parser("add", help="import a mesh (OBJ, STL, PLY, OFF, GLB/GLTF) or a URDF "
                           "(its first link's collision geometry) as an object")
    a.add_argument("path", help="the file to import")
    a.add_argument("--name", help="the object's name (default: from the file name)")
    a.add_argument("--scale", help="factor from the file's units to metres")
    a.add_argument("--units", choices=("mm", "cm", "m"), help="the file's units (instead of "
                   "--scale)")
    a.add_argument("--up", default="z", choices=("x", "y", "z"),
                   help="the file's up axis, turned into +z (many OBJ and glTF meshes are "
                   "y-up and would otherwise lie on their side)")
    a.add_argument("--threshold", default=str(DEFAULT_THRESHOLD),
                   help="CoACD concavity threshold, 0.01 .. 1 (smaller: more parts, closer to "
                   "the mesh)")
    a.add_argument("--max-parts", default=str(DEFAULT_MAX_PARTS),
                   help="most convex parts (each costs time in every draw)")
    a.add_argument("--density", metavar="KG_M3",
                   help="the object's uniform density, kg/m^3, which with its volume gives "
                   "the mass the hold scores and the simulators use (default 500); on an "
                   "object already imported from the same file and settings, it is set alone")
    a.add_argument("--force", action="store_true",
                   help="replace an object of the same name imported from another file or "
                   "with other settings")
    a.set_defaults(func=cmd_add)

    r = actions.add_parser("remove", help="delete an imported object")
    r.add_argument("name", help="the imported object's name")
    r.set_defaults(func=cmd_remove)

    s = actions.add_parser("show", help="draw an object's mesh and its convex parts (PNG)")
    s.add_argument("name", help="a built-in or imported object")
    s.add_argument("--plot", required=True, help="the PNG file to write")
    s.set_defaults(func=cmd_show)

    add_place_command(actions)
