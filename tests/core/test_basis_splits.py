"""A truncated basis size that splits a group of equal Laplace–Beltrami eigenvalues (paper §4–5:
the differences live in the first k_M eigenfunctions of the base, eq. (6) also in the first k_N of
the target) holds an arbitrary part of that eigenspace, chosen by rounding: the core warns
(``truncated``) and names the nearest sizes that split no group."""

import warnings

import numpy as np
import pytest
from meshes import grid, icosphere, stretch_and_bend

from core.laplace_basis import REPEATED_GAP, split_group
from core.reference_shape import ReferenceShape


def _split_warnings(vertices, triangles, target, k_M, k_N=None, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ReferenceShape(vertices, triangles, **options).shape_differences(target, k_M=k_M, k_N=k_N)
    return [str(w.message) for w in caught
            if getattr(w.message, "kind", None) == "truncated" and "splits" in str(w.message)]


def test_split_group_finds_the_whole_group_of_equal_eigenvalues_around_the_cut():
    """Against the groups read off by hand: equal within :data:`REPEATED_GAP` (relative) joins,
    twice it does not; a group reaching the last value computed ends there."""
    values = np.array([0.0, 2.0, 2.0 * (1 + REPEATED_GAP / 2), 2.0 * (1 + REPEATED_GAP), 5.0, 7.0, 7.0])
    assert split_group(values, 1) is None  # 0 | 2
    assert split_group(values, 2) == (1, 4)
    assert split_group(values, 3) == (1, 4)
    assert split_group(values, 4) is None  # 2.0…2.00000003 | 5
    assert split_group(values, 6) == (5, 7)  # reaches the end: may go on
    spread = np.array([1.0, 1.0 + 3 * REPEATED_GAP, 2.0])
    assert split_group(spread, 1) is None


def test_an_icosphere_warns_at_a_size_inside_its_five_fold_eigenvalue_and_names_the_safe_sizes():
    """The 162-vertex icosphere's eigenvalues 17–21 of the base (22.64, 5-fold; 22.71 4-fold
    after it) and 21–25 of the offset surface (the 4-fold one first) are equal groups: k_M = 20
    and 21 each split one, 16 and 25 neither — the sizes the message offers."""
    vertices, triangles = icosphere(2)
    target = vertices * np.array([1.2, 1.0, 0.8])
    assert _split_warnings(vertices, triangles, target, 16) == []
    assert _split_warnings(vertices, triangles, target, 25) == []
    at_20 = _split_warnings(vertices, triangles, target, 20)
    assert len(at_20) == 1 and "k_M = 20 splits a group of 5 equal frequencies" in at_20[0]
    assert "base mesh" in at_20[0] and "use k_M = 16 or 25" in at_20[0]
    at_21 = _split_warnings(vertices, triangles, target, 21)
    assert len(at_21) == 1 and "offset surface" in at_21[0] and "use k_M = 16 or 25" in at_21[0]
    # intrinsic only: the base alone decides, and 21 splits none of its groups
    assert _split_warnings(vertices, triangles, target, 21, use_extrinsic=False) == []


def test_a_regular_grid_warns_at_a_size_inside_an_eigenvalue_pair():
    """A square grid's Laplacian has pairs of equal eigenvalues (x ↔ y): its 10th and 11th."""
    vertices, triangles = grid(11)
    target = stretch_and_bend(vertices)
    found = _split_warnings(vertices, triangles, target, 10)
    assert len(found) == 1 and "a group of 2 equal frequencies" in found[0] and "use k_M = 9 or 11" in found[0]
    assert _split_warnings(vertices, triangles, target, 11) == []


@pytest.mark.parametrize("n, jitter", [(11, 0.1), (20, 0.02)])
def test_meshes_without_a_symmetry_do_not_warn_at_any_size(n, jitter):
    """Jittered grids (irregular, as a scan re-meshed): no basis size from 3 to 40 warns."""
    vertices, triangles = grid(n, jitter=jitter)
    target = stretch_and_bend(vertices)
    reference = ReferenceShape(vertices, triangles)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for k in range(3, 41):
            reference.shape_differences(target, k_M=k)
    assert not [w for w in caught if "splits" in str(w.message)]


def test_a_symmetric_target_warns_where_k_N_splits_its_equal_eigenvalues():
    """Eq. (6): the target's basis is truncated too; a jittered base posed as the regular grid
    (pairs of equal eigenvalues, its 10th and 11th) warns at k_N = 10, not at 11."""
    regular, triangles = grid(11)
    jittered, _ = grid(11, jitter=0.1)
    found = _split_warnings(jittered, triangles, regular, 5, 10, use_extrinsic=False)
    assert len(found) == 1 and "k_N = 10" in found[0] and "target pose" in found[0]
    assert "use k_N = 9 or 11" in found[0]
    assert _split_warnings(jittered, triangles, regular, 5, 11, use_extrinsic=False) == []
