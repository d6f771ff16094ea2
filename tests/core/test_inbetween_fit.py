"""The reconstruction's fit tolerances (core.inbetween_fit; issue 3); no bpy."""

from __future__ import annotations

import numpy as np
import pytest


def test_fit_tolerance_leaves_out_the_edges_a_fold_collapses():
    """Keys whose edges all change by 2 % but for 0.5 % of them that collapse by 60 %: the fit's
    tolerance is half the 2 % (TOLERANCE_TRIM drops the largest 1 %), the whole change's includes
    them; no change gives the METRIC_TOLERANCE floor."""
    from core.inbetween_fit import METRIC_TOLERANCE, change_tolerance, trimmed_tolerance

    base = np.random.default_rng(5).uniform(0.5, 2.0, size=(3, 20000))
    change = np.full(base.shape, 0.02)
    change.ravel()[::200] = -0.6
    assert trimmed_tolerance(base, base * (1.0 + change)) == pytest.approx(0.5 * 0.02, rel=1e-12)
    assert change_tolerance(base, base * (1.0 + change)) == pytest.approx(0.5 * (0.995 * 0.02 + 0.005 * 0.6), rel=1e-12)
    assert trimmed_tolerance(base, base.copy()) == change_tolerance(base, base.copy()) == METRIC_TOLERANCE


def test_the_fits_incidence_is_the_corner_edges_difference_operator_in_canonical_form():
    """``Topology.Dc`` (made in CSR form directly) is the matrix the sparse conversion from
    coordinates gives, to its index arrays and types (the factorizations depend on its layout),
    and takes positions to the corner edges ``p[next corner] − p[corner]``, corner-major."""
    import scipy.sparse as sp

    from core.inbetween_topology import Topology
    from core.mesh_topology import mesh_topology
    from meshes import grid, icosphere

    for vertices, triangles in (grid(6, 5, jitter=0.2), icosphere(2)):
        vertices = np.asarray(vertices, dtype=np.float64)
        topo = Topology(mesh_topology(triangles, len(vertices)), vertices)
        m, rows = len(triangles), np.arange(3 * len(triangles))
        expected = sp.csr_matrix((np.r_[-np.ones(3 * m), np.ones(3 * m)],
                                  (np.r_[rows, rows], np.r_[triangles.T.ravel(), triangles[:, [1, 2, 0]].T.ravel()])),
                                 shape=(3 * m, len(vertices)))
        for part in ("data", "indices", "indptr"):
            made, converted = getattr(topo.Dc, part), getattr(expected, part)
            assert made.dtype == converted.dtype and np.array_equal(made, converted)
        assert topo.Dc.has_canonical_format
        edges = (topo.Dc @ vertices).reshape(3, m, 3)
        for c in range(3):
            assert np.array_equal(edges[c], vertices[triangles[:, (c + 1) % 3]] - vertices[triangles[:, c]])


@pytest.mark.parametrize("precision", ["double", "local steps"])
def test_a_local_step_turns_each_triangle_by_its_own_rotation_within_the_limit(strip, precision):
    """Current edges that are the interpolated target edges turned per triangle by a rotation
    ``R_k`` (random axis; 10–40° or 50–80°) and scaled by ``c_k``: the polar factor of each
    triangle's map is ``R_k`` times the interpolated rotation, so the local step gives back
    ``R_k`` applied to the target edges where the turn is within the 45° limit and the target
    edges themselves beyond it (independent formula: the rotations as made; the step's
    closed-form 2×2 square root is not used), in double precision and in the local steps'."""
    from scipy.spatial.transform import Rotation

    from core.inbetween_fit import MAX_ROTATION_DEVIATION
    from core.sequence_inbetweens import SequenceInterpolator
    from inbetween_helpers import _bend

    flat, tri = strip
    gap = SequenceInterpolator([flat, _bend(flat, 0.6), _bend(flat, 1.2)], tri)._gap(0)
    gap.select(0.5)
    frames, stretch, _, _ = gap.targets(0.5)
    targets = gap.fit_targets(frames, stretch)
    m = targets["edges"].shape[2]
    rng = np.random.default_rng(11)
    angles = np.radians(np.where(rng.random(m) < 0.5, rng.uniform(10, 40, m), rng.uniform(50, 80, m)))
    axes = rng.normal(size=(m, 3))
    turns = Rotation.from_rotvec(axes / np.linalg.norm(axes, axis=1)[:, None] * angles[:, None]).as_matrix()
    turned = np.einsum("kij,jck->ick", turns, targets["edges"]) * rng.uniform(0.5, 2.0, m)
    expected = np.where(angles <= MAX_ROTATION_DEVIATION, np.einsum("kij,jck->ick", turns, targets["edges"]),
                        targets["edges"])
    assert 0.3 * m < np.count_nonzero(angles <= MAX_ROTATION_DEVIATION) < 0.7 * m
    if precision == "double":
        np.testing.assert_allclose(gap.fitted_edges(turned, targets), expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    else:  # float32: ~1e-7 relative per operation, a few dozen of them
        local = gap.local_step_targets(targets)
        out = gap.fitted_edges(turned.astype(np.float32), local)
        assert out.dtype == np.float32
        np.testing.assert_allclose(out, expected, rtol=0, atol=2e-5 * np.abs(expected).max())


def test_the_short_edge_floor_is_written_into_a_strided_array_too():
    """``floored_deviations`` sets ``|ℓ − t| / floor`` on the short edges of the array it is given,
    in place, also when that array is a strided slice (a reshape of one would be a copy)."""
    from core.inbetween_fit import floored_deviations
    rng = np.random.default_rng(3)
    lengths, targets = rng.uniform(0.5, 2.0, (2, 3, 3, 8))
    whole = np.abs(lengths / targets - 1.0)
    deviations = whole[:, :, :5]  # five of eight triangles: no single stride
    short = np.array([0, 5, 11])
    floor = 4.0
    part_lengths, part_targets = np.ascontiguousarray(lengths[:, :, :5]), np.ascontiguousarray(targets[:, :, :5])
    expected = np.abs(part_lengths / part_targets - 1.0).reshape(-1)
    expected[short] = np.abs(part_lengths.reshape(-1)[short] - part_targets.reshape(-1)[short]) / floor
    floored_deviations(deviations, part_lengths, part_targets, floor, short)
    assert np.array_equal(deviations.reshape(-1), expected)
    assert np.array_equal(whole[:, :, :5], deviations)  # written through to the array sliced
