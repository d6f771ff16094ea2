"""Pulled-back metric (paper §8.3): the target's Laplacian, geodesics and WKS on the base mesh."""

import numpy as np
import pytest
import scipy.linalg as sla

import core
from core.pulled_back_metric import IntrinsicTriangulation, wave_kernel_signature
from core.laplace_basis import LaplaceBasis
from meshes import grid, icosphere


def squashed_twisted(vertices):
    """A smooth, far from isometric target: squashed along two axes and twisted about z."""
    out = vertices * np.array([1.0, 0.75, 0.55])
    angle = 0.8 * out[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * out[:, 0] - s * out[:, 1], s * out[:, 0] + c * out[:, 1], out[:, 2]], axis=1)


def embedded_operators(vertices, triangles):
    """Galerkin mass and cotangent stiffness from positions and angles (an independent assembly)."""
    n = len(vertices)
    mass, stiffness = np.zeros((n, n)), np.zeros((n, n))
    for tri in triangles:
        p = vertices[tri]
        area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        for c in range(3):
            i, j, k = tri[c], tri[(c + 1) % 3], tri[(c + 2) % 3]
            u, w = vertices[j] - vertices[i], vertices[k] - vertices[i]
            cot = np.dot(u, w) / np.linalg.norm(np.cross(u, w))  # angle at i, opposite edge (j, k)
            for a, b in ((j, k), (k, j)):
                stiffness[a, b] -= 0.5 * cot
            stiffness[j, j] += 0.5 * cot
            stiffness[k, k] += 0.5 * cot
            mass[i, i] += area / 6.0
            mass[j, k] += area / 12.0
            mass[k, j] += area / 12.0
    return mass, stiffness


def relative_errors(values, truth):
    return np.abs(values - truth) / np.abs(truth)


def weighted_relative(values, truth, weights):
    return np.sqrt(np.sum(weights * (values - truth) ** 2) / np.sum(weights * truth**2))


@pytest.fixture(scope="module")
def full_sphere():
    v, t = icosphere(2)
    target = squashed_twisted(v)
    differences = core.shape_differences(v, target, t, use_extrinsic=False)
    return v, t, target, core.pull_back(v, t, differences)


def test_full_basis_pull_back_has_the_targets_metric_and_spectrum(full_sphere):
    v, t, target, pulled = full_sphere
    lengths = np.linalg.norm(target[pulled.edges[:, 0]] - target[pulled.edges[:, 1]], axis=1)
    assert np.abs(pulled.edge_lengths - lengths).max() <= 1e-9 * lengths.max()
    mass, stiffness = embedded_operators(target, t)
    truth = sla.eigh(stiffness, mass, eigvals_only=True, subset_by_index=[0, 19])
    values = pulled.laplacian_eigenvalues(20)
    assert values[0] == pytest.approx(0.0, abs=1e-8 * truth[-1])
    assert relative_errors(values[1:], truth[1:]).max() <= 1e-8
    functions = pulled.eigenfunctions(5)
    assert functions.shape == (len(v), 5)
    assert np.allclose(functions.T @ mass @ functions, np.eye(5), atol=1e-8)


def test_heat_method_matches_potpourri3d_on_an_embedded_mesh(full_sphere):
    pp3d = pytest.importorskip("potpourri3d")
    v, t, target, pulled = full_sphere
    solver = pp3d.MeshHeatMethodDistanceSolver(target, t, t_coef=1.0, use_robust=True)
    for source in (0, 57):
        ours = pulled.geodesic_distances(source)
        theirs = solver.compute_distance(source)
        assert ours[source] == 0.0
        # Same discretization (the intrinsic Delaunay triangulation, lumped mass, cotangent
        # Laplacian, t = h²); theirs is mollified and regularized slightly and shifted to a
        # minimum of zero, so compare up to a constant.
        difference = (ours - ours.min()) - (theirs - theirs.min())
        assert np.abs(difference).max() <= 1e-4 * theirs.max()


def test_heat_method_on_a_flat_sheet_approaches_euclidean_distance():
    v, t = grid(25, jitter=0.3)
    reference = core.ReferenceShape(v, t, use_extrinsic=False)
    triangulation = IntrinsicTriangulation(reference.topology, reference.base.squared_lengths)
    source = 12 * 25 + 12
    distances = triangulation.heat_method().distances(source)
    truth = np.linalg.norm(v - v[source], axis=1)
    assert np.abs(distances - truth).max() <= 0.05 * truth.max()


def twisted_disk(rings: int = 12, count: int = 32, twist: float = 1.5):
    """A flat disk of radius ``rings``: ``count`` points per ring, each ring turned ``twist`` steps
    further than the one inside it, and each quad between rings split along its long diagonal —
    obtuse slivers whose cotangent weights are negative, as Blender's Limited Dissolve leaves
    them. Vertex 0 is the centre."""
    points = [np.zeros(3)]
    for ring in range(1, rings + 1):
        angles = 2.0 * np.pi * (np.arange(count) + twist * ring) / count
        points += list(np.column_stack([ring * np.cos(angles), ring * np.sin(angles), np.zeros(count)]))
    v = np.array(points)
    index = lambda ring, i: 1 + (ring - 1) * count + i % count  # noqa: E731
    t = [[0, index(1, i), index(1, i + 1)] for i in range(count)]
    for ring in range(1, rings):
        for i in range(count):
            a, b, c, d = index(ring, i), index(ring, i + 1), index(ring + 1, i + 1), index(ring + 1, i)
            long_ac = np.linalg.norm(v[a] - v[c]) > np.linalg.norm(v[b] - v[d])
            t += [[a, b, c], [a, c, d]] if long_ac else [[a, b, d], [b, c, d]]
    t = np.array(t)
    up = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2] > 0
    return v, np.where(up[:, None], t, t[:, ::-1])


def test_intrinsic_delaunay_keeps_the_metric_and_makes_cotangent_weights_non_negative():
    """On a flat mesh the unfolded length of a flipped edge is the distance between its vertices,
    and after the flips no glued edge's opposite angles sum to more than π."""
    from core.delaunay_flips import intrinsic_delaunay, side_twins
    from core.geometry import heron
    from core.mesh_topology import mesh_topology

    v, t = twisted_disk()
    corners = np.sum((v[t[:, [2, 0, 1]]] - v[t[:, [1, 2, 0]]]) ** 2, axis=2)
    twins = side_twins(mesh_topology(t, len(v)))
    flipped, lengths, glued = intrinsic_delaunay(t, corners, twins)
    assert not np.array_equal(flipped, t)
    assert np.allclose(lengths, np.sum((v[flipped[:, [2, 0, 1]]] - v[flipped[:, [1, 2, 0]]]) ** 2, axis=2),
                       rtol=1e-12, atol=0.0)
    sides = np.flatnonzero(glued >= 0)
    assert np.array_equal(glued[glued[sides]], sides)  # a gluing: each glued side's twin glued back to it
    assert np.count_nonzero(glued < 0) == np.count_nonzero(twins < 0)  # the boundary kept
    # the two sides of a glued pair are one edge: the same length, run in opposite directions
    assert np.array_equal(lengths.ravel()[sides], lengths.ravel()[glued[sides]])
    tails, heads = flipped[:, [1, 2, 0]].ravel(), flipped[:, [2, 0, 1]].ravel()
    assert np.array_equal(tails[sides], heads[glued[sides]])
    cot = ((lengths.sum(axis=1)[:, None] - 2.0 * lengths) / np.sqrt(heron(lengths))[:, None]).ravel()  # per side
    assert (cot[sides] + cot[glued[sides]]).min() >= -1e-9


def random_point_square(n: int = 1000, seed: int = 0):
    """The Delaunay triangulation of ``n`` uniformly random points of the square [−1, 1]² (flat and
    convex: its geodesic distances are the Euclidean ones). Its hull is lined with obtuse slivers
    (largest angle 179.93° for the default), each with an edge on the boundary."""
    from scipy.spatial import Delaunay

    xy = np.random.default_rng(seed).uniform(-1.0, 1.0, (n, 2))
    t = Delaunay(xy).simplices
    v = np.column_stack([xy, np.zeros(n)])
    up = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2] > 0
    return v, np.where(up[:, None], t, t[:, ::-1])


def test_heat_method_with_obtuse_slivers_along_the_boundary_matches_the_distance():
    """Edge flips of the mesh itself cannot reach a boundary sliver (its long edge has one
    triangle); those of its tufted cover can. There the heat method's error is that of its
    smoothing, a couple of mean edge lengths (0.033–0.043 of the largest distance; mean edge
    0.023 of it); with the mesh's own flips it was 0.24–0.95."""
    v, t = random_point_square()
    pulled = core.pull_back(v, t, core.shape_differences(v, v, t, use_extrinsic=False))
    for source in (0, int(np.argmin(v[:, 0] + v[:, 1])), int(np.argmax(np.abs(v).sum(axis=1)))):
        distances = pulled.geodesic_distances(source)
        truth = np.linalg.norm(v - v[source], axis=1)
        assert np.abs(distances - truth).max() <= 0.06 * truth.max()


def test_heat_method_on_obtuse_slivers_matches_the_distance():
    """Geodesics on a flat disk of obtuse slivers are the distances from its centre: the heat
    method on the raw cotangent Laplacian was 0.27 of the radius off there (potpourri3d's, on
    its intrinsic Delaunay triangulation, 0.011)."""
    v, t = twisted_disk()
    pulled = core.pull_back(v, t, core.shape_differences(v, v, t, use_extrinsic=False))
    distances = pulled.geodesic_distances(0)
    radius = np.linalg.norm(v, axis=1)
    assert np.abs(distances - radius).max() <= 0.02 * radius.max()


def test_wks_is_invariant_to_the_eigenbasis_sign_and_matches_the_target(full_sphere):
    v, t, target, pulled = full_sphere
    mass, stiffness = embedded_operators(target, t)
    values, functions = sla.eigh(stiffness, mass, subset_by_index=[0, 39])
    energies = pulled.wks_energies(20, k=40)
    ours = pulled.wave_kernel_signature(energies, k=40)
    theirs = wave_kernel_signature(LaplaceBasis(values, -functions), energies)
    assert ours.shape == (len(v), 20)
    assert np.abs(ours - theirs).max() <= 1e-6 * np.abs(theirs).max()


def test_truncated_pull_back_beats_the_base_against_the_targets_own():
    """Fig. 11–12: from k_M = 100 / k_N = 200 differences the pulled-back eigenvalues are within a
    quarter and the geodesic distances within half of the base's own error."""
    v, t = icosphere(3)
    target = squashed_twisted(v)
    differences = core.shape_differences(v, target, t, k_M=100, k_N=200, use_extrinsic=False)
    pulled = core.pull_back(v, t, differences)

    mass_t, stiff_t = embedded_operators(target, t)
    mass_b, stiff_b = embedded_operators(v, t)
    truth = sla.eigh(stiff_t, mass_t, eigvals_only=True, subset_by_index=[0, 20])[1:]
    base = sla.eigh(stiff_b, mass_b, eigvals_only=True, subset_by_index=[0, 20])[1:]
    ours = pulled.laplacian_eigenvalues(21)[1:]
    assert relative_errors(ours, truth).mean() <= 0.25 * relative_errors(base, truth).mean()

    pp3d = pytest.importorskip("potpourri3d")
    weights = np.diag(mass_t).copy()
    base_pulled = core.pull_back(v, t, core.shape_differences(v, v, t, use_extrinsic=False))
    for source in (0, 300):
        truth = pp3d.MeshHeatMethodDistanceSolver(target, t, use_robust=False).compute_distance(source)
        ours = pulled.geodesic_distances(source)
        base = base_pulled.geodesic_distances(source)
        assert weighted_relative(ours, truth, weights) <= 0.5 * weighted_relative(base, truth, weights)


def test_bad_source_vertex():
    v, t = grid(5)
    v = np.vstack([v, [[5.0, 5.0, 5.0]]])  # a loose vertex
    pulled = core.pull_back(v, t, core.shape_differences(v, v, t, use_extrinsic=False))
    with pytest.raises(core.MeshError, match="in no triangle"):
        pulled.geodesic_distances(len(v) - 1)
    with pytest.raises(core.MeshError, match="vertex index"):
        pulled.geodesic_distances(len(v))
    assert np.isinf(pulled.geodesic_distances(0)[-1])


def test_differences_of_another_mesh_are_refused():
    """As ``core.reconstruct``: differences of another mesh or anything else than differences is a
    MeshError in the user's terms (before: SciPy's IndexError, an AttributeError on a string)."""
    v, t = grid(5)
    differences = core.shape_differences(v, 1.2 * v, t)
    with pytest.raises(core.MeshError, match="computed on a mesh with 25 vertices"):
        core.pull_back(*grid(6), differences)
    with pytest.raises(core.MeshError, match="from another base pose"):
        core.pull_back(v + 0.1, t, differences)
    with pytest.raises(core.MeshError, match="must be the ShapeDifferences"):
        core.pull_back(v, t, "differences")

