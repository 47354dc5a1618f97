"""Plotly figures as plain JSON for the HTML reports: compact typed arrays, safe embedding.

Figures are plain dicts (``{"data": [...], "layout": {...}}``) in plotly.js's schema; numeric
arrays travel as plotly.js typed-array specs (``{"dtype": "f4", "bdata": base64}``, read by
plotly.js >= 2.28), which are about a third the size of JSON number lists. Coordinates are
stored as float32 (about 1e-7 relative: far below a pixel).
"""

from __future__ import annotations

import base64
import json
import math
from functools import lru_cache

import numpy as np

#: numpy dtype -> plotly.js typed-array code.
DTYPES = {np.dtype("<f4"): "f4", np.dtype("<f8"): "f8", np.dtype("<i4"): "i4",
          np.dtype("<u4"): "u4", np.dtype("<i2"): "i2", np.dtype("<u2"): "u2",
          np.dtype("<i1"): "i1", np.dtype("<u1"): "u1"}


def typed_array(values, dtype: str = "<f4") -> dict:
    """A plotly.js typed-array spec of ``values`` (n,) or (n, k) cast to ``dtype``.

    NaN stays NaN (a gap in a line, for float dtypes).
    """
    array = np.ascontiguousarray(np.asarray(values), dtype=np.dtype(dtype))
    spec = {"dtype": DTYPES[array.dtype], "bdata": base64.b64encode(array.tobytes()).decode()}
    if array.ndim == 2:
        spec["shape"] = f"{array.shape[0]}, {array.shape[1]}"
    elif array.ndim != 1:
        raise ValueError(f"typed arrays are 1-D or 2-D, got shape {array.shape}")
    return spec


def decode_typed_array(spec: dict) -> np.ndarray:
    """The numpy array of a typed-array spec (the inverse of :func:`typed_array`)."""
    dtype = {code: dt for dt, code in DTYPES.items()}[spec["dtype"]]
    array = np.frombuffer(base64.b64decode(spec["bdata"]), dtype=dtype)
    if "shape" in spec:
        array = array.reshape([int(v) for v in spec["shape"].split(",")])
    return array


def _clean(value):
    """JSON-ready value: numpy scalars to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (np.floating, float)):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def figure_json(figure: dict) -> str:
    """Compact JSON of a figure, safe inside a ``<script>`` element (no ``</`` sequence)."""
    return json.dumps(_clean(figure), separators=(",", ":")).replace("</", "<\\/")


@lru_cache(maxsize=1)
def plotly_js() -> str:
    """plotly.js, minified, as bundled with the plotly Python package (works offline)."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


def plotly_version() -> str:
    import plotly

    return plotly.__version__


class MeshLibrary:
    """Triangle meshes shared by the figures of a page, each stored once in its own frame.

    A figure's mesh trace names its pieces as instances (:func:`instanced_mesh`): (key, pose)
    pairs that the page's script turns into vertices when it draws the figure. A ranking
    page that shows the same arm links for 40 candidates stores their triangles once.
    """

    def __init__(self) -> None:
        self.meshes: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def add(self, key: str, vertices: np.ndarray, faces: np.ndarray) -> str:
        """Store a mesh (vertices (V, 3) metres, faces (F, 3)) under ``key`` (once)."""
        if key not in self.meshes:
            self.meshes[key] = (np.asarray(vertices, dtype=float), np.asarray(faces))
        return key

    def to_json(self) -> dict:
        return {key: {"v": typed_array(v.reshape(-1)), "f": typed_array(f.reshape(-1), "<u4")}
                for key, (v, f) in self.meshes.items()}

    def placed(self, key: str, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The mesh ``key`` mapped by ``pose`` (4, 4): what the page's script computes."""
        vertices, faces = self.meshes[key]
        return vertices @ pose[:3, :3].T + pose[:3, 3], faces


MESH_STYLE = {"hoverinfo": "name", "flatshading": False,
              "lighting": {"ambient": 0.55, "diffuse": 0.7, "specular": 0.15}}


def instanced_mesh(instances: list[tuple[str, np.ndarray]], name: str, color: str, *,
                   opacity: float = 1.0, **extra) -> dict:
    """A Mesh3d trace made of library meshes, each placed by a (4, 4) pose: the trace holds
    ``kgInstances`` (key, the pose's top three rows, row-major) instead of coordinates."""
    return {"type": "mesh3d", "name": name, "color": color, "opacity": opacity,
            "kgInstances": [[key, np.asarray(pose)[:3].reshape(-1).tolist()]
                            for key, pose in instances],
            **MESH_STYLE, **extra}


BASE_LAYOUT = {
    "template": {"layout": {"font": {"family": "Helvetica, Arial, sans-serif", "size": 12},
                            "paper_bgcolor": "white", "plot_bgcolor": "white"}},
    "margin": {"l": 10, "r": 10, "t": 40, "b": 10},
}


def layout(**entries) -> dict:
    """A layout with the report's defaults, updated by ``entries``."""
    return {**BASE_LAYOUT, **entries}
