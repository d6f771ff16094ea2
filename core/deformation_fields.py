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
along screw motions (the exponential map of SE(3)).

Shapes: ``m`` triangles, ``n`` vertices; corner edge ``c`` of a triangle runs from its corner ``c``
to corner ``c + 1`` (mod 3).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .geometry import coordinate_cross, coordinate_dot

#: Smallest ratio (radius / mean eigenvalue, or angle in radians) at which the closed-form
#: expressions below are evaluated directly; below it their Taylor series (error < 1e-16).
SERIES_THRESHOLD = 1e-4
#: Relative cutoff of the singular values of ``V(ω)`` when solving for a screw's ``v``: far below
#: the smallest a turn short of a whole one has (θ = 2π − 1e-5: ~1e-6), far above round-off.
SCREW_CUTOFF = 1e-12
#: Log-stretch eigenvalues are clipped to ±this before exponentiating (a stretch by e^30 is far
#: outside anything a pose can mean; the clip only keeps extrapolations finite).
MAX_LOG_STRETCH = 30.0
#: Rotations within this angle (radians) of a half turn may turn either way: both are as short.
#: Far above rounding (1e-15) and far below any motion meant to turn one way.
HALF_TURN_TOLERANCE = 1e-6
#: A piece's rotation fitted to keys that are not exactly rigid is known to about its RMS misfit
#: over its size (radians); this many times that is its ``spread`` (:func:`rigid_logs`), within
#: which of a half turn it may turn either way too and of none it is none: float32 keys as Blender
#: keeps them read a 0.2-wide piece 100 units out ~1e-5 rad "short of a half turn the other way"
#: (turned against the rest of its mesh) and a card keyed two half turns on ~1e-6 rad about an
#: axis of rounding (continued a whole turn about it, off its circle); 300 cards of 4 vertices 10
#: units out: their angles' errors up to 30 × their misfit over size ...
TURN_NOISE = 100.0
#: ... but never more than this (radians): a piece deforming more turns the short way.
TURN_SPREAD = 1e-2
#: Rotations within this angle (radians) of none are the identity when a turn is continued
#: (``unwrap``): the identity's representatives are ``2πk u`` for every axis ``u``, and the axis
#: of a rotation vector of length ~1e-16 is rounding noise (a sheet keyed every half turn: its key
#: two half turns on was continued about a random axis, 181 % edge deviation half-way).
ZERO_TURN_TOLERANCE = 1e-9
#: Neighbouring triangles whose rotation vectors jump past a half turn (:func:`continuous_rotation_vectors`)
#: while their rotations differ by more than this (radians) meet at a fold's crease, which says
#: nothing of the way round: a sequence's part turning past a half turn is taken continuous across
#: the mesh only where none of its piece's jumps is one. A closed tube or a thin arm curled 120–170°
#: per key at two joints jumps between neighbours 0.2–9.2° apart (their bend per ring of the mesh);
#: a sheet swinging off a rod that stops dead, keys 4 / 8 frames apart, 22–55 / 37–58° (medians
#: 50 / 53°): taken continuous there, its in-betweens went 0.54 / 0.50 → 5.7 / 1.4 × the linear
#: blend's error. A piece none of whose neighbours' rotations are that far apart bends without a
#: crease (:data:`core.inbetween_keys.BENT_TURN`).
WRAP_CREASE = np.pi / 6
#: Meshes of at most this many pieces are turned one piece at a time (a 3×3 product per piece on a
#: view of its rows or columns where they are consecutive, ~5 µs of Python each), more pieces by
#: gathered 3×3 blocks per vertex or triangle: here in :func:`turned_coordinate_rows` (two pieces of
#: 10k triangles 3.6 → 0.14 ms) and in the sequences' rigid motions
#: (``core.inbetween_topology._Topology.apply_motion``: two 5k sheets 2.17 → 0.14 ms per call).
SLICED_PIECES = 64


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched products ``a @ b`` of small matrices (…, p, q) × (…, q, r), written out per entry:
    NumPy's batched ``matmul`` and ``einsum`` loop over the batch with per-matrix overhead and are
    5–10× slower for 2×2 and 3×3 blocks."""
    a, b = np.asarray(a), np.asarray(b)
    shape = np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + (a.shape[-2], b.shape[-1])
    out = np.empty(shape)
    for i in range(a.shape[-2]):
        for j in range(b.shape[-1]):
            entry = a[..., i, 0] * b[..., 0, j]
            for k in range(1, a.shape[-1]):
                entry = entry + a[..., i, k] * b[..., k, j]
            out[..., i, j] = entry
    return out


def transpose(a: np.ndarray) -> np.ndarray:
    """``a`` (…, p, q) with its last two axes swapped."""
    return np.swapaxes(a, -1, -2)


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
    zero = radius == 0  # the angle of (0, 0) is 0
    radius = np.where(zero, 1.0, radius)
    cos, sin = np.where(zero, 1.0, x / radius), y / radius
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
    positive definite (bool (m,); elsewhere the root is 1): the eigenvalues are ``μ ± ρ``."""
    mean, _, _, radius = _symmetric_parts(g)
    ok = mean - radius > np.finfo(float).tiny
    return np.sqrt(np.where(ok, (mean - radius) * (mean + radius), 1.0)), ok


def sqrt_stretch(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal square roots of symmetric 2×2 matrices ``(g11, g12, g22)`` (m, 3), same packing,
    and where they exist (bool (m,): positive definite): ``√G = (G + √det G · I) / √(tr G + 2 √det G)``
    (Cayley–Hamilton; the eigenvalues are ``μ ± ρ``). Rows that are not positive definite get I."""
    root_det, ok = sqrt_det(g)
    scale = 1.0 / np.sqrt(np.where(ok, g[:, 0] + g[:, 2] + 2.0 * root_det, 4.0))
    out = np.stack([(g[:, 0] + root_det) * scale, g[:, 1] * scale, (g[:, 2] + root_det) * scale], axis=1)
    out[~ok] = (1.0, 0.0, 1.0)
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
    return _rotation_vectors_of_entries([[rotations[:, a, b] for b in range(3)] for a in range(3)])


def frame_rows_rotation_vectors(frames: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Rotation vectors (m, 3) of the rotations taking frames ``columns`` to ``frames``, both
    stored by coordinate (3 columns, 3 coordinates, m): the nine entries of ``R = Σ_c f_c b_cᵀ``
    formed on contiguous (m,) rows, no (m, 3, 3) array (3× faster than :func:`rotation_vectors`
    of the products)."""
    f, b = frames, columns
    return _rotation_vectors_of_entries([[f[0, a] * b[0, c] + f[1, a] * b[1, c] + f[2, a] * b[2, c]
                                          for c in range(3)] for a in range(3)])


def turned_frame_rows(columns: np.ndarray, turn: tuple[np.ndarray, np.ndarray], rotations: np.ndarray,
                      components: np.ndarray) -> np.ndarray:
    """:func:`plane_turned_frames` followed by :func:`turned_coordinate_rows`, on frames stored by
    coordinate (3 columns, 3 coordinates, m): ``M_c · B · Rz(θ)`` for ``columns`` ``B``,
    ``turn = (cos θ, sin θ)`` ((m,) each) and the rotations (C, 3, 3) of each triangle's component."""
    return turned_coordinate_rows(plane_turned_frames(columns, turn), rotations, components)


def _rotation_vectors_of_entries(r) -> np.ndarray:
    """Shepperd's method on the entries ``r[a][b]`` ((m,) each) of rotation matrices: the
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
    q *= np.where(q[3] < 0, -1.0, 1.0)  # w ≥ 0: angle ≤ π
    sin_half = np.sqrt(coordinate_dot(q[:3], q[:3]))
    angle = 2.0 * np.arctan2(sin_half, q[3])
    scale = np.where(sin_half > SERIES_THRESHOLD, angle / np.where(sin_half > 0, sin_half, 1.0), 2.0)
    return (q[:3] * scale).T


# ---------------------------------------------------------------------------------------------
# rigid motions of the whole mesh (screw interpolation)


def _screw_coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a = (1 − cos θ)/θ²`` and ``b = (θ − sin θ)/θ³`` for rotation angles ``theta`` (…), by
    their series below :data:`SERIES_THRESHOLD`."""
    direct = theta > SERIES_THRESHOLD
    safe = np.where(direct, theta, 1.0)
    a = np.where(direct, (1.0 - np.cos(safe)) / safe ** 2, 0.5 - theta ** 2 / 24.0)
    b = np.where(direct, (safe - np.sin(safe)) / safe ** 3, 1.0 / 6.0 - theta ** 2 / 120.0)
    return a, b


def rigid_log(rotation: np.ndarray, translation: np.ndarray, reference: np.ndarray | None = None,
              unwrap: bool = False) -> np.ndarray:
    """Screw coordinates ``(ω, v)`` (6,) of the rigid motion ``x ↦ R x + t``: one row of
    :func:`rigid_logs`."""
    references = None if reference is None else np.asarray(reference, dtype=np.float64)[None]
    return rigid_logs(rotation[None], np.asarray(translation)[None], references, unwrap)[0]


def either_way(theta: np.ndarray, spread: np.ndarray | float = 0.0) -> np.ndarray:
    """Whether rotations of angles ``theta`` (radians) are half turns as short either way round:
    within :data:`HALF_TURN_TOLERANCE` of π, or within their ``spread`` (what each is known to)."""
    return np.abs(np.asarray(theta) - np.pi) < np.maximum(HALF_TURN_TOLERANCE, spread)


def rigid_logs(rotations: np.ndarray, translations: np.ndarray, references: np.ndarray | None = None,
               unwrap: bool = False, spread: np.ndarray | float = 0.0) -> np.ndarray:
    """Screw coordinates ``(ω, v)`` (P, 6) of the rigid motions ``x ↦ R x + t`` (rotations
    (P, 3, 3), translations (P, 3)), the short way round. With ``references`` (rotation vectors
    (P, 3), or screw coordinates (P, 6) whose first three are one): a half turn (within
    :data:`HALF_TURN_TOLERANCE` of π, or the row's ``spread`` (radians, per row or one for all: what
    its rotation is known to), both directions are as short) turns the way nearer to its
    row, and with ``unwrap`` the representative ``ω + 2πk ω̂`` nearest to it is taken (a motion
    continuing across keys; k = −1 is the same rotation the other way round, ``−ω`` would be its
    inverse). A rotation within :data:`ZERO_TURN_TOLERANCE` of none continued a whole turn about
    its reference's axis (or within its ``spread``) takes the part of ``v`` that no translation fixes there (``V(2πû)`` maps
    it to zero) from a reference screw: the continuation of a turn about a fixed axis stays about
    that axis. ``v`` is the least-squares (minimum-norm) solution of ``V(ω) v = t``."""
    w = rotation_vectors(rotations)
    translations = np.asarray(translations, dtype=np.float64)
    whole_turn = np.zeros(len(w), dtype=bool)
    if references is not None:
        references = np.asarray(references, dtype=np.float64)
        turn = references[:, :3]
        theta = np.linalg.norm(w, axis=1)
        if unwrap:  # every row (a half turn with a null reference goes the first way, k = −1)
            # within its spread of none only where the reference is nearer a whole turn than none
            # (|reference| ≥ π; a small real turn continuing a small reference stays what it is)
            still = (theta <= ZERO_TURN_TOLERANCE) | (
                (theta <= spread) & (np.einsum("ij,ij->i", turn, turn) >= np.pi ** 2))
            w = _nearest_representatives(w, theta, turn, np.flatnonzero(still), np.flatnonzero(~still))
            whole_turn = still & w.any(axis=1)
        else:
            half = either_way(theta, spread) & (np.einsum("ij,ij->i", w, turn) < 0)
            # the same rotation the long way round, ω − 2π ω̂ (−ω, its inverse, differs from it by
            # 2(π − θ): within a spread of 1e-2 a piece jumped at every key, 4.8e-2 of its diagonal)
            w = np.where(half[:, None], the_other_way(w, theta), w)
    a, b = _screw_coefficients(np.sqrt(np.einsum("ij,ij->i", w, w)))
    h = _hats(w)  # V(ω) = I + a [ω] + b [ω]²: the translation part of SE(3)'s exponential
    matrices = np.eye(3) + a[:, None, None] * h + b[:, None, None] * (h @ h)
    # the part a whole turn's V(2πû) cannot give comes from the reference's v (the least change)
    held = whole_turn & (references is not None and references.shape[1] == 6)
    base = np.where(held[:, None], references[:, 3:], 0.0) if held.any() else np.zeros_like(translations)
    rhs = translations - np.einsum("pab,pb->pa", matrices, base)
    return np.concatenate([w, base + least_squares_3x3(matrices, rhs)], axis=1)


def the_other_way(w: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The rotation vectors (P, 3) of the rotations ``w`` (P, 3; angles ``theta`` (P,)) taken the
    other way round, ``ω − 2π ω̂``: the same rotations (``−ω`` is their inverse); rows with a zero
    angle are left as they are."""
    return w - (2.0 * np.pi / np.where(theta > 0, theta, np.inf))[:, None] * w


def _hats(w: np.ndarray) -> np.ndarray:
    """The cross-product matrices [ω] (P, 3, 3) of the rows of ``w`` (P, 3)."""
    h = np.zeros((len(w), 3, 3))
    h[:, 0, 1], h[:, 0, 2], h[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    h[:, 1, 0], h[:, 2, 0], h[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return h


def least_squares_3x3(matrices: np.ndarray, rhs: np.ndarray, cutoff: np.ndarray | float = SCREW_CUTOFF) -> np.ndarray:
    """The minimum-norm least-squares solutions (P, 3) of ``matrices`` (P, 3, 3) ``x = rhs``
    (P, 3), singular values below ``cutoff`` (per row or one) times the largest dropped, by one batched
    SVD. ``V(2πkû) = ûûᵀ`` has rank one: its two zero singular values come out at round-off
    (2e-16–3e-16 for k = 3), within a factor of three of NumPy's ``lstsq`` cutoff (3 ε)."""
    u, sigma, vt = np.linalg.svd(matrices)
    cutoff = np.reshape(cutoff, (-1, 1)) * sigma[:, :1]
    inverse = np.where(sigma > cutoff, 1.0 / np.where(sigma > 0, sigma, 1.0), 0.0)
    return np.einsum("pji,pj->pi", vt, inverse * np.einsum("pji,pj->pi", u, rhs))


def unwrapped_rotation_vectors(rotvec: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Rotation vectors (m, 3) of the rotations ``rotvec`` (m, 3), each the representative
    ``ω + 2πk ω̂`` (k = −1, 0, 1, and further where the reference is past 2π) nearest its row of
    ``reference`` (m, 3): a turn continuing across keys past a half turn (the per-row counterpart
    of :func:`rigid_log`'s ``unwrap``). Only rows
    with ``|ω| + |reference| > π`` can change (elsewhere ``ω`` is within π of the reference and the
    other representatives are farther)."""
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    reach = np.sqrt(np.einsum("ij,ij->i", reference, reference))
    identity = np.flatnonzero((theta <= ZERO_TURN_TOLERANCE) & (reach > np.pi))
    rows = np.flatnonzero((theta + reach > np.pi) & (theta > ZERO_TURN_TOLERANCE))
    if not rows.size and not identity.size:
        return rotvec
    return _nearest_representatives(rotvec, theta, reference, identity, rows)


def continuous_rotation_vectors(rotvec: np.ndarray, pairs: np.ndarray, pieces: np.ndarray, turned=None,
                                toward=None, free=None) -> np.ndarray:
    """Rotation vectors (m, 3) of the rotations ``rotvec`` (m, 3) of a mesh's triangles, continuous
    across its edges past a half turn: ``pairs`` (E, 2) are the triangles sharing an edge. A part
    that turns by more than a half turn while the part it hangs from does not (a strip curled by
    240° on one arc: its tip turns by 240°, which the principal rotation vector, at most π, takes
    as 120° the other way) has its rotation vectors jump where their angle passes π; the
    in-between turns every triangle by its vector times the factor, so the part beyond the jump
    went the other way round. Across such a jump (a neighbour's other representative
    ``ω ± 2π ω̂`` nearer than its own: :func:`jumping_pairs`) the mesh is cut into
    regions; in each connected set of regions the one holding the least-turned triangle keeps its
    vectors, and each region reached from it across a jump takes the representatives continuous
    across it. ``pieces``: each triangle's connected piece of the mesh (m,). ``turned``: a function returning how far each triangle turns (m,) when that is not
    the angle of ``rotvec`` (residuals to a rigid motion: the part that stays put is the one whose
    whole rotation is least, whatever its residual), called only where there is a jump.
    ``toward``: the rotation vectors (m, 3) of the rigid motion each triangle's piece makes and the
    triangles' weights (m,) (their areas), or None. Continued from either end, a part turning by
    a whole turn more than the other end has the same turns between neighbours: the two readings
    differ by a whole turn of the entire piece (a tail whose root turns −60° and tip −300° read
    from the tip as +300° / +60°), and where both ends turn about as little the least-turned
    triangle picks one by the mesh's tessellation. With ``toward``, a linked set of regions whose
    least turns exceed its root's by no more than the root's own (a root that turns so is not
    known to stay) plus the step of the turn from either least-turned triangle to its neighbours
    (the mesh samples the turn no finer) is continued from the one of them whose reading
    is nearest the rigid motion's, in the weighted least squares along each triangle's axis (the
    piece as a whole turning as its rigid fit): the rigid fit's principal rotation does not tell
    the way round past a half turn itself (a strip held at one end and curled by 220° fits +129°
    the other way), so it only breaks the tie — after the count of neighbours whose readings'
    vectors lie more than :data:`WRAP_CREASE` apart: a whole turn of every triangle about its own
    axis is one turn of the piece only where those axes agree (a tail wagging about one axis), and
    where they part (an arm curling about y while it turns a little about z) a reading that keeps
    fewer than half as many neighbours that far apart as every other is taken (the arm curled
    170° per key at two joints turning 10° per key about z: its part that stays turns 10°, its
    tip 22°, and the rigid fit, reading the curl the other way round, took the tip: 27–78 % of
    the diagonal off). ``free``: per triangle
    (bool (m,)) or None, whether its linked set's least-turned region is not known to stay (the
    readings of a sequence's gaps disagree there): every region of such a set is tied, and the
    rigid motion picks.

    A connected piece left with a jump (its jumps do not close up: crumpled cloth, around whose
    folds the rotations wind by a whole turn) keeps its principal vectors: taken across the mesh
    there, two poses of a banner 8 / 16 frames apart went 0.747 / 0.832 → 0.792 / 0.923 × the
    blend's error (edge deviation 3.53 / 6.15 → 4.21 / 7.04 %). Whether a jump joins a fold's
    crease rather than a smooth part wrapping past a half turn is the caller's to tell
    (:func:`creased` on :func:`jumping_pairs`, :data:`WRAP_CREASE`). Rotations that never come near
    a half turn are returned as they are."""
    if not len(pairs):
        return rotvec
    jumps = jumping_pairs(rotvec, pairs)
    if not jumps.any():
        return rotvec
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    m = len(rotvec)
    joined = pairs[~jumps]
    count, region = connected_components(coo_matrix((np.ones(len(joined)), (joined[:, 0], joined[:, 1])), shape=(m, m)),
                                         directed=False)
    across = pairs[jumps]
    within = region[across[:, 0]] == region[across[:, 1]]
    if within.any():  # a jump inside one region cannot be undone: its piece is left as it is
        across = across[~np.isin(pieces[across[:, 0]], pieces[across[within, 0]])]
    if not across.size:
        return rotvec
    # the regions linked by jumps, one jump per linked pair of regions ((region, region) → its jump)
    ends = np.sort(region[across], axis=1)
    _, first = np.unique(ends, axis=0, return_index=True)
    links = coo_matrix((np.ones(len(first)), (ends[first, 0], ends[first, 1])), shape=(count, count))
    link = dict(zip(map(tuple, ends[first].tolist()), first.tolist()))
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    least = np.full(count, np.inf)
    amount = theta if turned is None else turned()
    np.minimum.at(least, region, amount)
    # each linked set's least-turned region (the first in the order of least turn) is its root; one
    # search from a node joined to the roots reaches every linked region (a search from each root
    # costs a pass over all regions: 0.4 s at 3,000 pieces with a single jump)
    by_least = np.argsort(least, kind="stable")
    _, sets = connected_components(links, directed=False)
    _, firsts = np.unique(sets[by_least], return_index=True)
    roots = by_least[firsts]
    roots = roots[np.isin(roots, ends[first])]  # a region with no link has nothing to take
    tails, heads = np.r_[ends[first, 0], np.full(len(roots), count)], np.r_[ends[first, 1], roots]
    graph = coo_matrix((np.ones(len(tails)), (tails, heads)), shape=(count + 1, count + 1))
    order, parent = breadth_first_order(graph.tocsr(), count, directed=False, return_predecessors=True)
    turns = np.zeros(count + 1)  # whole turns added per region (and the joining node's: none)
    axis = rotvec / np.where(theta > 0, theta, 1.0)[:, None]
    for r in order[1:]:
        if parent[r] == count:  # a root keeps its vectors
            continue
        pair = across[link[(min(parent[r], r), max(parent[r], r))]]
        inside, outside = (pair[0], pair[1]) if region[pair[1]] == r else (pair[1], pair[0])
        reached = rotvec[inside] + 2.0 * np.pi * turns[parent[r]] * axis[inside]
        turns[r] = np.round(np.dot(reached - rotvec[outside], axis[outside]) / (2.0 * np.pi))
    if toward is not None:
        reference, weights = toward
        linked = np.zeros(count + 1, dtype=bool)
        linked[ends[first].ravel()] = True
        rows = np.flatnonzero(linked[region])
        # a region's continued vectors (θ + 2π·turns) â point along u = ±â (θ ≤ π, â the principal
        # axis: the reverse where turns < 0), continuous across the mesh; a whole turn k more of
        # the entire set adds 2π k u, and k = −turns·sign makes a region the root. The k nearest
        # the rigid motion (minimising Σ w (|θ + 2π·turns| + 2πk − reference · u)² over the set)
        direction = np.where(turns[:count] >= 0, 1.0, -1.0)
        along = direction[region[rows]] * np.einsum("ij,ij->i", reference[rows], axis[rows])
        off = along - np.abs(theta[rows] + 2.0 * np.pi * turns[region[rows]])
        owner = sets[region[rows]]
        total = np.bincount(owner, weights[rows], minlength=len(sets))
        nearest = np.bincount(owner, weights[rows] * off, minlength=len(sets)) \
            / (2.0 * np.pi * np.maximum(total, np.finfo(float).tiny))
        # ... among the regions whose least turn exceeds the root's by no more than the root's
        # own (a root turning by that much is not known to be the part that stays) plus the step
        # of the turn from their least-turned triangle, or the root's, to its joined neighbours
        # (the mesh samples the rotations no finer there); elsewhere the root stays
        step = turn_steps(amount, joined)
        by_turn = np.lexsort((amount, region))
        _, lowest_row = np.unique(region[by_turn], return_index=True)
        resolution = step[by_turn[lowest_row]]  # per region: the step at its least-turned triangle
        root_of = np.zeros(len(sets), dtype=np.int64)
        root_of[sets[roots]] = roots
        root = root_of[sets]
        margin = least[root] + np.maximum(resolution, resolution[root])
        loose = np.zeros(len(sets), dtype=bool)
        if free is not None:
            loose[sets[region[free]]] = True
        tied = np.flatnonzero(linked[:count] & ((least - least[root] <= margin) | loose[sets]))
        candidate = -turns[tied] * direction[tied]
        # a whole turn of the entire set is one rigid turn only where its triangles turn about one
        # axis (a wagging tail); where their axes part (an arm curling about one axis while it
        # turns a little about another) the readings differ in shape, and one that joins fewer
        # neighbours more than WRAP_CREASE apart than half of every other's is taken before the
        # rigid motion is asked (counts within twice the least do not tell: a mesh creased all
        # over keeps about as many apart either way); not where the set is free: there the
        # readings of the gaps around decide, through the rigid turn
        counts = np.zeros(len(tied))
        strict = ~loose[sets[tied]]
        counts[strict] = _creases_read(rotvec, pairs, region, sets, turns[:count], direction, axis, linked[:count],
                                       tied[strict], candidate[strict])
        fewest = np.full(len(sets), np.inf)
        np.minimum.at(fewest, sets[tied], counts)
        order = np.lexsort((np.abs(candidate - nearest[sets[tied]]), counts > 2.0 * fewest[sets[tied]], sets[tied]))
        _, best = np.unique(sets[tied[order]], return_index=True)
        shift = np.zeros(len(sets))
        shift[sets[tied[order[best]]]] = candidate[order[best]]
        turns[:count] += np.where(linked[:count], shift[sets] * direction, 0.0)
    if not turns.any():
        return rotvec
    out = rotvec + (2.0 * np.pi * turns[region])[:, None] * axis
    left = jumping_pairs(out, pairs)
    if left.any():  # the pieces with a jump left keep their principal vectors
        kept = np.isin(pieces, pieces[pairs[left, 0]])
        out[kept] = rotvec[kept]
    return out


def _creases_read(rotvec: np.ndarray, pairs: np.ndarray, region: np.ndarray, sets: np.ndarray, turns: np.ndarray,
                  direction: np.ndarray, axis: np.ndarray, linked: np.ndarray, tied: np.ndarray,
                  candidate: np.ndarray) -> np.ndarray:
    """For each tied region ``tied`` (T,) of :func:`continuous_rotation_vectors` (its linked set read
    from it: the set's whole turns ``turns`` (per region) plus ``candidate`` (T,) × ``direction``),
    how many neighbouring triangles of its set (``pairs`` (E, 2)) get rotation vectors more than
    :data:`WRAP_CREASE` apart: the in-betweens turn each triangle by its vector times the factor,
    so those neighbours part by up to that angle. Counted only in sets with more than one tied
    region (elsewhere 0: nothing to choose)."""
    out = np.zeros(len(tied))
    several = np.bincount(sets[tied], minlength=len(sets)) > 1
    if not several[sets[tied]].any():
        return out
    first, second = region[pairs[:, 0]], region[pairs[:, 1]]
    inside = pairs[linked[first] & linked[second] & (sets[first] == sets[second]) & several[sets[first]]]
    owner = sets[region[inside[:, 0]]]
    for i in np.flatnonzero(several[sets[tied]]):
        ends = inside[owner == sets[tied[i]]]
        whole = 2.0 * np.pi * (turns + candidate[i] * direction)[region[ends]]  # (P, 2)
        vectors = rotvec[ends] + whole[:, :, None] * axis[ends]
        apart = np.linalg.norm(vectors[:, 0] - vectors[:, 1], axis=1)
        out[i] = np.count_nonzero(apart > WRAP_CREASE)
    return out


def turn_steps(amount: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Per triangle (m,), the largest change of its turn ``amount`` (m,) to a neighbour across
    ``pairs`` (E, 2): how finely the mesh samples the turn there."""
    step = np.zeros(len(amount))
    change = np.abs(amount[pairs[:, 0]] - amount[pairs[:, 1]])
    np.maximum.at(step, pairs[:, 0], change)
    np.maximum.at(step, pairs[:, 1], change)
    return step


def creased(rotvec: np.ndarray, pairs: np.ndarray, crease: float) -> np.ndarray:
    """Per pair of triangles (bool (E,); ``pairs`` (E, 2) indices into ``rotvec`` (m, 3)), whether
    their rotations differ by more than ``crease`` (radians, whichever representative each vector
    is): the unit quaternions' ``|q₁ · q₂|``, the cosine of half that angle, below ``cos(crease / 2)``
    (composing the rotations and taking the angle costs 5 × more: 0.33 s on 270k pairs). Each
    triangle's quaternion is made once where the pairs name more rows than the mesh has."""
    if pairs.size > len(rotvec):
        quaternions = Rotation.from_rotvec(rotvec).as_quat()
        first, second = quaternions[pairs[:, 0]], quaternions[pairs[:, 1]]
    else:
        first, second = (Rotation.from_rotvec(rotvec[pairs[:, k]]).as_quat() for k in (0, 1))
    return np.abs(np.einsum("ij,ij->i", first, second)) < np.cos(0.5 * crease)


def jumping_pairs(rotvec: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Per pair of neighbouring triangles (bool (E,)), whether the second's rotation vector jumps
    past a half turn from the first's: another of its representatives is nearer the first's."""
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    near = np.flatnonzero(theta[pairs[:, 0]] + theta[pairs[:, 1]] > np.pi)  # only these can jump
    out = np.zeros(len(pairs), dtype=bool)
    if near.size:
        first, second = rotvec[pairs[near, 0]], rotvec[pairs[near, 1]]
        whole = (2.0 * np.pi / np.maximum(theta[pairs[near, 1]], ZERO_TURN_TOLERANCE))[:, None] * second
        gap = second - first
        # |gap ± whole|² = |gap|² ± 2 gap·whole + |whole|²: below |gap|² where |2 gap·whole| > |whole|²
        out[near] = 2.0 * np.abs(np.einsum("ij,ij->i", gap, whole)) > np.einsum("ij,ij->i", whole, whole)
    return out


def _nearest_representatives(rotvec, theta, reference, identity, rows) -> np.ndarray:
    """``rotvec`` (m, 3) (angles ``theta``) with the ``identity`` rows replaced by the whole turns
    nearest their ``reference`` rows and the ``rows`` by the representative ``ω + 2πk ω̂``
    (k = −1, 0, 1, the first of equally near ones) nearest theirs; k = ±2 … as well where a
    reference reaches past 2π (the nearest is ``k = round((r − θ) / 2π)``, ``r`` the reference along
    the axis, so ``|k| ≤ |r| / 2π + 1``: a part of an arm turning 280° per gap continued to 560° at
    the key after, its principal axis reversed past 3π, needs ``k = −2`` from a reference of 2.9π)."""
    out = rotvec.copy()
    out[identity] = _unwrapped_identity(reference[identity])
    if not rows.size:
        return out
    axis = rotvec[rows] / theta[rows, None]
    reach = np.sqrt(np.max(np.einsum("ij,ij->i", reference[rows], reference[rows])))
    turns = int(reach // (2 * np.pi)) + 1
    candidates = np.stack([(theta[rows] + 2 * np.pi * k)[:, None] * axis for k in range(-turns, turns + 1)])
    distance = np.einsum("krj,krj->kr", candidates - reference[rows], candidates - reference[rows])
    out[rows] = candidates[np.argmin(distance, axis=0), np.arange(rows.size)]
    return out


def screw_left_jacobians(screws: np.ndarray) -> np.ndarray:
    """The left Jacobians (P, 6, 6) of SE(3)'s exponential at screw coordinates ``(ω, v)``
    (P, 6): ``(d exp(S)) exp(S)⁻¹ = (J dS)^``, the series ``Σ adₛⁿ / (n + 1)!``, read off the
    exponential of a 12 × 12 block matrix (SciPy's ``expm``)."""
    block = np.zeros((len(screws), 12, 12))
    w = _hats(screws[:, :3])
    block[:, :3, :3] = block[:, 3:6, 3:6] = w
    block[:, 3:6, :3] = _hats(screws[:, 3:])
    block[:, :6, 6:] = np.eye(6)
    from scipy.linalg import expm  # lazily: scipy.linalg is not loaded by the rest of this module

    return expm(block)[:, :6, 6:]


def continued_screws(screws: np.ndarray, motions: tuple, farther: tuple, spread: np.ndarray | float = 0.0) -> np.ndarray:
    """Screw coordinates (P, 6) to stand in a Catmull–Rom spline of screws for keys two steps on,
    whose next keys are ``screws`` (P, 6) (the rigid motions ``motions``: rotations (P, 3, 3),
    translations (P, 3)) and which are the rigid motions ``farther``: ``J(S)⁻¹ (S + T)``, ``T``
    the step from the next key on (the short way round; a half turn, to within ``spread`` as
    :func:`rigid_logs` takes it, the way ``S`` turns). Half of
    it, the spline's tangent at the next key, is there the velocity ``(S + T)/2`` that the next gap
    starts with, so the two meet with one velocity; and a piece that turns by nearly a whole turn
    over the two steps is never taken as one screw, whose ``V(ω)`` is nearly singular there (a ball
    rolling 178° per key came out 4.5 radii off its path)."""
    rotations, translations = motions
    step_rotations = matmul(farther[0], transpose(rotations))
    step_translations = farther[1] - np.einsum("pab,pb->pa", step_rotations, translations)
    steps = rigid_logs(step_rotations, step_translations, screws, spread=spread)
    return np.linalg.solve(screw_left_jacobians(screws), (screws + steps)[..., None])[..., 0]


def key_screws(motions: list, farther_is_key: bool) -> list[np.ndarray]:
    """Screw coordinates (P, 6) of P bodies' rigid motions ``motions`` (per key: rotations
    (P, 3, 3), translations (P, 3)) from a gap's base key to the keys at times −1, 0, 1, 2, for a
    spline of screws: the next key's the short way round, the key before's turn continued from it
    (the representative nearest its reverse), the key after as :func:`continued_screws` takes it
    where ``farther_is_key``, else (a sequence's end condition) its turn continued to twice the
    next key's."""
    def logs(k, reference=None):
        return rigid_logs(*motions[k], reference, reference is not None)

    nxt = logs(2)
    after = continued_screws(nxt, motions[2], motions[3]) if farther_is_key else logs(3, 2.0 * nxt)
    return [logs(0, -nxt), logs(1), nxt, after]


def _unwrapped_identity(reference: np.ndarray) -> np.ndarray:
    """The representatives ``2πk û`` (r, 3) of the identity nearest the rows of ``reference``
    (r, 3): along each reference, ``k`` its length in whole turns (rounded; zero for a null one)."""
    reach = np.sqrt(np.einsum("ij,ij->i", reference, reference))
    turns = np.round(reach / (2 * np.pi))
    return reference * (2 * np.pi * turns / np.where(reach > 0, reach, 1.0))[:, None]


def framed_screws(screws: np.ndarray, axes: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """Screw coordinates ``(ω, v)`` (P, 6) of motions ``x ↦ R x + t`` in world coordinates → the
    same motions' in each row's frame ``y = A (x − o)`` (``axes`` A: rows of rotations (P, 3, 3),
    ``origins`` o (P, 3)): the adjoint ``(A ω, A (v − o × ω))``, exact for every representative of
    a turn (linear, as the exponential is equivariant)."""
    w, v = screws[:, :3], screws[:, 3:]
    return np.concatenate([np.einsum("pab,pb->pa", axes, w),
                           np.einsum("pab,pb->pa", axes, v - np.cross(origins, w))], axis=1)


def world_screws(framed: np.ndarray, axes: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """The inverse of :func:`framed_screws`: ``(Aᵀ ω', Aᵀ v' + o × Aᵀ ω')``."""
    w = np.einsum("pba,pb->pa", axes, framed[:, :3])
    return np.concatenate([w, np.einsum("pba,pb->pa", axes, framed[:, 3:]) + np.cross(origins, w)], axis=1)


def rigid_exps(screws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (P, 3, 3) and translations (P, 3) of screw coordinates ``(ω, v)`` (P, 6), the
    inverse of :func:`rigid_log` row by row: the translation ``V(ω) v = v + a ω × v + b ω × (ω ×
    v)`` with the coefficients of :func:`_screw_coefficients`."""
    w, v = screws[:, :3], screws[:, 3:]
    a, b = _screw_coefficients(np.linalg.norm(w, axis=1))
    # the cross products by coordinate (NumPy's np.cross costs ~25 µs of axis handling per call,
    # most of a call on the few rows of a mesh's pieces; the same products and differences)
    turned = coordinate_cross(w.T, v.T)
    translations = v + (a * turned).T + (b * coordinate_cross(w.T, turned)).T
    return Rotation.from_rotvec(w).as_matrix().reshape(-1, 3, 3), translations


def similarity_paths(rotvec: np.ndarray, log_scales: np.ndarray, translations: np.ndarray, points: np.ndarray,
                     s: float) -> tuple[np.ndarray, np.ndarray]:
    """Where ``S^s``, the power ``s`` (``exp(s log S)``) of each similarity ``S: x ↦ e^λ R x + t``
    (rotation vectors ``rotvec`` ω (P, 3), so ``R = exp([ω])``; log-scales λ (P,); translations
    (P, 3)), takes ``points`` (P, 3), one point per similarity: ``(positions (P, 3), ok (P,))``.
    ``ok`` is False where the logarithm has no translation part to speak of (a whole turn with no
    scale: ``S`` is a translation along its axis only if ``t`` lies along it; the positions there
    are those of the chord ``x + s t``).

    The rotation and the uniform scale commute: along the axis ``û`` the map scales by ``e^{sλ}``,
    across it, taken as the complex plane (``i`` ≡ ``û ×``), it multiplies by ``e^{s(λ + iθ)}``. Its
    translation at ``s`` is ``∫₀ˢ e^{τ(λ I + [ω])} dτ`` times the logarithm's, i.e. ``t`` times
    ``expm1(sλ) / expm1(λ)`` along the axis and ``expm1(s z) / expm1(z)`` across it (``z = λ +
    iθ``; both ``s`` in the limit of a translation). For λ = 0 this is the screw motion
    (:func:`rigid_exps` of ``s`` times :func:`rigid_logs`); for a rigid motion with a uniform scale
    the spiral that takes a piece, and everything scaled and turned with it, along one motion."""
    rotvec = np.asarray(rotvec, dtype=np.float64)
    log_scales = np.asarray(log_scales, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    theta = np.sqrt(np.einsum("ij,ij->i", rotvec, rotvec))
    axis = np.where((theta > 0)[:, None], rotvec / np.where(theta > 0, theta, 1.0)[:, None], [0.0, 0.0, 1.0])
    z = log_scales + 1j * theta

    def ratio(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # expm1(s v) / expm1(v), s where v → 0
        whole = np.expm1(values)
        small = np.abs(values) < 1e-12
        ok = small | (np.abs(whole) > 1e-6 * np.abs(values))  # not a whole turn (expm1(2πki) = 0)
        safe = np.where(ok & ~small, whole, 1.0)
        return np.where(small, s, np.expm1(s * values) / safe), ok

    along, _ = ratio(log_scales.astype(complex))
    across, ok = ratio(z)
    along = along.real
    parallel = np.einsum("ij,ij->i", translations, axis)[:, None] * axis
    perpendicular = translations - parallel
    moved_translation = (along[:, None] * parallel + across.real[:, None] * perpendicular
                         + across.imag[:, None] * np.cross(axis, perpendicular))
    rotations = Rotation.from_rotvec(s * rotvec).as_matrix().reshape(-1, 3, 3)
    out = np.exp(s * log_scales)[:, None] * np.einsum("pab,pb->pa", rotations, points) + moved_translation
    chord = points + s * translations
    return np.where(ok[:, None], out, chord), ok
