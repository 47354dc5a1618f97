"""Prepare the open-world data of the elbow agent: import the objects of ``agents/heldout.yaml``
and plan their grasps with fixed seeds.

Example (the whole pipeline of the open-world evaluation):
    python agents/prepare.py
    python agents/train.py --grasp-file agents/grasps/train.json --name openworld
    python agents/evaluate.py --model agents/models/KineGraspSelect-v0_ppo_openworld.zip \
        --grasp-file agents/grasps/test.json --out agents/models/evaluation_openworld.json

Steps (idempotent: a second run reuses everything and changes no file):

1. Import ``random_urdfs/NNN/NNN.urdf`` of ``pybullet_data`` as catalog object ``blobNNN``
   (in ``$KINEGRASP_HOME`` when set, else the user's data folder) for every index of the
   spec's ``train`` and ``test`` lists, at the spec's ``scale`` with the importer's defaults.
   An entry of the same file and settings is reused.
2. Plan grasps of each with the sampler that planned the shipped sets
   (``scripts/sdh_grasp_sampler.py``'s ``GraspPlanner``), seed = the index, no time budget
   (deterministic), into ``agents/grasps/blobNNN.json``; a file already planned with the
   same object, count and seed is kept (``--replan`` plans again).
3. The spec's fallback: an index the importer refuses, or one the planner finds too few
   grasps for, is replaced by the next index (the replacement is printed and recorded in the
   set files; the spec's ``replaced`` must then name it).
4. Write ``agents/grasps/train.json`` (the built-in objects' training grasps, i % 4 != 3 of
   each shipped set, plus every grasp of the imported training objects) and
   ``agents/grasps/test.json`` (every grasp of the held-out objects).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SPEC = HERE / "heldout.yaml"
GRASPS = HERE / "grasps"
#: How far the fallback looks past an index before giving up.
MAX_FALLBACK = 20


class UsageError(ValueError):
    """A bad spec or argument (reported in one line, exit status 2)."""


def read_spec(path: Path = SPEC) -> dict:
    """The held-out spec: ``source``, ``scale``, ``train``/``test`` index lists and the grasp
    counts ``train_grasps``/``test_grasps``; UsageError names what is missing or bad."""
    import yaml

    if not path.is_file():
        raise UsageError(f"no spec file {path}")
    spec = yaml.safe_load(path.read_text()) or {}
    for key in ("train", "test"):
        values = spec.get(key)
        if not (isinstance(values, list) and values
                and all(isinstance(v, int) and 0 <= v <= 999 for v in values)):
            raise UsageError(f"{path}: '{key}' must be a list of indices 0..999, got {values!r}")
        count = spec.get(f"{key}_grasps")
        if not (isinstance(count, int) and count >= 1):
            raise UsageError(f"{path}: '{key}_grasps' must be an integer >= 1, got {count!r}")
    if set(spec["train"]) & set(spec["test"]):
        raise UsageError(f"{path}: train and test share indices "
                         f"{sorted(set(spec['train']) & set(spec['test']))}")
    return spec


def object_name(index: int) -> str:
    """The catalog name of random_urdfs index ``index``: ``blobNNN``."""
    return f"blob{index:03d}"


def source_file(index: int) -> Path:
    """pybullet_data's ``random_urdfs/NNN/NNN.urdf``."""
    import pybullet_data

    return Path(pybullet_data.getDataPath()) / "random_urdfs" / f"{index:03d}" / f"{index:03d}.urdf"


def import_index(index: int, scale: float) -> bool:
    """Import (or reuse) object ``blobNNN``; False when the importer refuses the file."""
    from kinegrasp_env.world.import_settings import ImportSettings
    from kinegrasp_env.world.importer import import_object
    from kinegrasp_env.world.meshfile import MeshError

    try:
        result = import_object(source_file(index), object_name(index), ImportSettings(scale=scale))
    except MeshError as error:
        print(f"  {object_name(index)}: refused by the importer ({error})", flush=True)
        return False
    print(f"  {result.name}: {'reused' if result.reused else 'imported'} "
          f"({result.entry['parts']} parts, {result.seconds:.0f} s)", flush=True)
    return True


def plan_index(index: int, count: int, replan: bool) -> list | None:
    """The planned grasps of ``blobNNN`` (file kept when already planned with these settings),
    or None when the planner finds fewer than ``count``."""
    from kinegrasp_env.world.grasps import load_grasps, save_grasps

    sys.path.insert(0, str(HERE.parent / "scripts"))
    from sdh_grasp_sampler import GraspPlanner

    name, path = object_name(index), GRASPS / f"{object_name(index)}.json"
    if path.is_file() and not replan:
        meta = json.loads(path.read_text())
        if (meta.get("object"), meta.get("seed"), meta.get("count")) == (name, index, count):
            return load_grasps(path)
    start = time.perf_counter()
    planner = GraspPlanner(name)
    try:
        found = planner.plan(count, seed=index)
    finally:
        planner.close()
    print(f"  {name}: {len(found)} of {count} grasps planned in "
          f"{time.perf_counter() - start:.0f} s", flush=True)
    if len(found) < count:
        return None
    save_grasps(found, path, seed=index, count=count,
                source=f"random_urdfs/{index:03d}/{index:03d}.urdf")
    return found


def resolve(index: int, count: int, scale: float, replan: bool) -> tuple[int, list]:
    """(the index used, its grasps) for a listed index, after the fallback rule."""
    for candidate in range(index, index + MAX_FALLBACK):
        if import_index(candidate, scale):
            grasps = plan_index(candidate, count, replan)
            if grasps is not None:
                if candidate != index:
                    print(f"  fallback: {index} -> {candidate}", flush=True)
                return candidate, grasps
    raise UsageError(f"no usable object among random_urdfs {index}..{index + MAX_FALLBACK - 1}")


def write_set(path: Path, grasps: list, **extra) -> None:
    """A grasp file of several objects (``object`` null, ``objects`` listing them)."""
    from kinegrasp_env.atomic_files import write_atomic

    objects = list(dict.fromkeys(g.object for g in grasps))
    payload = {"object": None, "objects": objects, **extra,
               "grasps": [g.to_dict() for g in grasps]}
    write_atomic(path, json.dumps(payload, indent=1))


def prepare(spec: dict, replan: bool = False) -> dict:
    """Run the steps of the module docstring; returns {"train": names, "test": names,
    "replaced": {index: used}}."""
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import OBJECT_NAMES

    GRASPS.mkdir(parents=True, exist_ok=True)
    scale = float(spec.get("scale", 1.0))
    sets: dict[str, list] = {"train": [], "test": []}
    names: dict[str, list[str]] = {"train": [], "test": []}
    replaced: dict[int, int] = {}
    for role in ("test", "train"):
        print(f"{role} objects:", flush=True)
        for index in spec[role]:
            used, grasps = resolve(index, spec[f"{role}_grasps"], scale, replan)
            if used != index:
                replaced[index] = used
            sets[role] += grasps
            names[role].append(object_name(used))
    builtin = [g for name in OBJECT_NAMES for i, g in enumerate(shipped_grasps(name))
               if i % 4 != 3]
    rule = "see agents/heldout.yaml"
    write_set(GRASPS / "train.json", builtin + sets["train"], rule=rule,
              builtin="shipped grasps i % 4 != 3 of " + ", ".join(OBJECT_NAMES),
              imported=names["train"], replaced=replaced)
    write_set(GRASPS / "test.json", sets["test"], rule=rule, imported=names["test"],
              replaced=replaced)
    print(f"train.json: {len(builtin) + len(sets['train'])} grasps "
          f"({len(builtin)} built-in, {len(sets['train'])} imported); "
          f"test.json: {len(sets['test'])} grasps of {', '.join(names['test'])}", flush=True)
    return {"train": names["train"], "test": names["test"], "replaced": replaced}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spec", default=str(SPEC), help="the held-out spec (YAML)")
    parser.add_argument("--replan", action="store_true",
                        help="plan again even where a grasp file with these settings exists")
    args = parser.parse_args(argv)
    try:
        prepare(read_spec(Path(args.spec)), replan=args.replan)
    except (UsageError, ValueError) as error:
        print(f"prepare: error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
