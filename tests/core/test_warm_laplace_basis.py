"""Warm-started Laplace–Beltrami eigensolver (core.laplace_basis.warm_laplace_basis) against ARPACK."""

import logging

import numpy as np
import pytest

from core.errors import MeshError
from core.inner_products import ProductAssembler, pose_products
from core.laplace_basis import WARM_TOLERANCE, laplace_basis, warm_laplace_basis
from core.mesh_topology import mesh_topology
from meshes import grid


@pytest.fixture(scope="module")
def two_poses():
    """A 900-vertex sheet (ARPACK's size range) and the same sheet slightly bent (3 iterations converge)."""
    v, t = grid(30, jitter=0.2)
    bent = v.copy()
    bent[:, 2] = 0.001 * np.sin(np.pi * v[:, 0]) * v[:, 1]
    assembler = ProductAssembler(mesh_topology(t, v.shape[0]))
    return [pose_products(assembler, x)[2:] for x in (v, bent)]


def largest_angle(a, b, mass):
    """Largest principal angle between the spans of A-orthonormal ``a`` and ``b``."""
    cosines = np.linalg.svd(a.T @ (mass @ b), compute_uv=False)
    return float(np.sqrt(max(0.0, 1.0 - cosines.min() ** 2)))


def test_matches_arpack_from_a_nearby_pose(two_poses, caplog):
    (m0, c0), (m1, c1) = two_poses
    k = 40
    start = laplace_basis(m0, c0, 60)
    with caplog.at_level(logging.INFO, logger="core.laplace_basis"):
        warm = warm_laplace_basis(m1, c1, k, start)
    assert "falling back" not in caplog.text  # the subspace iteration itself converged
    exact = laplace_basis(m1, c1, k)
    assert warm.size == 60
    # residual r ≤ tol·λ_k: eigenvalue errors O(r²/gap) — bounded here by r — and the subspace
    # within r/gap of the exact one; the gap after λ_k on this sheet is ≥ 1e-3 λ_k.
    assert np.abs(warm.eigenvalues[:k] - exact.eigenvalues).max() <= WARM_TOLERANCE * exact.eigenvalues[-1]
    full = laplace_basis(m1, c1, k + 1).eigenvalues
    gap = full[k] - full[k - 1]
    assert largest_angle(warm.functions[:, :k], exact.functions, m1) <= 2 * WARM_TOLERANCE * full[k - 1] / gap
    # A-orthonormal Ritz vectors
    gram = warm.functions.T @ (m1 @ warm.functions)
    assert np.abs(gram - np.eye(60)).max() < 1e-10


def test_falls_back_to_arpack_when_it_does_not_converge(two_poses, caplog):
    (m0, c0), (m1, c1) = two_poses
    start = np.random.default_rng(1).standard_normal((m1.shape[0], 30))  # far from any eigenspace
    with caplog.at_level(logging.INFO, logger="core.laplace_basis"):
        warm = warm_laplace_basis(m1, c1, 20, start, iterations=1)
    assert "falling back" in caplog.text
    exact = laplace_basis(m1, c1, 30)
    np.testing.assert_allclose(warm.eigenvalues, exact.eigenvalues, rtol=0, atol=1e-12 * exact.eigenvalues[-1])


def test_start_must_hold_more_functions_than_wanted(two_poses):
    (m0, c0), _ = two_poses
    with pytest.raises(MeshError, match="warm start"):
        warm_laplace_basis(m0, c0, 20, laplace_basis(m0, c0, 20))
