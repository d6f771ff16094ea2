"""The topology (and rest positions) of a Wavefront OBJ file, for retiming caches outside
Blender. Written by hand because only ``v`` and ``f`` lines matter and every OBJ library on PyPI
pulls in a scene graph or a renderer."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .errors import MeshError
from .mesh_topology import DEGENERATE_TRIANGLE_RATIO
from .point_cache import PC2_MAGIC


def read_obj(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices float64 ``(n, 3)`` and triangles int64 ``(m, 3)`` of an OBJ file.

    Polygons are split into a fan of triangles from their first corner, or, where that fan has a
    zero-area or inverted triangle, from the corner whose fan's worst triangle is the largest
    (:func:`fan_corners`); ``v/vt/vn`` corners and negative (relative) indices are understood;
    other statements (normals, groups, materials, lines) are ignored. A missing file, a bad index
    or a file without faces, and a vertex coordinate that is not a finite number, raise :class:`MeshError`.
    """
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"'{path}' does not exist or is not a file.")
    vertices, polygons = [], []
    with open(path, encoding=_text_encoding(path), errors="replace") as stream:
        for line_number, line in enumerate(stream, 1):
            fields = line.split()
            if not fields:
                continue
            try:
                if fields[0] == "v":
                    if len(fields) < 4:
                        raise ValueError("a vertex needs three coordinates")
                    vertex = [float(value) for value in fields[1:4]]
                    if not all(math.isfinite(x) for x in vertex):  # "nan", "inf", 1e400: no place to fan faces at
                        raise ValueError("a vertex coordinate is not a finite number")
                    vertices.append(vertex)
                elif fields[0] == "f":
                    corners = [int(corner.split("/")[0]) for corner in fields[1:]]
                    corners = [c - 1 if c > 0 else len(vertices) + c for c in corners]
                    if len(corners) < 3 or min(corners) < 0 or max(corners) >= len(vertices):
                        raise ValueError("a face needs three corners that name earlier vertices")
                    polygons.append(corners)
            except ValueError as error:
                raise MeshError(f"'{path}' line {line_number} cannot be read ({error}): {line.strip()!r}") from None
    if not polygons:
        raise MeshError(f"'{path}' has no faces: a topology needs a surface mesh.")
    vertices = np.array(vertices, dtype=np.float64).reshape(-1, 3)
    triangles = []
    for corners, first in zip(polygons, fan_corners(vertices, polygons)):
        corners = corners[first:] + corners[:first]
        triangles += [[corners[0], corners[i], corners[i + 1]] for i in range(1, len(corners) - 1)]
    return vertices, np.array(triangles, dtype=np.int64)


# Bytes read from the start of an OBJ to tell text from binary data.
TEXT_PROBE_BYTES = 4096


def _text_encoding(path: Path) -> str:
    """The encoding to read the OBJ ``path`` in: UTF-16 where it starts with UTF-16's byte-order mark
    (as Windows PowerShell's ``>`` saves text), else UTF-8 (``-sig``: a UTF-8 byte-order mark is no
    text). Raise :class:`MeshError` where it holds binary data (a NUL byte in its first
    :data:`TEXT_PROBE_BYTES`), which no OBJ in UTF-8 holds: a point cache, an Alembic or a .blend
    given as the topology (the cache and the OBJ swapped on a command line) would otherwise be
    refused by the first of its bytes that happen to read as a face, quoted as garbage."""
    with open(path, "rb") as stream:
        head = stream.read(TEXT_PROBE_BYTES)
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):  # in UTF-16 every ASCII character has a NUL byte
        return "utf-16"
    if b"\0" not in head:
        return "utf-8-sig"
    formats = {PC2_MAGIC[:11]: "a PC2 point cache", b"BLENDER": "a .blend file", b"Ogawa": "an Alembic cache"}
    kind = next((f", {name}" for magic, name in formats.items() if head.startswith(magic)), "")
    raise MeshError(f"'{path}' is not an OBJ file: it holds binary data{kind}. The topology is a Wavefront "
                    "OBJ (text: 'v x y z' and 'f a b c' lines) exported from the mesh the cache moves; check "
                    "that the cache and the OBJ are not swapped.")


def fan_corners(vertices: np.ndarray, polygons: list[list[int]]) -> np.ndarray:
    """For each polygon (a list of vertex indices into ``vertices`` float64 ``(n, 3)``), the corner
    its fan of triangles starts from, int ``(len(polygons),)``: 0 where every triangle of that fan
    has an area above the degenerate threshold of :mod:`core.mesh_topology` and faces the
    polygon's way (its normal by Newell's formula), else the corner whose fan's smallest such
    area (signed, relative to its longest squared edge) is the largest. Exporters write n-gons
    with corners on one line (what Dissolve leaves, a T-junction's vertex) and concave quads,
    whose fan from the first corner can have a zero-area triangle, refused as degenerate, or an
    inverted one, which folds the surface over; Blender triangulates them without either."""
    first = np.zeros(len(polygons), dtype=np.int64)
    sizes = np.array([len(corners) for corners in polygons])
    for size in np.unique(sizes[sizes > 3]):
        rows = np.flatnonzero(sizes == size)
        corners = np.array([polygons[row] for row in rows], dtype=np.int64)  # (k, c)
        points = vertices[corners]
        points = points - points.mean(axis=1, keepdims=True)
        normal = np.cross(points, np.roll(points, -1, axis=1)).sum(axis=1)  # Newell: 2 × vector area
        length = np.linalg.norm(normal, axis=1)
        normal = np.divide(normal, length[:, None], out=np.zeros_like(normal), where=length[:, None] > 0)
        # the fan from corner a: triangles (a, a + i, a + i + 1) for i = 1 .. c − 2
        apex = np.arange(size)[:, None]
        steps = np.arange(1, size - 1)[None, :]
        a = points[:, np.broadcast_to(apex, (size, size - 2))]  # (k, c, c − 2, 3)
        b = points[:, (apex + steps) % size]
        c = points[:, (apex + steps + 1) % size]
        signed = np.einsum("kftd,kd->kft", np.cross(b - a, c - a), normal)
        longest = np.max([np.einsum("...d,...d->...", p - q, p - q) for p, q in ((a, b), (b, c), (c, a))], axis=0)
        score = (signed / np.where(longest > 0, longest, 1.0)).min(axis=2)  # (k, c)
        fine = score[:, 0] > DEGENERATE_TRIANGLE_RATIO
        first[rows] = np.where(fine | (length == 0), 0, np.argmax(score, axis=1))
    return first


def write_obj(path, vertices, triangles) -> Path:
    """Write vertices ``(n, 3)`` and triangles ``(m, 3)`` as an OBJ file (for tests and exports)."""
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in np.asarray(vertices, dtype=np.float64)]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(triangles, dtype=np.int64)]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return Path(path)
