"""Exaggerated and small bends (issue 17 item 3): an exaggeration flips no triangle and is not the
linear extrapolation; a small bend is interpolated as a bend. No bpy."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import ShapeDifferenceWarning
from core.two_pose_inbetweens import Interpolator

from inbetween_helpers import _normals
from placement_helpers import _arm


@pytest.mark.parametrize("degrees", [10.0, 20.0, 30.0, 45.0])
def test_a_small_bend_is_interpolated_as_a_bend(degrees):
    """An arm bent at the elbow by a small angle: half-way it is the arm bent by half the angle, to
    5e-4 of the diagonal, its edges within 0.5 %. The linear blend's chord is 7.5e-4 / 3.0e-3 /
    6.7e-3 / 1.5e-2 off; anchored to it where it barely shortens edges, the forearm was 6.2e-4 /
    2.4e-3 / 3.8e-3 / 2.2e-3 off with edges up to 1.8 % off."""
    a, tri = _arm(0.0)
    b, _ = _arm(np.radians(degrees))
    x = Interpolator(a, b, tri).pose(0.5)
    truth, _ = _arm(np.radians(degrees / 2))
    diagonal = np.linalg.norm(np.ptp(a, axis=0))
    assert np.sqrt(np.mean(np.sum((x - truth) ** 2, axis=1))) < 5e-4 * diagonal
    lengths = np.linalg.norm(x[tri[:, 1]] - x[tri[:, 0]], axis=1)
    rest = np.linalg.norm(a[tri[:, 1]] - a[tri[:, 0]], axis=1)
    assert np.abs(lengths / rest - 1.0).max() < 5e-3


def test_exaggerated_bend_does_not_flip():
    """×2 of a 100° bend: no triangle faces against the 200° bend's, and the forearm keeps its
    length (the exaggeration is a bend, not a stretch)."""
    a, tri = _arm(0.0)
    b, _ = _arm(np.radians(100.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShapeDifferenceWarning)
        x = Interpolator(a, b, tri).pose(2.0)
    truth, _ = _arm(np.radians(200.0))
    assert (np.einsum("ij,ij->i", _normals(x, tri), _normals(truth, tri)) > 0).all()
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    lengths = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
    rest = np.linalg.norm(a[edges[:, 0]] - a[edges[:, 1]], axis=1)
    assert np.abs(lengths / rest - 1).max() < 0.02


def test_an_exaggerated_bend_is_not_the_linear_extrapolation():
    """×2 of a tube bent 100° at its elbow about an oblique axis: where the fit keeps a few
    defects, the pose is still a bend (the forearm keeps its length) with a warning that says so;
    before, the fit held near the linear extrapolation 2b − a was returned (forearm 1.94 × its
    length, 0.88 of the diagonal off the 200° bend) as "the interpolated metric fitted near the
    linear blend"."""
    a, tri = _tube()
    b = _skinned(a, 100.0)
    joint = np.array([1.0, 0.0, 0.0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        x = Interpolator(a, b, tri).pose(2.0)
    tip = a[:, 0] == a[:, 0].max()
    assert abs(np.linalg.norm(x[tip].mean(axis=0) - joint) - 1.0) < 0.05
    assert all("near the linear blend" not in str(w.message) for w in caught)


def _tube(sides=12, rings=41):
    """A tube along x ∈ [0, 2] (radius 0.15): its vertices and triangles (the first half of the
    triangles one of each quad, the second half the other, both on the quad's diagonal)."""
    angles = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    a = np.vstack([np.c_[np.full(sides, x), 0.15 * np.cos(angles), 0.15 * np.sin(angles)]
                   for x in np.linspace(0.0, 2.0, rings)])
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(sides), indexing="ij")
    i, j = i.ravel(), j.ravel()
    tri = np.r_[np.c_[i * sides + j, i * sides + (j + 1) % sides, (i + 1) * sides + (j + 1) % sides],
                np.c_[i * sides + j, (i + 1) * sides + (j + 1) % sides, (i + 1) * sides + j]]
    return a, tri


def _skinned(vertices, degrees):
    """``vertices`` turned about an oblique axis through the elbow (1, 0, 0) by their weight's share
    of ``degrees`` (a smooth ramp from x = 0.6 to 1.4)."""
    t = np.clip((vertices[:, 0] - 0.6) / 0.8, 0.0, 1.0)
    t = t * t * (3.0 - 2.0 * t)
    axis = np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0])
    joint = np.array([1.0, 0.0, 0.0])
    turns = Rotation.from_rotvec(np.outer(t * np.radians(degrees), axis)).as_matrix()
    return np.einsum("nij,nj->ni", turns, vertices - joint) + joint


def _with_slivers(vertices, tri, height, every=3):
    """``tri`` with a vertex added on the diagonal of every ``every``-th quad of the bend zone
    (0.8 < x < 1.2), ``height`` × the diagonal's length off it along the surface's normal, and the
    quad's two triangles made four: three about the new vertex and a sliver standing on the
    diagonal (as a scan's T-junction leaves them). Returns the vertices and triangles."""
    sides = 12
    half = len(tri) // 2
    new_vertices, new_tri, dropped = [vertices], [], set()
    for q in range(half):
        x, z, y = tri[q + half][0], tri[q + half][1], tri[q][1]  # diagonal x–z, apexes y and w
        w = tri[q + half][2]
        if not (0.8 < vertices[x, 0] < 1.2) or (q % sides) % every:
            continue
        normal = np.cross(vertices[y] - vertices[x], vertices[z] - vertices[x])
        normal /= np.linalg.norm(normal)
        length = np.linalg.norm(vertices[z] - vertices[x])
        m = len(vertices) + len(new_vertices) - 1
        new_vertices.append(((vertices[x] + vertices[z]) / 2 + height * length * normal)[None])
        # (x, y, z) → (x, y, m), (m, y, z) and the sliver (x, m, z), wound as the surface
        new_tri += [(x, y, m), (m, y, z), (x, z, w), (x, m, z)]
        dropped |= {q, q + half}
    kept = np.array([t for k, t in enumerate(tri) if k not in dropped])
    return np.vstack(new_vertices), np.vstack([kept, np.array(new_tri)])


@pytest.mark.parametrize("height", [1e-9, 1e-7, 1e-5])
def test_slivers_a_skin_bends_keep_their_size_in_an_exaggerated_bend(height):
    """×2 of a 100° bend of a tube whose bend zone holds 28 slivers standing on its quads'
    diagonals (a scan's T-junctions, ``height`` × their edge high: validation accepts them). The
    skin bends the diagonals, so a sliver's height changes by orders of magnitude between the keys
    (or the sliver turns over); raised to the factor's power, its stretch swelled it and the pose
    came out 1.0e6 / 1.0e4 / 102 mean edges off the same tube's ×2 without slivers. Held at the
    key's size beyond the keys (a sliver's shape is known only to the fits' floor), the slivered
    tube's ×2 is the plain one's to within a mean edge (0.26): the two triangulations of the bend
    zone differ at that scale."""
    a, tri = _tube()
    slivered, slivered_tri = _with_slivers(a, tri, height)
    with warnings.catch_warnings():
        # the plain tube's ×2 about this oblique axis keeps a few defects, and the keys' slivers
        # turn over: both warned, neither what is compared here
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        plain = Interpolator(a, _skinned(a, 100.0), tri).pose(2.0)
        x = Interpolator(slivered, _skinned(slivered, 100.0), slivered_tri).pose(2.0)
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    mean_edge = np.linalg.norm(a[edges[:, 0]] - a[edges[:, 1]], axis=1).mean()
    assert np.linalg.norm(x[:len(a)] - plain, axis=1).max() < mean_edge
