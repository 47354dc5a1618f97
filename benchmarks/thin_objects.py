"""Thin-walled and handled objects for the benchmarks, made with trimesh primitives and
imported into the catalog as a user imports a mesh (``kinegrasp objects add``): a tube
(6 cm across, 4 mm wall), an open tray (10 x 7 x 4 cm, 5 mm walls) and a cup with a handle
(7 cm across, 4 mm wall, a square handle of 6 mm bars). Importing is skipped for an object
already in the catalog from the same mesh (the importer's own check)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: The objects this module makes.
THIN_OBJECTS = ("tube", "tray", "cup")


def _box(extents, at):
    import trimesh

    box = trimesh.creation.box(extents)
    box.apply_translation(at)
    return box


def _annulus(inner: float, outer: float, height: float, base: float):
    import trimesh

    ring = trimesh.creation.annulus(r_min=inner, r_max=outer, height=height, sections=64)
    ring.apply_translation((0.0, 0.0, base + height / 2))
    return ring


def thin_mesh(name: str):
    """The trimesh of one of :data:`THIN_OBJECTS` (metres, base on z = 0)."""
    import trimesh

    if name == "tube":
        return _annulus(0.026, 0.03, 0.09, 0.0)
    wall = 0.005
    if name == "tray":
        height = 0.035
        parts = [_box((0.10, 0.07, wall), (0, 0, wall / 2))]
        for side in (-1, 1):
            parts.append(_box((wall, 0.07, height), (side * (0.05 - wall / 2), 0,
                                                     wall + height / 2)))
            parts.append(_box((0.10 - 2 * wall, wall, height), (0, side * (0.035 - wall / 2),
                                                                wall + height / 2)))
        return trimesh.util.concatenate(parts)
    if name == "cup":
        bottom = trimesh.creation.cylinder(0.035, 0.004, sections=64)
        bottom.apply_translation((0, 0, 0.002))
        handle = [_box((0.025, 0.008, 0.006), (0.0475, 0, z)) for z in (0.02, 0.07)]
        handle.append(_box((0.006, 0.008, 0.044), (0.057, 0, 0.045)))
        return trimesh.util.concatenate([_annulus(0.031, 0.035, 0.076, 0.004), bottom,
                                         *handle])
    raise ValueError(f"unknown thin object {name!r}; choose from {', '.join(THIN_OBJECTS)}")


def import_thin_objects(folder: Path, names=THIN_OBJECTS) -> list[str]:
    """Write each mesh to ``folder`` and import it into the catalog; the names imported."""
    from kinegrasp_env.world.importer import import_object

    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        path = folder / f"{name}.obj"
        mesh = thin_mesh(name)
        assert np.isfinite(mesh.volume)
        mesh.export(path)
        import_object(path, name)
    return list(names)
