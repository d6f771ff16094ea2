"""Full-basis recovery of areas and squared edge lengths (Props. 1–2), and their singular cases."""

import numpy as np
import pytest

import core
from core.shape_difference import FullDifference
from meshes import cube, cube_with_bump, drape, grid, icosphere, stretch_and_bend, twisted_torus

CASES = {
    "cloth draped (large isometric motion)": (grid(16, jitter=0.3), lambda v: drape(v, 4.0)),
    "cloth stretched": (grid(12, jitter=0.3), stretch_and_bend),
    "sphere stretched": (icosphere(2), stretch_and_bend),
    "cube to bump (closed, small motion)": (cube(8), lambda v: cube_with_bump(8, 0.2)[0]),
}


def _relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


@pytest.mark.parametrize("case", CASES)
def test_full_basis_recovers_areas_and_squared_lengths(case):
    (vertices, triangles), motion = CASES[case]
    target = motion(vertices)
    differences = core.shape_differences(vertices, target, triangles)
    reference = differences.reference
    recovered, exact = reference.recover_metric(differences), reference.pose_metric(target)
    for layer in ("base", "offset"):
        got, want = getattr(recovered, layer), getattr(exact, layer)
        assert _relative(got.areas, want.areas) <= 1e-8, layer
        assert _relative(got.squared_lengths, want.squared_lengths) <= 1e-8, layer


def test_recovery_from_an_explicit_dense_difference_operator():
    vertices, triangles = icosphere(1)
    target = stretch_and_bend(vertices)
    differences = core.shape_differences(vertices, target, triangles, use_extrinsic=False)
    dense_area, dense_conformal = differences.area.dense(), differences.conformal.dense()
    # D_A = A_M⁻¹ A_N and D_C = C_M⁺ C_N as explicit matrices, then recovery from them alone.
    area = FullDifference.from_operator("area", differences.area.base_product, dense_area)
    conformal = FullDifference.from_operator("conformal", differences.conformal.base_product, dense_conformal)
    layer = differences.reference.base
    metric = layer.recover(area, conformal)
    exact = differences.reference.pose_metric(target).base
    assert _relative(metric.areas, exact.areas) <= 1e-8
    assert _relative(metric.squared_lengths, exact.squared_lengths) <= 1e-8


def _octahedron():
    vertices = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    triangles = np.array(
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    )
    return vertices, triangles


def _singular_values(reference):
    """Singular values of Prop. 1's map µ ↦ edge entries of A(µ) (dense: small meshes only)."""
    return np.linalg.svd(reference.base.assembler.area_map().toarray(), compute_uv=False)


# Closed meshes whose triangles two-colour (every edge between the colours): an octahedron, and a
# torus (genus 1) whose quads alternate their diagonals, glued without a twist.
BIPARTITE = {"octahedron": _octahedron, "torus, alternating diagonals": lambda: twisted_torus(12, 12)}


@pytest.mark.parametrize("mesh", BIPARTITE)
def test_closed_mesh_with_two_coloured_triangles_is_reported_as_not_recoverable(mesh):
    vertices, triangles = BIPARTITE[mesh]()
    reference = core.ReferenceShape(vertices, triangles, use_extrinsic=False)
    singular = _singular_values(reference)
    assert singular[-1] < 1e-12 * singular[0]  # ±1 areas on the two colours: A(µ) unchanged
    differences = reference.shape_differences(1.1 * vertices)
    with pytest.raises(core.RecoveryError, match="two alternating colours"):
        reference.recover_metric(differences)


def test_even_valence_torus_with_an_odd_cycle_of_triangles_is_recoverable():
    """Prop. 1's condition (a boundary or an odd-valence vertex) is sufficient, not necessary: on
    a torus glued with a twist of one quad every vertex has even valence, but a ring of triangles
    around the twisted seam is an odd cycle, so no alternating ±1 areas hide in A(µ)."""
    vertices, triangles = twisted_torus(12, 12, shift=1)
    target = stretch_and_bend(vertices)
    differences = core.shape_differences(vertices, target, triangles, use_extrinsic=False)
    reference = differences.reference
    topology = reference.base.assembler.topology
    assert np.all(np.bincount(topology.edges.ravel()) % 2 == 0)
    singular = _singular_values(reference)
    assert singular[-1] > 1e-8 * singular[0]  # full rank (a kernel would sit at round-off, 1e-16)
    recovered, exact = reference.recover_metric(differences).base, reference.pose_metric(target).base
    assert _relative(recovered.areas, exact.areas) <= 1e-8
    assert _relative(recovered.squared_lengths, exact.squared_lengths) <= 1e-8


def _bipyramid():
    """The paper's Fig. 2: two regular tetrahedra glued at their bases (all areas equal)."""
    side = 1.0
    radius = side / np.sqrt(3)
    h = side * np.sqrt(2.0 / 3.0)
    angles = np.array([0, 2 * np.pi / 3, 4 * np.pi / 3])
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros(3)], axis=1)
    vertices = np.vstack([ring, [[0, 0, h], [0, 0, -h]]])
    triangles = np.array([[0, 1, 3], [1, 2, 3], [2, 0, 3], [1, 0, 4], [2, 1, 4], [0, 2, 4]])
    return vertices, triangles


@pytest.mark.parametrize("mesh", ["bipyramid (Fig. 2)", "flat regular grid"])
def test_singular_length_system_is_resolved_with_herons_formula(mesh):
    vertices, triangles = _bipyramid() if mesh.startswith("bipyramid") else grid(8)
    reference = core.ReferenceShape(vertices, triangles, use_extrinsic=False)
    layer = reference.base
    assert np.allclose(layer.areas, layer.areas[0])
    # Prop. 2's linear map alone is singular for these equal areas ...
    singular_values = np.linalg.svd(layer.assembler.length_map(layer.areas).toarray(), compute_uv=False)
    assert singular_values[-1] < 1e-12 * singular_values[0]
    # ... but with the recovered areas (Heron's formula) the lengths are still determined. The
    # reference lengths the solve starts from are perturbed so that nothing is read off them.
    differences = reference.shape_differences(vertices)
    rng = np.random.default_rng(0)
    layer.squared_lengths = layer.squared_lengths * rng.uniform(0.8, 1.2, layer.squared_lengths.shape)
    metric = reference.recover_metric(differences)
    exact = reference.pose_metric(vertices).base
    assert _relative(metric.base.squared_lengths, exact.squared_lengths) <= 1e-8


def _perturbed_conformal(layer, differences, factor):
    """The conformal difference with its per-edge entries multiplied by ``factor`` ``(E,)``."""
    diagonal, edge_values = layer.assembler.entries(differences.conformal.target_product)
    return FullDifference("conformal", layer.conformal, layer.assembler.from_entries(diagonal, edge_values * factor))


def test_inconsistent_conformal_difference_is_reported():
    vertices, triangles = grid(8)
    reference = core.ReferenceShape(vertices, triangles, use_extrinsic=False)
    layer = reference.base
    differences = reference.shape_differences(vertices)
    factor = np.random.default_rng(1).uniform(0.5, 1.5, layer.topology.n_edges)
    with pytest.raises(core.RecoveryError, match="not that of any mesh .* triangle inequality"):
        layer.recover(differences.area, _perturbed_conformal(layer, differences, factor))


@pytest.mark.parametrize("jitter", [0.0, 0.3])
@pytest.mark.parametrize("noise", [1e-6, 1e-4])
def test_noisy_conformal_difference_gives_the_closest_lengths(jitter, noise):
    # Differences edited (§8.4's blends), rounded or noisy are no mesh's exactly: no squared lengths
    # satisfy both Prop. 2's equations and Heron's. Their least-squares fit moves with the data by
    # about the system's condition number times the noise (measured: 0.8–1.0 × on these grids,
    # flat (B_µ singular) and jittered), and it is returned with a warning saying how far it is.
    vertices, triangles = grid(8, jitter=jitter) if jitter else grid(8)
    target = stretch_and_bend(vertices)
    differences = core.shape_differences(vertices, target, triangles, use_extrinsic=False)
    layer = differences.reference.base
    factor = 1.0 + noise * np.random.default_rng(1).normal(size=layer.topology.n_edges)
    with pytest.warns(core.ShapeDifferenceWarning, match="not exactly those of any mesh .* fit them closest"):
        metric = layer.recover(differences.area, _perturbed_conformal(layer, differences, factor))
    exact = differences.reference.pose_metric(target).base
    assert _relative(metric.squared_lengths, exact.squared_lengths) <= 10 * noise


def test_recovery_does_not_depend_on_vertex_order():
    (vertices, triangles), motion = CASES["cloth stretched"]
    target = motion(vertices)
    rng = np.random.default_rng(2)
    perm = rng.permutation(len(vertices))
    inverse = np.argsort(perm)
    triangle_perm = rng.permutation(len(triangles))
    permuted_triangles = inverse[triangles][triangle_perm]
    original = core.shape_differences(vertices, target, triangles)
    permuted = core.shape_differences(vertices[perm], target[perm], permuted_triangles)
    areas = original.reference.recover_metric(original).base.areas
    areas_p = permuted.reference.recover_metric(permuted).base.areas
    assert np.allclose(areas_p, areas[triangle_perm], rtol=1e-9)
