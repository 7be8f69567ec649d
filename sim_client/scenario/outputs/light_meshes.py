"""Lighter meshes for pictures: a video of the G1 is drawn from ~60k triangles instead of 461k.

On a CPU renderer (llvmpipe, ``MUJOCO_GL=egl`` without a GPU) a frame of the G1 costs its triangles, not
its pixels: 461k triangles took ~30 ms to draw at 640x480 and about as long at 320x240. Seen from the
video's camera a few metres away a pixel spans ~5 mm, so detail finer than that is never seen. Each
binary STL mesh of the render-only spec is simplified by vertex clustering (the vertices in a cube of
``cell_m`` merge into their mean; triangles left with fewer than three corners go), and handed to MuJoCo
as the mesh's own vertices. Only pictures use this: the simulation's models keep every triangle.
"""

from __future__ import annotations

import pathlib
from typing import Any

import numpy as np

RENDER_MESH_CELL_M = 0.005  # [m] vertices closer than about this merge (a pixel spans ~5 mm in the videos)
_STL_HEADER_BYTES = 84
_STL_RECORD = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
_BITS = 21  # per axis of a cell's key: +-2^20 cells


def read_binary_stl(path: pathlib.Path) -> np.ndarray | None:
    """The triangles of a binary STL file, (m, 3, 3) corners; None if it is not one (ASCII, or cut short)."""
    data = path.read_bytes()
    if len(data) < _STL_HEADER_BYTES:
        return None
    count = int.from_bytes(data[80:84], "little")
    if len(data) != _STL_HEADER_BYTES + count * _STL_RECORD.itemsize or count == 0:
        return None  # an ASCII STL (whose size does not match), or a damaged one: left as it is
    return np.frombuffer(data, dtype=_STL_RECORD, count=count, offset=_STL_HEADER_BYTES)["corners"].astype(np.float64)


def _keys(columns: np.ndarray) -> np.ndarray:
    """One int64 per row of three non-negative integers below 2^21."""
    return (columns[:, 0] << (2 * _BITS)) | (columns[:, 1] << _BITS) | columns[:, 2]


def cluster(triangles: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clustering of a triangle soup (m, 3, 3): the corners in each cube of side ``cell`` become one vertex,
    their mean; triangles left with fewer than three corners, and repeated ones, are dropped (each keeps its
    winding, so its outside stays outside). Returns the vertices (n, 3) and triangles (k, 3)."""
    corners = triangles.reshape(-1, 3)
    cells = np.floor(corners / cell).astype(np.int64)
    cells -= cells.min(axis=0)
    if int(cells.max(initial=0)) >= 1 << _BITS:
        raise ValueError(f"a mesh over {(1 << _BITS) * cell:.0f} m across cannot be clustered at {cell} m")
    _, group = np.unique(_keys(cells), return_inverse=True)
    group = group.reshape(-1)
    counts = np.bincount(group)
    merged = np.stack([np.bincount(group, weights=corners[:, axis]) for axis in range(3)], axis=1) / counts[:, None]
    faces = group.reshape(-1, 3)
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    _, first = np.unique(_keys(np.sort(faces, axis=1)), return_index=True)
    return merged, faces[np.sort(first)]


def lighten_meshes(spec: Any, cell_m: float = RENDER_MESH_CELL_M) -> tuple[int, int]:
    """Simplify every binary STL mesh of ``spec`` (a render-only copy) in place; returns the triangles before and after.

    A mesh keeps its name, scale and reference frame; its file is replaced by the simplified vertices. A mesh
    that would lose its volume (fewer than 4 vertices or triangles left) stays as it was.
    """
    before = after = 0
    for mesh in spec.meshes:
        path = pathlib.Path(mesh.file)
        if path.suffix.lower() != ".stl" or not path.is_absolute():
            continue
        triangles = read_binary_stl(path)
        if triangles is None:
            continue
        scale = float(np.max(np.abs(mesh.scale))) or 1.0
        vertices, faces = cluster(triangles, cell_m / scale)
        if len(vertices) < 4 or len(faces) < 4:
            continue
        before += len(triangles)
        after += len(faces)
        mesh.file = ""
        mesh.uservert = vertices.astype(np.float32).reshape(-1)
        mesh.userface = faces.astype(np.int32).reshape(-1)
    return before, after
