"""Validation of user meshes: every error names the problem, the first offending index and a fix."""

import numpy as np
import pytest

import core
from core.mesh_topology import _triangle_measures, mesh_topology
from meshes import grid, icosphere


def _error(vertices, triangles, target=None):
    with pytest.raises(core.MeshError) as info:
        core.shape_differences(vertices, vertices if target is None else target, triangles)
    assert isinstance(info.value, ValueError)
    return str(info.value)


def test_topology_of_a_grid():
    vertices, triangles = grid(5)
    topology = mesh_topology(triangles, len(vertices))
    assert topology.n_edges == 4 * 5 + 4 * 5 + 16  # horizontal + vertical + diagonals
    assert len(topology.boundary_edges) == 16
    # Every triangle's edge opposite corner k joins its other two corners.
    for k in range(3):
        ends = np.sort(triangles[:, [(k + 1) % 3, (k + 2) % 3]], axis=1)
        assert np.array_equal(topology.edges[topology.triangle_edges[:, k]], ends)
    # The forward triangle of an edge traverses it from edges[e,0] to edges[e,1].
    for e in topology.interior_edges[:10]:
        a, b = topology.edges[e]
        t = triangles[topology.edge_triangles[e, 0]]
        k = list(t).index(a)
        assert t[(k + 1) % 3] == b


def test_index_out_of_range():
    vertices, triangles = grid(4)
    triangles = triangles.copy()
    triangles[7, 1] = 99
    message = _error(vertices, triangles)
    assert "Triangle 7" in message and "99" in message and "0..15" in message


def test_repeated_vertex():
    vertices, triangles = grid(4)
    triangles = triangles.copy()
    triangles[3] = [2, 5, 2]
    message = _error(vertices, triangles)
    assert "Triangle 3" in message and "twice" in message and "Degenerate Dissolve" in message


def test_zero_area_triangle():
    vertices, triangles = grid(4)
    vertices = vertices.copy()
    a, b, c = triangles[4]
    vertices[c] = 0.5 * (vertices[a] + vertices[b])  # collinear corners
    message = _error(vertices, triangles)
    assert "zero area" in message and "Clean Up" in message


def test_triangles_flattened_by_the_rounding_far_from_the_origin_say_so():
    # a 20 x 20 grid of edges 1/19 moved 1e6 out in single precision (Blender's coordinates): its
    # coordinates fall on a grid of 0.0625, so triangles land on lines; the mesh is not to blame
    vertices, triangles = grid(20)
    far = (vertices + 1e6).astype(np.float32).astype(np.float64)
    message = _error(far, triangles)
    assert "zero area" in message and "from its origin" in message and "Origin to Geometry" in message
    assert "Degenerate Dissolve" not in message
    # the same mesh's own sliver at the origin is the mesh's: cleaning it up is the advice
    sliver = vertices.astype(np.float32).astype(np.float64)
    a, b, c = triangles[4]
    sliver[c] = 0.5 * (sliver[a] + sliver[b])
    message = _error(sliver, triangles)
    assert "Degenerate Dissolve" in message and "from its origin" not in message


def _crushed_keys():
    """Three keys of a 20 × 20 sheet (edges 1/19): flat, stretched 2 % along x, and one whose vertex 41
    is pushed to 1.5e-5 above the middle of the opposite side of triangle 40, as a simulation crushes
    a triangle (thin, not flat: its area is 4e-7 of its longest edge squared); and its triangles."""
    vertices, triangles = grid(20)
    crushed = vertices * [1.02, 1.0, 1.0]
    a, b, c = triangles[40]
    crushed[c] = 0.5 * (crushed[a] + crushed[b]) + [0.0, 1.5e-5, 0.0]
    return [vertices, vertices * [1.02, 1.0, 1.0], crushed], triangles


@pytest.mark.parametrize("single", [False, True])
def test_triangles_a_later_keys_decimal_rounding_flattened_are_told_as_the_rounding(single):
    """The keys exported to 4 decimals (read back in double precision, or single as Blender stores
    them): the crushed triangle lands on one line in the third key, while the first key has it
    whole. Refused as the export's rounding, with the decimals to export (before: "Remove degenerate
    faces", blaming the mesh, which Blender's Clean Up would not find degenerate); exported so, the
    keys are taken. The same key flattened in place, on no decimal grid, is still the mesh's."""
    from core.mesh_topology import zero_area_triangles

    keys, triangles = _crushed_keys()
    assert zero_area_triangles(keys[2], triangles).size == 0  # the simulation's key: thin, whole

    def exported(places):
        rounded = [np.round(key, places) for key in keys]
        return [key.astype(np.float32).astype(np.float64) for key in rounded] if single else rounded

    rounded = exported(4)
    assert zero_area_triangles(rounded[0], triangles).size == 0
    assert 40 in zero_area_triangles(rounded[2], triangles)  # and its neighbour along the same row
    with pytest.raises(core.MeshError) as info:
        core.SequenceInterpolator(rounded, triangles)
    message = str(info.value)
    assert message.startswith("key pose 2: triangle ") and "zero area" in message
    assert "rounded to 4 decimal(s)" in message and "key pose 0 has those triangle(s) whole" in message
    assert "try 6" in message and "scale the object up 100 ×" in message and "Degenerate Dissolve" not in message
    core.SequenceInterpolator(exported(6), triangles)  # the advice followed
    flat = [key.copy() for key in keys]
    a, b, c = triangles[40]
    flat[2][c] = 0.5 * (flat[2][a] + flat[2][b])
    with pytest.raises(core.MeshError, match="Degenerate Dissolve") as info:
        core.SequenceInterpolator(flat, triangles)
    assert "decimal" not in str(info.value)


@pytest.mark.parametrize("built", ["whole units", "Grid primitive"])
def test_flat_triangles_of_keys_built_on_a_grid_are_the_meshs_not_a_rounding(built):
    """Keys whose every vertex lies on a grid as coarse as their edges were built on it, not rounded
    to it: a voxel-like sheet on whole units (edges 1), Blender's Grid primitive (size 2, 10 cuts:
    edges 0.2, in single precision). A later key that collapses a 2 × 2 patch to a grid point, or
    snaps a vertex onto the line of a triangle's other two (the midpoint, on the 0.1 grid), flattens
    triangles by its own doing: refused with the mesh's advice. Before, both said "Every key so far
    is rounded to 1 decimal(s) … Export the keys with more decimals (try 3…)", which changes nothing.
    The crushed sheet's keys exported to 2 decimals (edges 5 steps of the grid) are still told as
    the rounding."""
    if built == "whole units":
        first, triangles = grid(11, size=10.0)
    else:
        first, triangles = grid(11, size=2.0)
        first = (first - [1.0, 1.0, 0.0]).astype(np.float32).astype(np.float64)
    collapsed = first.copy()
    collapsed[[0, 1, 11, 12]] = first[0]
    snapped = first.copy()
    a, b, c = triangles[0]
    snapped[c] = 0.5 * (first[a] + first[b])
    for key in (collapsed, snapped):
        with pytest.raises(core.MeshError) as info:
            core.SequenceInterpolator([first, key, first], triangles)
        message = str(info.value)
        assert message.startswith("key pose 1: triangle ") and "zero area" in message
        assert "decimal" not in message and "scale that part to a small size instead of zero" in message
    keys, triangles = _crushed_keys()
    with pytest.raises(core.MeshError, match=r"rounded to 2 decimal\(s\)"):
        core.SequenceInterpolator([np.round(key, 2) for key in keys], triangles)


def test_degenerate_target_is_rejected_too():
    vertices, triangles = grid(4)
    target = vertices.copy()
    target[triangles[2]] = target[triangles[2, 0]]
    message = _error(vertices, triangles, target)
    assert "target" in message and "zero area" in message


def test_edge_shared_by_three_triangles():
    vertices, triangles = grid(4)
    topology = mesh_topology(triangles, len(vertices))
    a, b = topology.edges[topology.interior_edges[0]]
    vertices = np.vstack([vertices, [[0.1, 0.1, 1.0]]])
    triangles = np.vstack([triangles, [[a, b, 16]]])
    message = _error(vertices, triangles)
    assert f"({min(a, b)}, {max(a, b)})" in message and "3 triangles" in message and "Non Manifold" in message


def test_inconsistent_orientation():
    vertices, triangles = grid(4)
    triangles = triangles.copy()
    triangles[5] = triangles[5, ::-1]
    message = _error(vertices, triangles)
    assert "same direction" in message and "Recalculate Outside" in message


def test_non_finite_coordinates():
    vertices, triangles = grid(4)
    target = vertices.copy()
    target[6, 2] = np.nan
    message = _error(vertices, triangles, target)
    assert "vertex 6" in message and "non-finite" in message


def test_vertex_count_mismatch():
    vertices, triangles = grid(4)
    message = _error(vertices, triangles, vertices[:-1])
    assert "15 vertices" in message and "16" in message and "correspondence" in message


def test_no_triangles():
    vertices, _ = grid(3)
    message = _error(vertices, np.zeros((0, 3), dtype=int))
    assert "no triangles" in message


def test_loose_vertices_are_allowed_and_kept_in_place():
    vertices, triangles = icosphere(1)
    loose = np.array([[3.0, 3.0, 3.0], [4.0, 0.0, 0.0]])
    base = np.vstack([vertices, loose])
    target = base.copy()
    target[: len(vertices)] *= 1.3
    target[len(vertices):] += 7.0  # motion of loose vertices is not encoded by shape differences
    differences = core.shape_differences(base, target, triangles)
    metric = differences.reference.recover_metric(differences)
    exact = differences.reference.pose_metric(target)
    assert np.allclose(metric.base.areas, exact.base.areas, rtol=1e-10)
    assert differences.reference.expand_pose(differences.reference.base_positions)[-2:].tolist() == loose.tolist()


def test_a_duplicated_face_is_named_as_such():
    """A face repeated in place (a scan's or an importer's doubles) makes each of its edges shared
    by three triangles: the error names the duplicate and its original, not only the edges."""
    _, tri = grid(4, 4)
    doubled = np.vstack([tri, tri[5][::-1]])
    with pytest.raises(core.MeshError, match=f"Triangle {len(tri)} uses the same three vertices as triangle 5"):
        mesh_topology(doubled, int(tri.max()) + 1)
    three = np.vstack([tri, [[1, 4, 99]]])  # a third triangle on an edge, not a duplicate: the edge message
    with pytest.raises(core.MeshError, match="shared by 3 triangles"):
        mesh_topology(three, 100)


def test_triangle_measures_are_each_sides_square_and_the_doubled_area():
    """The pose checks' measures (core.validation.check_pose): each side's squared length, exactly
    the sum of its coordinates' squares whichever way the side is taken, the longest of them, and
    twice the area (the cross product's length)."""
    vertices, triangles = icosphere(2)
    vertices = vertices * np.array([1.0, 0.4, 2.5]) + 1e3
    _, doubled, squared, longest = _triangle_measures(vertices, triangles)
    p = vertices[triangles]
    for got, side in zip(squared, (p[:, 1] - p[:, 2], p[:, 2] - p[:, 0], p[:, 0] - p[:, 1])):
        np.testing.assert_array_equal(got, side[:, 0] * side[:, 0] + side[:, 1] * side[:, 1] + side[:, 2] * side[:, 2])
    np.testing.assert_array_equal(longest, np.max(squared, axis=0))
    np.testing.assert_allclose(doubled, np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1),
                               rtol=1e-12)


def _fans_by_walking(triangles: np.ndarray, n_vertices: int) -> np.ndarray:
    """Fans per vertex (n,), found independently: the triangles around each vertex, joined where
    two of them share an edge at that vertex (two vertices in common), counted by a union-find."""
    fans = np.zeros(n_vertices, dtype=int)
    for v in range(n_vertices):
        around = [t for t in range(len(triangles)) if v in triangles[t]]
        parent = list(range(len(around)))

        def root(i):
            while parent[i] != i:
                i = parent[i]
            return i

        for i in range(len(around)):
            for j in range(i + 1, len(around)):
                if len(set(triangles[around[i]]) & set(triangles[around[j]])) == 2:
                    parent[root(i)] = root(j)
        fans[v] = len({root(i) for i in range(len(around))})
    return fans


def test_bow_tie_vertices_are_those_whose_triangles_form_several_fans():
    """check_manifold_vertices names exactly the vertices with more than one fan, as a walk
    around each vertex counts them: sheets with triangles taken out at random (two missing around
    an inner vertex part its fan), a sheet's vertex shared with another sheet (two fans) and with
    a third (three)."""
    from core.errors import MeshError
    from core.mesh_topology import check_manifold_vertices

    rng = np.random.default_rng(3)
    vertices, triangles = grid(7, 6)
    n = len(vertices)
    refused = 0
    for trial in range(12):
        kept = triangles[rng.random(len(triangles)) >= (rng.uniform(0.1, 0.4) if trial % 4 else 0.0)]
        if trial % 3 == 1:  # a second sheet sharing its vertex 8 with vertex 16 of the first
            second = triangles + n
            second[second == n + 8] = 16
            kept = np.vstack([kept, second])
        if trial % 3 == 2:  # and a third sharing it too
            second, third = triangles + n, triangles + 2 * n
            second[second == n + 8] = 16
            third[third == 2 * n + 20] = 16
            kept = np.vstack([kept, second, third])
        n_vertices = 3 * n
        fans = _fans_by_walking(kept, n_vertices)
        expected = np.flatnonzero(fans > 1)
        topology = mesh_topology(kept, n_vertices, allow_bow_ties=True)
        if not expected.size:
            check_manifold_vertices(topology)
            continue
        with pytest.raises(MeshError) as raised:
            check_manifold_vertices(topology)
        message = str(raised.value)
        assert message.startswith(f"Vertices {expected[:10].tolist()}") and f"({expected.size} in all)" in message
        refused += 1
    assert 4 <= refused < 12  # both outcomes were exercised


def test_components_are_found_once_per_topology_and_each_caller_gets_its_own_labels(monkeypatch):
    """The input checks and the in-betweens' setup both ask a topology for its components: the
    graph search runs once, and a caller changing its labels changes no one else's."""
    import scipy.sparse.csgraph as csgraph

    vertices, triangles = grid(5, 4)
    pieces = np.vstack([triangles, triangles + len(vertices)])
    topology = mesh_topology(pieces, 2 * len(vertices))
    searches = []
    search = csgraph.connected_components
    monkeypatch.setattr(csgraph, "connected_components", lambda *a, **k: searches.append(1) or search(*a, **k))
    count, labels = topology.components()
    assert count == 2 and np.array_equal(labels, np.repeat([labels[0], labels[-1]], len(triangles)))
    assert labels[0] != labels[-1]
    labels[:] = 7
    again = topology.components()
    assert again[0] == 2 and again[1][0] != again[1][-1]
    assert len(searches) == 1
