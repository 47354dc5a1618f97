"""The catalog listing: one summary row per object (what ``kinegrasp objects`` prints).

A row gives an object's name, source, size, r_max, centre of mass, parts, faces, the
decomposition's deviation from the source mesh, the source file's up axis and where the object
stands (position, yaw, orientation, support table). Built-in objects come first, then the
imported ones, then the placed ones (their base's row under their own name and placement).
:mod:`kinegrasp_env.world.catalog_cache` keeps a copy of the rows on disk.
"""

from __future__ import annotations

from kinegrasp_env.world.names import OBJECT_NAMES
from kinegrasp_env.world.objects import GraspObject, load_object
from kinegrasp_env.world.store import imported_folder, imported_names, read_entry


def catalog() -> list[dict]:
    """One summary dict per object, built-in then imported: name, source, size (m), r_max
    (m), centre of mass (object frame), parts, faces, the decomposition's deviation from
    the source mesh (None for built-in objects, whose parts are exact; see
    :class:`kinegrasp_env.world.deviation.Deviation`), the source file's up axis (turned
    into +z at import) and the placement (:func:`placement_fields`); placed objects last."""
    rows, placed = [], []
    for name in OBJECT_NAMES:
        obj = load_object(name)
        rows.append({"name": name, "source": "built-in", "size": obj.size.round(4).tolist(),
                     "r_max": round(obj.r_max, 4),
                     "center_of_mass": obj.center_of_mass.round(4).tolist(),
                     "parts": len(obj.parts), "faces": len(obj.mesh.faces), "deviation": None,
                     "up": "z", **placement_fields(obj)})
    for name in imported_names():
        if name in OBJECT_NAMES:
            continue
        entry = read_entry(imported_folder(name))
        if entry.get("base") is not None:
            placed.append((name, entry))
            continue
        rows.append({"name": name, "source": entry["source"]["description"],
                     "size": [round(v, 4) for v in entry["size"]],
                     "r_max": round(entry["r_max"], 4),
                     "center_of_mass": [round(v, 4) for v in entry["center_of_mass"]],
                     "parts": entry["parts"], "faces": entry["faces"],
                     "deviation": entry["deviation"],
                     "up": entry.get("settings", {}).get("up", "z"),
                     **placement_fields(load_object(name))})
    return rows + [placed_row(name, entry, rows) for name, entry in placed]


def placement_fields(obj: GraspObject, rounded: bool = True) -> dict:
    """A catalog row's placement: ``position`` (3,) metres, ``yaw`` radians (of an upright
    object; None for a tilted one), ``orientation`` (4,) quaternion [x, y, z, w] and
    ``table`` (:meth:`SupportTable.to_dict` or None); ``rounded``: to the listing's digits
    (4 for metres and radians, 6 for the quaternion), else as the pose holds them."""
    from scipy.spatial.transform import Rotation

    from kinegrasp_env.world.support import is_upright, pose_yaw

    def kept(value: float, digits: int) -> float:
        return round(float(value), digits) if rounded else float(value)

    return {"position": [kept(v, 4) for v in obj.pose[:3, 3]],
            "yaw": kept(pose_yaw(obj.pose), 4) if is_upright(obj.pose) else None,
            "orientation": [kept(v, 6)
                            for v in Rotation.from_matrix(obj.pose[:3, :3]).as_quat()],
            "table": None if obj.table is None else obj.table.to_dict()}


def placed_row(name: str, entry: dict, base_rows: list[dict]) -> dict:
    """The catalog row of a placed object: its base's row (among ``base_rows``, the built-in
    and imported objects') under its own name and placement (source ``placed <base>``)."""
    base = next((r for r in base_rows if r["name"] == entry["base"]), None)
    if base is None:  # the base is gone: say so in the row, loading it says how to fix it
        return {"name": name, "source": f"placed {entry['base']} (missing)", "size": [0, 0, 0],
                "r_max": 0.0, "center_of_mass": [0, 0, 0], "parts": 0, "faces": 0,
                "deviation": None, "up": "z", "position": [0, 0, 0], "yaw": 0.0,
                "orientation": [0.0, 0.0, 0.0, 1.0], "table": entry.get("table")}
    return {**base, "name": name, "source": f"placed {entry['base']}",
            **placement_fields(load_object(name))}

