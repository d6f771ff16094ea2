"""Meshes and motions shared by the placement tests (test_placement_*.py, test_seams); no bpy."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm, logm
from scipy.spatial import ConvexHull, Delaunay
from scipy.spatial.transform import Rotation

import meshes
from meshes import grid, icosphere


#: What a half turn the keys do not tell the way of is said with (of pieces, or of the whole mesh
#: turning as one).
HALF_TURN_UNTOLD = r"turns? a half turn \(180°\)(?: as one)? to within what the keys tell"


FACTORS = (-0.5, 0.25, 0.5, 0.75, 1.5, 2.0)


def _rigid(vertices, rotation, pivot, shift=(0.0, 0.0, 0.0)):
    return (vertices - pivot) @ rotation.T + pivot + np.asarray(shift)


def _screw(vertices, rotation, translation, s):
    """``x ↦ exp(s log T) x`` for the rigid motion ``T x = R x + t`` (the constant-velocity rigid
    motion; SciPy's matrix logarithm and exponential, independent of the code under test)."""
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rotation, translation
    moved = np.real(expm(s * logm(t)))
    return vertices @ moved[:3, :3].T + moved[:3, 3]


def _head_with_eyes():
    """A head (sphere of radius 1) and two eyes (spheres of radius 0.2) in their sockets: three
    connected components."""
    head, tri = icosphere(2)
    eye, eye_tri = icosphere(1, radius=0.2)
    parts, triangles, offset = [head], [tri], len(head)
    for center in ((0.35, 0.85, 0.3), (-0.35, 0.85, 0.3)):
        parts.append(eye + np.array(center))
        triangles.append(eye_tri + offset)
        offset += len(eye)
    return np.vstack(parts), np.vstack(triangles)


def _arm(angle, n=41, width=7):
    """A strip along x ∈ [0, 2] bent about y at the elbow (x = 1) by ``angle``: the upper arm
    (x < 0.9) is fixed, the forearm turns rigidly, the elbow (0.9–1.1) bends isometrically."""
    flat, tri = grid(n, width, size=2.0)
    x = flat[:, 0]
    radius = 0.2 / angle if angle else np.inf
    out = flat.copy()
    if angle:
        bend = np.clip(x - 0.9, 0.0, 0.2)
        theta = bend / radius
        out[:, 0] = np.where(x < 0.9, x, 0.9 + radius * np.sin(theta))
        out[:, 2] = np.where(x < 0.9, 0.0, radius * (1 - np.cos(theta)))
        past = x > 1.1
        along = x[past] - 1.1
        out[past, 0] += along * np.cos(angle)
        out[past, 2] += along * np.sin(angle)
    return out, tri


def _curled_line(u, angles, joints, spread):
    """The points (x, z) at arc lengths ``u`` of a line along x curled about y at the ``joints``
    (each bend spread over ``spread`` of its length) by ``angles`` (radians), and its turning
    angle there: integrated from the turning angle, so the segments between the joints stay
    straight and the line keeps its length."""
    fine = np.linspace(0.0, u.max(), 20001)
    turn = sum(angle * np.clip((fine - joint) / spread, 0.0, 1.0) for angle, joint in zip(angles, joints))
    step = np.diff(fine)
    x = np.concatenate([[0.0], np.cumsum(np.cos(turn[:-1]) * step)])
    z = np.concatenate([[0.0], np.cumsum(np.sin(turn[:-1]) * step)])
    return np.interp(u, fine, x), np.interp(u, fine, z), np.interp(u, fine, turn)


def _curled_strip(angles, joints=(0.9, 1.9), n=121, width=9, length=3.0):
    """A strip along x ∈ [0, 3] curled about y at the ``joints`` (each bend spread over 0.2 of
    its length) by ``angles`` (radians): the segments between the joints stay straight and rigid
    and the strip keeps its length."""
    flat, tri = grid(n, width, size=length)
    out = flat.copy()
    out[:, 0], out[:, 2], _ = _curled_line(flat[:, 0], angles, joints, 0.2)
    return out, tri


def _curled_tube(angles, joints, spread, radius=0.07, rings=61, sides=10):
    """A closed tube (a finger: radius 0.07, length 1, 1,220 triangles) curled about y at the
    ``joints`` by ``angles`` (radians), each bend spread over ``spread`` of its length: each
    cross-section stays a circle normal to the curled centre line."""
    tube, tri = meshes.closed_tube(rings, sides, radius=radius)
    x, z, turn = _curled_line(tube[:, 0], angles, joints, spread)
    out = tube.copy()
    out[:, 0], out[:, 2] = x - np.sin(turn) * tube[:, 2], z + np.cos(turn) * tube[:, 2]
    return out, tri


def _scanned_head(points, seed):
    """An ellipsoidal head (semi-axes 0.8, 1, 0.9 about (0, 1.6, 0)) triangulated irregularly, as a
    scan re-meshed: the hull of ``points`` random directions (seeded), outward; or, with
    ``points`` None, a regular icosphere of 2,562 vertices."""
    if points is None:
        unit, tri = icosphere(4)
    else:
        unit = np.random.default_rng(seed).normal(size=(points, 3))
        unit /= np.linalg.norm(unit, axis=1, keepdims=True)
        tri = ConvexHull(unit).simplices
        normals = np.cross(unit[tri[:, 1]] - unit[tri[:, 0]], unit[tri[:, 2]] - unit[tri[:, 0]])
        inward = np.einsum("ij,ij->i", normals, unit[tri].mean(axis=1)) < 0
        tri[inward] = tri[inward][:, [0, 2, 1]]
    return unit * np.array([0.8, 1.0, 0.9]) + np.array([0.0, 1.6, 0.0]), tri


def _nodded(vertices, degrees, s):
    """``vertices`` of :func:`_scanned_head` nodded about x at the neck (0, 0.6, 0) by ``s`` ×
    ``degrees``, as a skin with one bone does: each vertex turned by its weight's share, 0 below
    y = 0.75 (the neck, still) ramping to 1 at y = 1.1 (the head, rigid)."""
    weights = np.clip((vertices[:, 1] - 0.75) / 0.35, 0.0, 1.0)
    turns = Rotation.from_rotvec(s * np.radians(degrees) * weights[:, None] * np.array([1.0, 0.0, 0.0]))
    pivot = np.array([0.0, 0.6, 0.0])
    return turns.apply(vertices - pivot) + pivot


def _remeshed_tube(points, seed, length=3.0, radius=0.15, density=10.0):
    """A limb re-meshed irregularly, as a scan is: ``points`` random points (seeded) on a tube
    along x ∈ [0, ``length``], their density rising ``density`` × along it, triangulated by
    :class:`scipy.spatial.Delaunay` in the unrolled (x, arc length) domain (copies a turn either
    side close the seam), each end ringed at the local spacing and closed by a fan around a centre
    vertex; triangles facing outward. Slivers and valences from 3 to the caps' ~35 included."""
    rng = np.random.default_rng(seed)
    around = 2.0 * np.pi * radius
    domain = []
    while len(domain) < points:  # rejection sampling of the density ramp, point by point
        point = rng.random(2) * (length, around)
        if rng.random() < (1.0 + (density - 1.0) * point[0] / length) / density:
            domain.append(point)
    domain = np.array(domain)

    def spacing(x):
        return np.sqrt(length * around / points * density / (1.0 + (density - 1.0) * x / length) * 2.0 /
                       (1.0 + density))

    rings = []
    for end in (0.0, length):
        count = max(6, int(around / spacing(end)))
        rings.append(np.c_[np.full(count, end), (np.arange(count) + rng.uniform(0.0, 1.0)) * around / count % around])
    inside = (domain[:, 0] > 0.4 * spacing(0.0)) & (domain[:, 0] < length - 0.4 * spacing(length))
    domain = np.vstack(rings + [domain[inside]])
    m = len(domain)
    wrapped = np.vstack([domain, domain + (0.0, around), domain - (0.0, around)])
    tri = Delaunay(wrapped).simplices
    centre = wrapped[tri].mean(axis=1)
    tri = tri[(centre[:, 1] >= 0.0) & (centre[:, 1] < around)] % m
    angle = domain[:, 1] / radius
    vertices = np.vstack([np.c_[domain[:, 0], radius * np.cos(angle), radius * np.sin(angle)],
                          [[0.0, 0.0, 0.0], [length, 0.0, 0.0]]])
    first, last = len(rings[0]), np.argsort(rings[1][:, 1]) + len(rings[0])
    start = np.argsort(rings[0][:, 1])
    caps = [[m, start[(k + 1) % first], start[k]] for k in range(first)]
    caps += [[m + 1, last[k], last[(k + 1) % len(last)]] for k in range(len(last))]
    tri = np.vstack([tri, caps])
    # outward: away from the axis on the side, along it on the caps
    centre = vertices[tri].mean(axis=1)
    away = centre - np.c_[np.clip(centre[:, 0], 0.0, length), np.zeros((len(tri), 2))]
    capped = (centre[:, 0] < 1e-9) | (centre[:, 0] > length - 1e-9)
    away[capped] = np.c_[np.sign(centre[capped, 0] - 0.5 * length), np.zeros((capped.sum(), 2))]
    normals = np.cross(vertices[tri[:, 1]] - vertices[tri[:, 0]], vertices[tri[:, 2]] - vertices[tri[:, 0]])
    inward = np.einsum("ij,ij->i", normals, away) < 0
    tri[inward] = tri[inward][:, [0, 2, 1]]
    return vertices, tri


def _skinned_limb(vertices, angles, joints=(1.0, 2.0), ramp=0.6):
    """``vertices`` of a limb along x bent about y at the ``joints`` by ``angles`` (radians), as a
    skin with a bone per segment does: each vertex turned about each joint by its weight's share
    of the angle, the weight ramping from 0 to 1 over ``ramp`` centred on the joint (the outer
    joint turned first, then carried by the inner one)."""
    out = vertices.copy()
    for angle, joint in reversed(list(zip(angles, joints))):
        weights = np.clip((vertices[:, 0] - joint + 0.5 * ramp) / ramp, 0.0, 1.0)
        pivot = np.array([joint, 0.0, 0.0])
        out = Rotation.from_rotvec(angle * weights[:, None] * np.array([0.0, 1.0, 0.0])).apply(out - pivot) + pivot
    return out
