"""The four shape differences (§6): full, reduced (eq. 5), functional map (eq. 6), and the
intrinsic/extrinsic distinction of the paper's Fig. 7 cube."""

import numpy as np
import pytest

import core
from meshes import cube, cube_with_bump, drape, grid, icosphere, stretch_and_bend


def _relative_difference(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_intrinsic_differences_cannot_tell_inward_from_outward_bumps_but_extrinsic_can():
    base, triangles = cube(10)
    outward, _ = cube_with_bump(10, +0.35)
    inward, _ = cube_with_bump(10, -0.35)
    reference = core.ReferenceShape(base, triangles)
    out_d, in_d = reference.shape_differences(outward), reference.shape_differences(inward)
    for kind in ("area", "conformal"):
        a, b = getattr(out_d, kind).target_product.toarray(), getattr(in_d, kind).target_product.toarray()
        assert _relative_difference(a, b) < 1e-12, kind  # identical up to rounding
        a, b = getattr(out_d, "offset_" + kind).target_product.toarray(), getattr(in_d, "offset_" + kind).target_product.toarray()
        assert _relative_difference(a, b) > 1e-2, kind  # clearly different
    # The operators themselves (not only the products) differ the same way.
    assert np.allclose(out_d.area.dense(), in_d.area.dense(), atol=1e-10)
    assert not np.allclose(out_d.offset_area.dense(), in_d.offset_area.dense(), atol=1e-3)
    # In the truncated basis (eq. 5) as well.
    out_r, in_r = reference.shape_differences(outward, k_M=30), reference.shape_differences(inward, k_M=30)
    assert _relative_difference(out_r.conformal.matrix, in_r.conformal.matrix) < 1e-10
    assert _relative_difference(out_r.offset_conformal.matrix, in_r.offset_conformal.matrix) > 1e-3


def test_full_area_difference_is_the_operator_of_the_inner_product():
    vertices, triangles = icosphere(1)
    target = stretch_and_bend(vertices)
    differences = core.shape_differences(vertices, target, triangles, use_extrinsic=False)
    rng = np.random.default_rng(0)
    f, g = rng.normal(size=(2, len(vertices)))
    base_mass, target_mass = differences.area.base_product, differences.area.target_product
    # ⟨F f, F g⟩_N = ⟨f, D g⟩_M with the identity functional map (§4.1).
    assert np.isclose(f @ (target_mass @ g), f @ (base_mass @ (differences.area.dense() @ g)), rtol=1e-10)
    conformal = differences.conformal
    g0 = g - (g @ (base_mass @ np.ones_like(g))) / base_mass.sum()  # orthogonal to constants
    assert np.isclose(
        f @ (conformal.target_product @ g0), f @ (conformal.base_product @ (conformal.dense() @ g0)), rtol=1e-8
    )


def test_reduced_differences_of_the_identity_are_the_identity():
    vertices, triangles = icosphere(2)
    reference = core.ReferenceShape(vertices, triangles)
    k = 20
    for k_n in (None, 30):
        d = reference.shape_differences(vertices, k_M=k, k_N=k_n)
        assert np.allclose(d.area.matrix, np.eye(k), atol=1e-8)
        expected = np.eye(k)
        expected[0, 0] = 0.0  # the constant function has λ = 0: diag(λ)⁺ drops it
        assert np.allclose(d.conformal.matrix, expected, atol=1e-6)
        assert d.offset_area.matrix.shape == (k, k)


def test_reduced_difference_matches_its_definition():
    vertices, triangles = icosphere(2)
    target = stretch_and_bend(vertices)
    reference = core.ReferenceShape(vertices, triangles, use_extrinsic=False)
    k = 25
    basis = reference.base.basis(k)
    phi = basis.functions
    assert np.allclose(phi.T @ reference.base.mass @ phi, np.eye(k), atol=1e-9)
    assert np.allclose(reference.base.conformal @ phi, (reference.base.mass @ phi) * basis.eigenvalues, atol=1e-7)
    d = reference.shape_differences(target, k_M=k)
    full = reference.shape_differences(target)
    assert np.allclose(d.area.matrix, phi.T @ full.area.target_product @ phi, atol=1e-12)
    scaled = basis.eigenvalues[1:, None] * d.conformal.matrix[1:]
    assert np.allclose(scaled, (phi.T @ full.conformal.target_product @ phi)[1:], atol=1e-9)


def test_truncated_differences_are_reproducible_on_a_symmetric_mesh():
    # A square grid has repeated Laplace–Beltrami eigenvalues: any rotation of such an eigenspace
    # is an eigenbasis, so the sparse eigensolver must start from the same vector every time.
    vertices, triangles = grid(30)
    assert vertices.shape[0] > core.laplace_basis.DENSE_EIGEN_LIMIT  # the sparse (ARPACK) path
    target = drape(vertices)
    first, second = (core.ReferenceShape(vertices, triangles, use_extrinsic=False) for _ in range(2))
    np.testing.assert_allclose(first.base.basis(40).functions, second.base.basis(40).functions, atol=1e-10)
    a = first.shape_differences(target, k_M=40, k_N=80)
    b = second.shape_differences(target, k_M=40, k_N=80)
    np.testing.assert_allclose(a.conformal.matrix, b.conformal.matrix, atol=1e-10)


def test_zero_basis_size_means_the_full_basis_as_in_the_sidebar():
    base, triangles = grid(6, 6)
    target = stretch_and_bend(base)
    reference = core.ReferenceShape(base, triangles)
    zero = reference.shape_differences(target, k_M=0, k_N=0)
    assert zero.k_M is None and zero.k_N is None
    full = reference.shape_differences(target)
    assert np.allclose(zero.offset_conformal.dense(), full.offset_conformal.dense(), rtol=0, atol=1e-12)
    with pytest.raises(core.MeshError, match="k_N .* needs k_M"):
        reference.shape_differences(target, k_M=0, k_N=20)
