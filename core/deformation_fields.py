"""Per-triangle deformation fields between two poses of one mesh, and their log/exp coordinates.

The deformation of triangle ``T`` from a base pose to another pose is the linear map ``F_T`` that
takes the base triangle's edges to the other's (and its unit normal to the other's unit normal).
Its polar decomposition ``F_T = R_T U_T`` splits it into

- a **stretch** ``U_T`` (symmetric positive definite, identity along the base normal): the
  first fundamental form of the other pose pulled back to the base, ``F_Tᵀ F_T = U_T²``, i.e. the
  triangle's edge lengths and area — the information of the intrinsic shape differences in the
  full basis (paper §4.2, Props. 1–2);
- a **rotation** ``R_T``: how the triangle turns, whose variation between neighbours is the
  extrinsic information (§5.3).

Both are stored in coordinates where interpolation is linear: the stretch as the 2×2 matrix
logarithm in the base triangle's tangent basis (three numbers), the rotation as a rotation vector
relative to the whole mesh's best rigid motion (so a rigid motion of the mesh, or of several
pieces moving as one, has zero residual at every triangle and is interpolated exactly, also for
half turns). Everything is closed-form per triangle (2×2 polar decompositions, logarithms and
exponentials), vectorized over the triangles; rigid motions of the whole mesh are interpolated
along screw motions (the exponential map of SE(3): :mod:`core.screw_motions`), past half turns the way
:mod:`core.rotation_continuity` tells.

Shapes: ``m`` triangles, ``n`` vertices; corner edge ``c`` of a triangle runs from its corner ``c``
to corner ``c + 1`` (mod 3).
"""

from __future__ import annotations

import numpy as np

from .geometry import coordinate_cross, coordinate_dot

#: Smallest ratio (radius / mean eigenvalue, or angle in radians) at which the closed-form
#: expressions below are evaluated directly; below it their Taylor series (error < 1e-16).
SERIES_THRESHOLD = 1e-4
#: Log-stretch eigenvalues are clipped to ±this before exponentiating (a stretch by e^30 is far
#: outside anything a pose can mean; the clip only keeps extrapolations finite).
MAX_LOG_STRETCH = 30.0
#: Meshes of at most this many pieces are turned one piece at a time (a 3×3 product per piece on a
#: view of its rows or columns where they are consecutive, ~5 µs of Python each), more pieces by
#: gathered 3×3 blocks per vertex or triangle: here in :func:`turned_coordinate_rows` (two pieces of
#: 10k triangles 3.6 → 0.14 ms) and in the sequences' rigid motions
#: (``core.inbetween_topology.Topology.apply_motion``: two 5k sheets 2.17 → 0.14 ms per call).
SLICED_PIECES = 64


def corner_edges(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Edge vectors (m, 3, 3) of every triangle: ``[:, c]`` runs from corner ``c`` to ``c + 1``."""
    p = vertices[triangles]
    return p[:, [1, 2, 0]] - p


def tangent_frame_rows(edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal right-handed frames of triangles with corner ``edges`` stored by coordinate
    (3 coordinates, 3 corners, m) as columns (3 columns, 3 coordinates, m) — ``t1`` along the
    first edge, ``t2 = n × t1``, ``n`` the unit normal — and the corner edges' coordinates in
    ``(t1, t2)`` stored the same way (2, 3 corners, m). The coordinates in closed form (the first
    edge is ``(|e₀|, 0)``, ``p2 − p0`` is ``(e₀·f, |e₀ × f|) / |e₀|``) instead of nine projections.
    Degenerate triangles get zero frames (callers check non-degeneracy at the boundary)."""
    e1, f = edges[:, 0], -edges[:, 2]
    cross = coordinate_cross(e1, f)
    tiny = np.finfo(float).tiny
    length = np.maximum(np.sqrt(coordinate_dot(e1, e1)), tiny)
    height = np.sqrt(coordinate_dot(cross, cross))
    columns = np.empty((3,) + e1.shape)
    columns[0] = e1 / length
    columns[2] = cross / np.maximum(height, tiny)
    columns[1] = coordinate_cross(columns[2], columns[0])
    along, rise = coordinate_dot(e1, f) / length, height / length
    coordinates = np.empty((2,) + edges.shape[1:])
    coordinates[0, 0], coordinates[1, 0] = length, 0.0
    coordinates[0, 1], coordinates[1, 1] = along - length, rise
    coordinates[0, 2], coordinates[1, 2] = -along, -rise
    return columns, coordinates


def inverse_edge_rows(coordinates: np.ndarray) -> np.ndarray:
    """Entries 00, 01, 11 (3, m) of the inverse edge matrices ``[p1 − p0, p2 − p0]⁻¹`` of
    triangles with tangent ``coordinates`` (2, 3 corners, m) from :func:`tangent_frame_rows`
    (upper triangular in their own basis: ``p1 − p0`` lies along ``t1``)."""
    a, b, d = coordinates[0, 0], -coordinates[0, 2], -coordinates[1, 2]
    return np.stack([1.0 / a, -b / (a * d), 1.0 / d])


def planar_map_entries(coordinates: np.ndarray, base_inverse: np.ndarray) -> tuple:
    """Entries ``(a, b, c, d)`` ((m,) each; ``[[a, b], [c, d]]``) of the 2×2 deformation gradients
    from the base triangles (``base_inverse``: :func:`inverse_edge_rows` of theirs) to triangles
    with tangent ``coordinates`` (2, 3 corners, m) in their own tangent bases."""
    i00, i01, i11 = base_inverse
    x, y = coordinates[0, 0], coordinates[1, 0]  # p1 − p0
    u, v = -coordinates[0, 2], -coordinates[1, 2]  # p2 − p0
    return x * i00, x * i01 + u * i11, y * i00, y * i01 + v * i11


def planar_polar(a, b, c, d) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Polar decomposition ``M = Q S`` of 2×2 maps ``[[a, b], [c, d]]`` (entries (m,) each) with
    positive determinant: the rotations ``Q`` as ``(cos, sin)`` of their angles ((m,) each) and
    the symmetric stretches ``S`` as ``(s11, s12, s22)`` (m, 3). Closed form: ``Q`` turns by the
    angle of ``(a + d, c − b)`` (normalized, no trigonometric function)."""
    x, y = a + d, c - b
    radius = _length(x, y)
    zero = np.flatnonzero(radius == 0)  # the angle of (0, 0) is 0 (rows set after: see sqrt_det)
    radius[zero] = 1.0
    cos, sin = x / radius, y / radius
    cos[zero] = 1.0
    s11 = cos * a + sin * c
    s12 = 0.5 * (cos * b + sin * d + cos * c - sin * a)
    s22 = -sin * b + cos * d
    return (cos, sin), np.stack([s11, s12, s22], axis=1)


def _length(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``√(x² + y²)`` element-wise. Not ``np.hypot``, which NumPy computes one value at a time
    (8× slower at 60k values); the entries here (planar maps, stretches and their logarithms) are
    far from where the squares would overflow or underflow."""
    return np.sqrt(x * x + y * y)


def _symmetric_parts(s: np.ndarray):
    mean = 0.5 * (s[:, 0] + s[:, 2])
    half = 0.5 * (s[:, 0] - s[:, 2])
    return mean, half, s[:, 1], _length(half, s[:, 1])


def log_stretch(s: np.ndarray) -> np.ndarray:
    """Matrix logarithm of symmetric positive definite 2×2 matrices ``(s11, s12, s22)`` (m, 3),
    in the same packing: ``log S = ½ log det S · I + atanh(ρ/μ)/ρ · (S − μ I)`` with mean
    eigenvalue ``μ`` and radius ``ρ`` (the eigenvalues are ``μ ± ρ``)."""
    mean, half, off, radius = _symmetric_parts(s)
    x = radius / mean
    direct = x > SERIES_THRESHOLD
    ratio = np.where(direct, np.arctanh(np.minimum(x, 1 - 1e-16)) / np.where(direct, x, 1.0), 1.0 + x * x / 3.0)
    slope = ratio / mean
    level = 0.5 * np.log(np.maximum((mean - radius) * (mean + radius), np.finfo(float).tiny))
    return np.stack([level + slope * half, slope * off, level - slope * half], axis=1)


def exp_stretch(log: np.ndarray) -> np.ndarray:
    """Matrix exponential of symmetric 2×2 matrices ``(l11, l12, l22)`` (m, 3), same packing:
    ``exp L = e^μ (cosh ρ · I + sinh ρ / ρ · (L − μ I))``, with ``e^μ cosh ρ`` and ``e^μ sinh ρ``
    from the two eigenvalues ``e^(μ ± ρ)`` (two exponentials instead of three functions)."""
    mean, half, off, radius = _symmetric_parts(log)
    mean = np.clip(mean, -MAX_LOG_STRETCH, MAX_LOG_STRETCH)
    radius_clipped = np.minimum(radius, MAX_LOG_STRETCH)
    scale = np.where(radius > 0, radius_clipped / np.where(radius > 0, radius, 1.0), 1.0)
    up, down = np.exp(mean + radius_clipped), np.exp(mean - radius_clipped)
    diagonal = 0.5 * (up + down)
    direct = radius_clipped > SERIES_THRESHOLD
    slope = np.where(direct, 0.5 * (up - down) / np.where(direct, radius_clipped, 1.0),
                     diagonal * (1.0 - radius_clipped ** 2 / 3.0)) * scale
    return np.stack([diagonal + slope * half, slope * off, diagonal - slope * half], axis=1)


def squared_stretch(u: np.ndarray) -> np.ndarray:
    """``U²`` of symmetric 2×2 matrices ``(u11, u12, u22)`` (m, 3), same packing: the metric
    ``G = UᵀU`` of a planar map with stretch ``U``."""
    a, b, c = u[:, 0], u[:, 1], u[:, 2]
    return np.stack([a * a + b * b, b * (a + c), b * b + c * c], axis=1)


def sqrt_det(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``√det G`` (m,) of symmetric 2×2 matrices ``(g11, g12, g22)`` (m, 3) and where they are
    positive definite (bool (m,); elsewhere the root is 1): the eigenvalues are ``μ ± ρ``. The
    rows that are not (rare) are set before the root: the same values as ``np.where`` of the two,
    which computes both on every row and costs more than the products (here and wherever a
    degenerate row takes another value)."""
    mean, _, _, radius = _symmetric_parts(g)
    low = mean - radius
    ok = low > np.finfo(float).tiny
    det = low * (mean + radius)
    det[~ok] = 1.0
    return np.sqrt(det), ok


def sqrt_stretch(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal square roots of symmetric 2×2 matrices ``(g11, g12, g22)`` (m, 3), same packing,
    and where they exist (bool (m,): positive definite): ``√G = (G + √det G · I) / √(tr G + 2 √det G)``
    (Cayley–Hamilton; the eigenvalues are ``μ ± ρ``). Rows that are not positive definite get I."""
    root_det, ok = sqrt_det(g)
    bad = ~ok
    trace = g[:, 0] + g[:, 2] + 2.0 * root_det
    trace[bad] = 4.0  # before the root (see sqrt_det)
    scale = 1.0 / np.sqrt(trace)
    out = np.stack([(g[:, 0] + root_det) * scale, g[:, 1] * scale, (g[:, 2] + root_det) * scale], axis=1)
    out[bad] = (1.0, 0.0, 1.0)
    return out, ok


def apply_stretch(s: np.ndarray, coordinates: np.ndarray) -> np.ndarray:
    """``S v`` for packed symmetric 2×2 ``s`` (m, 3) and tangent vectors ``coordinates`` (m, c, 2)."""
    x, y = coordinates[..., 0], coordinates[..., 1]
    return np.stack([s[:, 0, None] * x + s[:, 1, None] * y, s[:, 1, None] * x + s[:, 2, None] * y], axis=-1)


def rotated_frames(rotvec: np.ndarray, rotations: np.ndarray, components: np.ndarray,
                   column_rows: np.ndarray) -> np.ndarray:
    """Images ``R_T b_c`` (k, m, 3) of the base frame columns ``column_rows`` (k columns,
    3 coordinates, m) under the rotations ``R_T = M_{c(T)} · exp(rotvec_T)``: ``rotvec`` (m, 3)
    rotation vectors, ``rotations`` the components' rotations (C, 3, 3), ``components`` (m,) each
    triangle's component. Rodrigues' formula ``cos θ b + sinc θ (ω × b) + (1 − cos θ)/θ² ω (ω · b)`` on
    contiguous coordinate rows, then the components' rotations; returned as a (k, m, 3) view of
    rows stored (k columns, 3 coordinates, m) (no 3×3 matrix per triangle is formed: 3× faster
    than SciPy's ``Rotation.as_matrix`` and a batched product)."""
    w = np.ascontiguousarray(rotvec.T)
    theta2 = coordinate_dot(w, w)
    theta = np.sqrt(theta2)
    series = theta < SERIES_THRESHOLD
    safe = np.where(series, 1.0, theta)
    # cos θ and sin θ from t = tan(θ/2): one tangent and a few products, 0.10 against 0.46 ms for
    # np.cos and np.sin at 20k values (NumPy computes those one value at a time here)
    t = np.tan(0.5 * theta)
    t2 = t * t
    half_cos2 = 1.0 / (1.0 + t2)  # cos²(θ/2)
    cos = (1.0 - t2) * half_cos2
    sinc = np.where(series, 1.0 - theta2 / 6.0, 2.0 * t * half_cos2 / safe)
    versine = np.where(series, 0.5 - theta2 / 24.0, 2.0 * t2 * half_cos2 / (safe * safe))  # (1 − cos θ)/θ²
    out = np.empty_like(column_rows)
    for c in range(len(column_rows)):
        b = column_rows[c]
        out[c] = cos * b
        out[c] += sinc * coordinate_cross(w, b)
        out[c] += (versine * coordinate_dot(w, b)) * w
    return turned_coordinate_rows(out, rotations, components).transpose(0, 2, 1)


def turned_coordinate_rows(rows: np.ndarray, rotations: np.ndarray, components: np.ndarray) -> np.ndarray:
    """Vectors stored by coordinate (…, 3 coordinates, m) with column ``k`` turned by
    ``rotations[components[k]]`` (rotations (C, 3, 3))."""
    if len(rotations) == 1:
        return np.matmul(rotations[0], rows)
    if components.size and (np.diff(components) >= 0).all():
        # the pieces' columns in order (the usual case): one product per piece on a view of its
        # columns, 3.6 → 0.14 ms for two pieces of 10k triangles against the gathered blocks below
        bounds = np.searchsorted(components, np.arange(len(rotations) + 1))
        pieces = np.flatnonzero(np.diff(bounds))
        if pieces.size <= SLICED_PIECES:
            out = np.empty(rows.shape, dtype=np.result_type(rows, rotations))
            for c in pieces:
                columns = slice(bounds[c], bounds[c + 1])
                out[..., columns] = np.matmul(rotations[c], rows[..., columns])
            return out
    r = rotations[components]
    return np.stack([sum(r[:, a, b] * rows[..., b, :] for b in range(3)) for a in range(3)], axis=-2)


def turned_rows(vectors: np.ndarray, rotations: np.ndarray, components: np.ndarray) -> np.ndarray:
    """Vectors (…, m, 3) with row ``k`` turned by ``rotations[components[k]]`` (rotations
    (C, 3, 3)); one product with the matrix when there is one component."""
    if len(rotations) == 1:
        return vectors @ rotations[0].T
    return np.einsum("kab,...kb->...ka", rotations[components], vectors)


def plane_turned_frames(columns: np.ndarray, turn: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Frames ``B · Rz(θ)`` stored by coordinate (3 columns, 3 coordinates, m) for tangent frames
    ``columns`` ``B`` stored the same way, turned in their plane by ``turn = (cos θ, sin θ)``
    ((m,) each): the images of a base triangle's frame under the rotation ``B · Rz(θ) · B_baseᵀ``
    that takes it to the triangle of ``columns`` (the polar rotation of the planar map turns it by
    ``θ`` first)."""
    cos, sin = turn
    out = np.empty_like(columns)
    out[0] = cos * columns[0] + sin * columns[1]
    out[1] = cos * columns[1] - sin * columns[0]
    out[2] = columns[2]
    return out


def rotation_vectors(rotations: np.ndarray) -> np.ndarray:
    """Rotation vectors (m, 3) (angle ≤ π) of rotation matrices (m, 3, 3), through unit
    quaternions by Shepperd's method (the largest of the four candidate components is divided by,
    stable at every angle including half turns); the same as SciPy's ``Rotation.as_rotvec``,
    whose ``from_matrix`` re-orthogonalizes each matrix and costs 20× more."""
    return rotation_vectors_of_entries([[rotations[:, a, b] for b in range(3)] for a in range(3)])


def frame_rows_rotation_vectors(frames: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Rotation vectors (m, 3) of the rotations taking frames ``columns`` to ``frames``, both
    stored by coordinate (3 columns, 3 coordinates, m): :func:`rotation_vectors_of_entries` of
    :func:`frame_rows_rotation_entries` (3× faster than :func:`rotation_vectors` of the products)."""
    return rotation_vectors_of_entries(frame_rows_rotation_entries(frames, columns))


def frame_rows_rotation_entries(frames: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """The nine entries (3, 3, m) of the rotations ``R = Σ_c f_c b_cᵀ`` taking frames ``columns``
    to ``frames``, both stored by coordinate (3 columns, 3 coordinates, m): ``[a, b]`` is entry
    ``R_ab`` of every triangle, formed on contiguous (m,) rows (no (m, 3, 3) array)."""
    f, b = frames, columns
    out = np.empty((3, 3) + f.shape[2:], dtype=np.result_type(f, b))
    product = np.empty(f.shape[2:], dtype=out.dtype)
    for a in range(3):
        for c in range(3):  # (f0a b0c + f1a b1c) + f2a b2c, summed in place
            entry = out[a, c]
            np.multiply(f[0, a], b[0, c], out=entry)
            entry += np.multiply(f[1, a], b[1, c], out=product)
            entry += np.multiply(f[2, a], b[2, c], out=product)
    return out


def entries_rotation_angles(entries: np.ndarray) -> np.ndarray:
    """The angles (m,) of rotations given by their entries (3, 3, m) (as
    :func:`frame_rows_rotation_entries` gives them), from the trace."""
    return trace_rotation_angles(entries[0, 0] + entries[1, 1] + entries[2, 2])


def trace_rotation_angles(trace: np.ndarray) -> np.ndarray:
    """The angles (m,) of rotations whose traces are ``trace`` (m,): ``tr R = 1 + 2 cos θ``
    (clipped to the cosine's range against rounding)."""
    return np.arccos(np.clip(0.5 * (trace - 1.0), -1.0, 1.0))


def turned_frame_rows(columns: np.ndarray, turn: tuple[np.ndarray, np.ndarray], rotations: np.ndarray,
                      components: np.ndarray) -> np.ndarray:
    """:func:`plane_turned_frames` followed by :func:`turned_coordinate_rows`, on frames stored by
    coordinate (3 columns, 3 coordinates, m): ``M_c · B · Rz(θ)`` for ``columns`` ``B``,
    ``turn = (cos θ, sin θ)`` ((m,) each) and the rotations (C, 3, 3) of each triangle's component."""
    return turned_coordinate_rows(plane_turned_frames(columns, turn), rotations, components)


def rotation_vectors_of_entries(r) -> np.ndarray:
    """Rotation vectors (m, 3) (angle ≤ π) of rotation matrices given by their entries ``r[a][b]``
    ((m,) each; a nested list or an array (3, 3, m)), by Shepperd's method: the
    quaternion from the trace for every row (the common case: turns below ~120°), re-done from
    the largest diagonal entry on the rows where that entry exceeds the trace."""
    trace = r[0][0] + r[1][1] + r[2][2]
    w4 = 2.0 * np.sqrt(np.maximum(1.0 + trace, 0.0))  # 4w
    q = np.empty((4, len(trace)))  # rows x, y, z, w
    with np.errstate(divide="ignore", invalid="ignore"):  # rows with w4 = 0 are re-done below
        np.divide(r[2][1] - r[1][2], w4, out=q[0])
        np.divide(r[0][2] - r[2][0], w4, out=q[1])
        np.divide(r[1][0] - r[0][1], w4, out=q[2])
    np.multiply(0.25, w4, out=q[3])
    redo = np.flatnonzero(np.maximum(np.maximum(r[0][0], r[1][1]), r[2][2]) > trace)
    if redo.size:
        choice = np.argmax(np.stack([r[i][i][redo] for i in range(3)]), axis=0)
        for i in range(3):
            rows = redo[choice == i]
            if not rows.size:
                continue
            e = [[r[a][b][rows] for b in range(3)] for a in range(3)]
            j, l = (i + 1) % 3, (i + 2) % 3
            big4 = 2.0 * np.sqrt(np.maximum(1.0 + e[i][i] - e[j][j] - e[l][l], 0.0))  # 4 × the component
            q[i, rows] = 0.25 * big4
            q[j, rows] = (e[j][i] + e[i][j]) / big4
            q[l, rows] = (e[l][i] + e[i][l]) / big4
            q[3, rows] = (e[l][j] - e[j][l]) / big4
    flip = np.flatnonzero(q[3] < 0)  # w ≥ 0: angle ≤ π (only rows re-done above can have w < 0)
    if flip.size:
        q[:, flip] *= -1.0
    sin_half = np.sqrt(coordinate_dot(q[:3], q[:3]))
    angle = 2.0 * np.arctan2(sin_half, q[3])
    scale = np.where(sin_half > SERIES_THRESHOLD, angle / np.where(sin_half > 0, sin_half, 1.0), 2.0)
    return (q[:3] * scale).T
