"""A(µ) and C(ℓ²; µ) (paper §4.2) against independent formulas."""

import numpy as np

from core.inner_products import ProductAssembler, pose_products
from core.mesh_topology import mesh_topology
from meshes import grid, icosphere, stretch_and_bend


def _products(vertices, triangles):
    assembler = ProductAssembler(mesh_topology(triangles, len(vertices)))
    _, _, mass, conformal = pose_products(assembler, vertices)
    return mass, conformal


def _cotangent_laplacian_from_angles(vertices, triangles):
    """L_ij = −½ Σ cot(opposite angle), from the angle itself (dot / |cross| of edge vectors)."""
    n = len(vertices)
    laplacian = np.zeros((n, n))
    for tri in triangles:
        for k in range(3):
            o, i, j = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            u, v = vertices[i] - vertices[o], vertices[j] - vertices[o]
            angle = np.arctan2(np.linalg.norm(np.cross(u, v)), np.dot(u, v))
            w = 0.5 / np.tan(angle)
            laplacian[i, j] -= w
            laplacian[j, i] -= w
            laplacian[i, i] += w
            laplacian[j, j] += w
    return laplacian


def test_conformal_matrix_is_the_cotangent_laplacian():
    vertices, triangles = icosphere(1)
    vertices = stretch_and_bend(vertices)
    _, conformal = _products(vertices, triangles)
    expected = _cotangent_laplacian_from_angles(vertices, triangles)
    assert np.allclose(conformal.toarray(), expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    eigenvalues = np.linalg.eigvalsh(conformal.toarray())
    assert eigenvalues.min() > -1e-10 * eigenvalues.max()  # positive semidefinite


def test_mass_matrix_integrates_products_of_piecewise_linear_functions_exactly():
    vertices, triangles = grid(6, jitter=0.4)
    vertices = stretch_and_bend(vertices)
    mass, _ = _products(vertices, triangles)
    rng = np.random.default_rng(3)
    f, g = rng.normal(size=(2, len(vertices)))
    # f·g is quadratic on each triangle; the edge-midpoint rule integrates quadratics exactly.
    p = vertices[triangles]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    quadrature = 0.0
    for a, b in ((0, 1), (1, 2), (2, 0)):
        fm = 0.5 * (f[triangles[:, a]] + f[triangles[:, b]])
        gm = 0.5 * (g[triangles[:, a]] + g[triangles[:, b]])
        quadrature += np.sum(area / 3.0 * fm * gm)
    assert np.isclose(f @ (mass @ g), quadrature, rtol=1e-12)
    assert np.isclose(mass.sum(), area.sum(), rtol=1e-13)


def test_scaling_scales_mass_by_alpha_squared_and_leaves_conformal_unchanged():
    vertices, triangles = icosphere(2)
    alpha = 2.7
    mass, conformal = _products(vertices, triangles)
    mass_scaled, conformal_scaled = _products(alpha * vertices, triangles)
    assert np.allclose(mass_scaled.toarray(), alpha**2 * mass.toarray(), rtol=1e-12, atol=0)
    assert np.allclose(conformal_scaled.toarray(), conformal.toarray(), rtol=1e-10, atol=1e-12)


def test_products_do_not_depend_on_vertex_or_triangle_order():
    vertices, triangles = grid(7, jitter=0.3)
    vertices = stretch_and_bend(vertices)
    rng = np.random.default_rng(5)
    perm = rng.permutation(len(vertices))  # new index of old vertex i is inverse[i]
    inverse = np.argsort(perm)
    shuffled_triangles = np.roll(inverse[triangles], 1, axis=1)[rng.permutation(len(triangles))]
    mass, conformal = _products(vertices, triangles)
    mass_p, conformal_p = _products(vertices[perm], shuffled_triangles)
    assert np.allclose(mass_p.toarray(), mass.toarray()[np.ix_(perm, perm)], rtol=1e-13, atol=1e-16)
    assert np.allclose(conformal_p.toarray(), conformal.toarray()[np.ix_(perm, perm)], rtol=1e-12, atol=1e-12)
