import numpy as np

from core.small_matrices import cofactors_3x3


def test_cofactors_give_the_inverse_and_determinant_of_each_matrix():
    rng = np.random.default_rng(7)
    matrices = rng.normal(size=(50, 3, 3))
    cofactors, det = cofactors_3x3(matrices)
    np.testing.assert_allclose(det, np.linalg.det(matrices), rtol=1e-12, atol=1e-12)
    inverse = np.transpose(cofactors, (0, 2, 1)) / det[:, None, None]
    np.testing.assert_allclose(inverse @ matrices, np.broadcast_to(np.eye(3), matrices.shape), atol=1e-9)
