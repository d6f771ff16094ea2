"""The topology (and rest positions) of a Wavefront OBJ file, for retiming caches outside
Blender. Written by hand because only ``v`` and ``f`` lines matter and every OBJ library on PyPI
pulls in a scene graph or a renderer."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import MeshError


def read_obj(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices float64 ``(n, 3)`` and triangles int64 ``(m, 3)`` of an OBJ file.

    Polygons are split into a fan of triangles from their first corner; ``v/vt/vn`` corners and
    negative (relative) indices are understood; other statements (normals, groups, materials)
    are ignored. A missing file, a bad index or a file without faces raises :class:`MeshError`.
    """
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"'{path}' does not exist or is not a file.")
    vertices, triangles = [], []
    with open(path, encoding="utf-8-sig", errors="replace") as stream:  # -sig: a byte-order mark is no text
        for line_number, line in enumerate(stream, 1):
            fields = line.split()
            if not fields:
                continue
            try:
                if fields[0] == "v":
                    if len(fields) < 4:
                        raise ValueError("a vertex needs three coordinates")
                    vertices.append([float(value) for value in fields[1:4]])
                elif fields[0] == "f":
                    corners = [int(corner.split("/")[0]) for corner in fields[1:]]
                    corners = [c - 1 if c > 0 else len(vertices) + c for c in corners]
                    if len(corners) < 3 or min(corners) < 0 or max(corners) >= len(vertices):
                        raise ValueError("a face needs three corners that name earlier vertices")
                    triangles += [[corners[0], corners[i], corners[i + 1]] for i in range(1, len(corners) - 1)]
            except ValueError as error:
                raise MeshError(f"'{path}' line {line_number} cannot be read ({error}): {line.strip()!r}") from None
    if not triangles:
        raise MeshError(f"'{path}' has no faces: a topology needs a surface mesh.")
    return np.array(vertices, dtype=np.float64).reshape(-1, 3), np.array(triangles, dtype=np.int64)


def write_obj(path, vertices, triangles) -> Path:
    """Write vertices ``(n, 3)`` and triangles ``(m, 3)`` as an OBJ file (for tests and exports)."""
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in np.asarray(vertices, dtype=np.float64)]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(triangles, dtype=np.int64)]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return Path(path)
