"""A vertex order that scatters neighbours (a scan's, an exporter's) is renumbered inside the
in-betweens (core.vertex_locality), and the in-betweens come back in the caller's order, equal to
those of the mesh in its own order; Blender's orders are left as they are. No bpy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import core.vertex_locality as vertex_locality
from core.mesh_topology import mesh_topology
from core.sequence_inbetweens import SequenceInterpolator
from core.two_pose_inbetweens import Interpolator
from core.vertex_locality import SCATTERED_SPAN, local_order, order_span, renumbered
from meshes import grid

DATA = Path(__file__).parent / "data"


def _shuffled(triangles, n, seed=1):
    """A random order of ``n`` vertices (the old index of each new one) and ``triangles`` in it,
    their rows shuffled too (the order a scan or an exporter can give)."""
    rng = np.random.default_rng(seed)
    order = rng.permutation(n)
    inverse = np.argsort(order)
    return order, inverse[triangles][rng.permutation(len(triangles))]


def test_a_scattered_order_is_renumbered_and_blenders_is_not():
    """A 40k-vertex grid in its row order is kept (the span is one row, 200); the same grid with its
    vertices shuffled is renumbered, and the renumbered order brings every edge's ends within the
    grid's own bandwidth again (reverse Cuthill–McKee's span is at most a diagonal's length)."""
    vertices, triangles = grid(200)
    n = len(vertices)
    ordered = mesh_topology(triangles, n)
    assert order_span(ordered) < SCATTERED_SPAN and local_order(ordered) is None
    _, scattered_triangles = _shuffled(triangles, n)
    scattered = mesh_topology(scattered_triangles, n)
    assert order_span(scattered) >= SCATTERED_SPAN
    order = local_order(scattered)
    assert order is not None and np.array_equal(np.sort(order), np.arange(n))
    local, triangle_order = renumbered(scattered, order)
    assert np.array_equal(np.sort(triangle_order), np.arange(len(triangles)))
    # the same triangles, corners in the same cyclic order (orientation kept)
    assert np.array_equal(order[local.triangles], scattered_triangles[triangle_order])
    assert np.abs(local.edges[:, 1] - local.edges[:, 0]).max() <= 2 * 200


@pytest.fixture
def renumber_every_order(monkeypatch):
    """Renumber every mesh with edges (a small mesh stands in for one past SCATTERED_SPAN)."""
    monkeypatch.setattr(vertex_locality, "SCATTERED_SPAN", 1)


def test_renumbered_inbetweens_equal_those_of_the_mesh_in_its_own_order(renumber_every_order):
    """A pulled tablecloth's keys (2,592 vertices) shuffled, renumbered inside the sequence and two
    poses: every in-between, mapped back to the original order, equals the original's to 1e-9 of
    the diagonal (only the summation order differs)."""
    data = np.load(DATA / "pulled_tablecloth.npz")
    keys, triangles = data["keys"], data["triangles"]
    n = keys.shape[1]
    order, shuffled = _shuffled(triangles, n)
    inverse = np.argsort(order)
    diagonal = np.linalg.norm(np.ptp(keys[0], axis=0))
    factors = np.arange(1, 4) / 4
    with pytest.MonkeyPatch.context() as unchanged:
        unchanged.setattr(vertex_locality, "SCATTERED_SPAN", np.inf)
        expected = [SequenceInterpolator(keys, triangles).poses(g, factors) for g in range(len(keys) - 1)]
        pair = Interpolator(keys[0], keys[1], triangles).pose(1.5)
    sequence = SequenceInterpolator(keys[:, order], shuffled)
    assert sequence._unordered is not None
    for g in range(len(keys) - 1):
        got = sequence.poses(g, [0.0, *factors, 1.0])
        assert np.array_equal(got[0], keys[g][order]) and np.array_equal(got[-1], keys[g + 1][order])
        assert np.abs(got[1:-1][:, inverse] - expected[g]).max() <= 1e-9 * diagonal
    two = Interpolator(keys[0][order], keys[1][order], shuffled)
    assert two._sequence._unordered is not None
    assert np.abs(two.pose(1.5)[inverse] - pair).max() <= 1e-9 * diagonal


def test_a_renumbered_mesh_names_its_own_triangles(renumber_every_order):
    """Two poses of a cloth hanging from a rod (data/rod_sheet.npz), vertices and triangles
    shuffled and renumbered inside: the warning about triangles turning over between the poses
    names one, in the caller's numbering, whose normals in the two poses do face more than a right
    angle apart (as the warning says), and as many of them as the mesh in its own order does."""
    import re
    import warnings

    data = np.load(DATA / "rod_sheet.npz")
    (a, b), triangles = data["keys"].astype(np.float64), data["triangles"]
    pattern = r"(\d+) triangle\(s\) \(e\.g\. triangle (\d+)\) turn over between the poses"

    def named(a, b, triangles):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            Interpolator(a, b, triangles).pose(0.5)
        found = [re.search(pattern, str(w.message)) for w in caught]
        return next(m for m in found if m is not None)

    with pytest.MonkeyPatch.context() as unchanged:
        unchanged.setattr(vertex_locality, "SCATTERED_SPAN", np.inf)
        count = int(named(a, b, triangles).group(1))
    order, shuffled = _shuffled(triangles, len(a))
    found = named(a[order], b[order], shuffled)
    t = int(found.group(2))
    corners = [p[order][shuffled[t]] for p in (a, b)]
    normals = [np.cross(c[1] - c[0], c[2] - c[0]) for c in corners]
    assert int(found.group(1)) == count
    assert np.dot(normals[0], normals[1]) < 0


def test_a_mesh_with_near_duplicates_names_its_own_triangles():
    """The cloth hanging from a rod (data/rod_sheet.npz) with its first triangle split at a point
    1e-7 of its sides from a corner (prepended: the three pieces are the caller's triangles 0–2, the
    rest shifted by two): the point and the corner are solved as one (core.near_duplicates), which
    drops two of the pieces; the warning about triangles turning over between the poses names one,
    in the caller's numbering, whose normals in the two poses face more than a right angle apart."""
    import re
    import warnings

    data = np.load(DATA / "rod_sheet.npz")
    (a, b), triangles = data["keys"].astype(np.float64), data["triangles"]
    p, q, r = triangles[0]
    v = len(a)
    keys = [np.vstack([k, k[p] + 1e-7 * (k[q] + k[r] - 2.0 * k[p])]) for k in (a, b)]
    split = np.vstack([[[p, q, v], [q, r, v], [r, p, v]], triangles[1:]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Interpolator(keys[0], keys[1], split).pose(0.5)
    found = [re.search(r"triangle\(s\) \(e\.g\. triangle (\d+)\) turn over between the poses", str(w.message))
             for w in caught]
    t = int(next(m for m in found if m is not None).group(1))
    normals = [np.cross(k[split[t][1]] - k[split[t][0]], k[split[t][2]] - k[split[t][0]]) for k in keys]
    assert np.dot(normals[0], normals[1]) < 0
