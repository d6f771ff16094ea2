"""Test meshes built from scratch (no files): cloth grids, spheres, cubes, and analytic poses."""

from __future__ import annotations

import numpy as np


def grid(nx: int, ny: int | None = None, *, size: float = 1.0, jitter: float = 0.0, seed: int = 0, alternate: bool = True):
    """A flat ``nx × ny``-vertex sheet in the xy-plane, triangles counter-clockwise seen from +z.

    Quads are split along alternating diagonals (``alternate``) or all along the same one, as
    Blender's Grid primitive and the paper's cloth do; ``jitter`` moves interior vertices randomly by a
    fraction of the spacing (breaks symmetries). Returns ``(vertices (n,3), triangles (m,3))``.
    """
    ny = nx if ny is None else ny
    xs, ys = np.meshgrid(np.linspace(0.0, size, nx), np.linspace(0.0, size * (ny - 1) / (nx - 1), ny))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    if jitter:
        rng = np.random.default_rng(seed)
        interior = (xs > 0) & (xs < xs.max()) & (ys > 0) & (ys < ys.max())
        vertices[interior.ravel(), :2] += jitter * size / (nx - 1) * rng.uniform(-0.5, 0.5, (interior.sum(), 2))
    triangles = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            b, c, d = a + 1, a + nx, a + nx + 1
            if (i + j) % 2 or not alternate:
                triangles += [[a, b, d], [a, d, c]]
            else:
                triangles += [[a, b, c], [b, d, c]]
    return vertices, np.array(triangles, dtype=np.int64)


def icosphere(subdivisions: int = 2, radius: float = 1.0):
    """A closed unit icosphere (valences 5 and 6), outward counter-clockwise triangles."""
    phi = (1 + 5**0.5) / 2
    vertices = np.array(
        [[-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0], [0, -1, phi], [0, 1, phi],
         [0, -1, -phi], [0, 1, -phi], [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1]],
        dtype=float,
    )
    triangles = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
         [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    )
    vertices = list(vertices / np.linalg.norm(vertices, axis=1, keepdims=True))
    for _ in range(subdivisions):
        midpoint = {}

        def middle(i, j):
            key = (min(i, j), max(i, j))
            if key not in midpoint:
                p = vertices[i] + vertices[j]
                vertices.append(p / np.linalg.norm(p))
                midpoint[key] = len(vertices) - 1
            return midpoint[key]

        new = []
        for a, b, c in triangles:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            new += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        triangles = np.array(new)
    return radius * np.array(vertices), np.asarray(triangles, dtype=np.int64)


def cube(n: int = 8):
    """The surface of the cube [-1, 1]³ with an ``n × n`` grid per face, outward triangles."""
    index, vertices, triangles = {}, [], []

    def vertex(p):
        key = tuple(int(c) for c in p)
        if key not in index:
            index[key] = len(vertices)
            vertices.append(np.array(key, dtype=float) * 2.0 / n - 1.0)
        return index[key]

    for axis in range(3):
        for side in (0, n):
            u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
            normal = np.zeros(3)
            normal[axis] = 1 if side else -1
            for i in range(n):
                for j in range(n):
                    corners = []
                    for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = np.zeros(3, dtype=int)
                        p[axis], p[u_axis], p[v_axis] = side, i + du, j + dv
                        corners.append(vertex(p))
                    a, b, c, d = corners
                    quad = [[a, b, c], [a, c, d]] if (i + j) % 2 else [[a, b, d], [b, c, d]]
                    for tri in quad:
                        p0, p1, p2 = (vertices[k] for k in tri)
                        if np.dot(np.cross(p1 - p0, p2 - p0), normal) < 0:
                            tri = [tri[0], tri[2], tri[1]]
                        triangles.append(tri)
    return np.array(vertices), np.array(triangles, dtype=np.int64)


def cube_with_bump(n: int = 10, height: float = 0.35, radius: float = 0.7):
    """Cube of :func:`cube` with a smooth bump on its top face: ``height > 0`` outward, ``< 0``
    inward. Opposite heights are mirror images across the face plane, hence exactly isometric."""
    vertices, triangles = cube(n)
    top = np.isclose(vertices[:, 2], 1.0)
    r = np.linalg.norm(vertices[:, :2], axis=1)
    profile = np.where(r < radius, np.cos(0.5 * np.pi * r / radius) ** 2, 0.0)
    vertices = vertices.copy()
    vertices[top, 2] += height * profile[top]
    return vertices, triangles


def drape(vertices: np.ndarray, amount: float = 1.0) -> np.ndarray:
    """A large, nearly isometric motion of a unit sheet: rolled around a cylinder (axis along y)
    by ``amount`` radians per unit length, plus a gentle twist — a sheet draped over a bar."""
    x, y = vertices[:, 0] - 0.5, vertices[:, 1] - 0.5
    radius = 1.0 / max(amount, 1e-9)
    theta = x / radius
    out = np.stack([radius * np.sin(theta), y, radius * (1 - np.cos(theta))], axis=1)
    twist = 0.3 * amount * y
    c, s = np.cos(twist), np.sin(twist)
    out[:, 0], out[:, 2] = c * out[:, 0] - s * out[:, 2], s * out[:, 0] + c * out[:, 2]
    return out


def draped_sheet():
    """A 21 × 21-vertex sheet 2 units across, centred on the origin and draped over a bar
    (:func:`drape`, 0.8): ``(vertices (441, 3), triangles)``."""
    flat, triangles = grid(21, size=2.0)
    return drape(flat - [1.0, 1.0, 0.0], 0.8), triangles


def turned(vertices: np.ndarray, t: float, degrees: float = 100.0) -> np.ndarray:
    """``vertices`` (n, 3) turned about the z axis by ``degrees`` per unit of key time ``t``."""
    angle = np.radians(degrees * t)
    c, s = np.cos(angle), np.sin(angle)
    return vertices @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T


def stretch_and_bend(vertices: np.ndarray, seed: int = 1) -> np.ndarray:
    """A non-isometric, smooth deformation (stretch + bend + smooth random displacement)."""
    rng = np.random.default_rng(seed)
    out = vertices * np.array([1.2, 0.9, 1.1])
    out[:, 2] += 0.3 * np.sin(2.5 * vertices[:, 0]) * np.cos(1.7 * vertices[:, 1])
    k = rng.normal(size=(3, 3))
    return out + 0.05 * np.sin(vertices @ k)


def random_rotation(seed: int = 0) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def capped_cylinder(sides: int = 64):
    """A closed cylinder (radius 1, height 2) whose caps are fans from one rim vertex, as Blender
    splits an n-gon cap: long flat triangles. Vertices (2·sides, 3), triangles."""
    angle = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    ring = np.c_[np.cos(angle), np.sin(angle)]
    vertices = np.vstack([np.c_[ring, np.full(sides, -1.0)], np.c_[ring, np.full(sides, 1.0)]])
    triangles = []
    for i in range(sides):
        j = (i + 1) % sides
        triangles += [[i, j, sides + j], [i, sides + j, sides + i]]
    for i in range(1, sides - 1):
        triangles += [[0, i + 1, i], [sides, sides + i, sides + i + 1]]
    return vertices, np.array(triangles)


def closed_tube(rings: int, sides: int, *, length: float = 1.0, radius: float = 0.07):
    """A closed tube along x ∈ [0, length] (a finger): ``rings`` rings of ``sides`` vertices, each
    cap a fan around a centre vertex, triangles facing outward. Vertices (rings·sides + 2, 3),
    triangles."""
    angle = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    x = np.repeat(np.linspace(0.0, length, rings), sides)
    vertices = np.c_[x, radius * np.tile(np.cos(angle), rings), radius * np.tile(np.sin(angle), rings)]
    vertices = np.vstack([vertices, [[0.0, 0.0, 0.0], [length, 0.0, 0.0]]])
    triangles = []
    for k in range(rings - 1):
        for i in range(sides):
            j = (i + 1) % sides
            a, b, c, d = k * sides + i, k * sides + j, (k + 1) * sides + j, (k + 1) * sides + i
            triangles += [[a, b, c], [a, c, d]]
    start, end = rings * sides, rings * sides + 1
    for i in range(sides):
        j = (i + 1) % sides
        triangles += [[start, j, i], [end, (rings - 1) * sides + i, (rings - 1) * sides + j]]
    return vertices, np.array(triangles)


def twisted_torus(n: int, m: int, *, shift: int = 0, alternate: bool = True, major: float = 3.0, minor: float = 1.0):
    """A torus of revolution cut into ``n`` (around the axis) × ``m`` (around the tube) quads, the
    tube's seam glued with a twist of ``shift`` quads: quad ``(i, m)`` is quad ``(i + shift, 0)``.
    Quads are split along alternating diagonals (``alternate``: valences 4 and 8 when n, m and
    shift allow it) or all along the same one (valence 6); outward counter-clockwise triangles.
    Vertices (n·m, 3), triangles (2·n·m, 3)."""
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    u = 2.0 * np.pi * (i + shift * j / m) / n  # the twist spread evenly along the tube
    v = 2.0 * np.pi * j / m
    ring = major + minor * np.cos(v)
    vertices = np.stack([ring * np.cos(u), ring * np.sin(u), minor * np.sin(v)], axis=-1).reshape(-1, 3)

    def index(a, b):
        return (a + shift * (b // m)) % n * m + b % m

    triangles = []
    for a in range(n):
        for b in range(m):
            p, q, r, s = index(a, b), index(a + 1, b), index(a + 1, b + 1), index(a, b + 1)
            if (a + b) % 2 and alternate:
                triangles += [[p, q, s], [q, r, s]]
            else:
                triangles += [[p, q, r], [p, r, s]]
    return vertices, np.array(triangles, dtype=np.int64)
