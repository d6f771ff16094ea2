"""Hostile inputs through the public API (issue 19): every bad argument is a documented exception
(MeshError for meshes and parameters, RecoveryError for solver failure) naming the argument and
the user's own index; accepted input the method cannot represent faithfully gets a
ShapeDifferenceWarning; inputs are never modified. Numbered tests follow the issue's items."""

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import core
from core import MeshError, RecoveryError, ShapeDifferenceWarning

from meshes import drape, grid, icosphere


@pytest.fixture(scope="module")
def sheet():
    v, t = grid(6, jitter=0.2)
    return v, t, drape(v, 1.0)


@pytest.fixture(scope="module")
def sequence(sheet):
    v, t, target = sheet
    return core.SequenceInterpolator([v, target, drape(v, 1.5)], t)


def _no_warnings(function, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return function(*args, **kwargs)


def _bow_tie(v, t):
    """Two copies of the sheet touching at one vertex (the first copy's far corner)."""
    n = len(v)
    corner, other = int(np.argmax(v[:, 0] + v[:, 1])), int(np.argmin(v[:, 0] + v[:, 1]))
    v2 = np.concatenate([v, v + [1.0, 1.0, 0.3]])
    v2[n + other] = v[corner]
    t2 = np.concatenate([t, t + n])
    t2[t2 == n + other] = corner
    return v2, t2, corner


# -- item 2: bow-tie vertices -----------------------------------------------------------------
def test_2_bow_tie_vertex_is_rejected_with_its_index_and_the_fix(sheet):
    v, t, _ = sheet
    v2, t2, corner = _bow_tie(v, t)
    for call in (lambda: core.shape_differences(v2, drape(v2, 0.8), t2),
                 lambda: core.interpolate(v2, drape(v2, 0.8), t2, 0.5),
                 lambda: core.default_offset(v2, t2) and core.ReferenceShape(v2, t2)):
        with pytest.raises(MeshError, match=rf"Vertices \[{corner}\].*bow-tie.*Rip Vertices"):
            call()


def test_manifold_meshes_with_boundary_corners_pass(sheet):
    v, t, target = sheet
    _no_warnings(core.shape_differences, v, target, t)


# -- item 3: large bases use the dense eigensolver ---------------------------------------------
def test_3_basis_near_the_vertex_count_uses_the_dense_solver(monkeypatch):
    import scipy.sparse.linalg

    v, t = grid(26, jitter=0.2)  # 676 vertices: above the small-mesh dense limit
    n = len(v)

    def no_arpack(*args, **kwargs):
        raise AssertionError("ARPACK used for a basis of nearly every vertex")

    monkeypatch.setattr(scipy.sparse.linalg, "eigsh", no_arpack)
    d = core.shape_differences(v, drape(v, 1.0), t, k_M=n - 1, use_extrinsic=False)
    basis = d.area.basis
    assert basis.size == n - 1
    reference = d.reference
    gram = basis.functions.T @ (reference.base.mass @ basis.functions)
    assert np.allclose(gram, np.eye(n - 1), atol=1e-8)  # A-orthonormal, as eq. (5) needs
    residual = reference.base.conformal @ basis.functions - reference.base.mass @ basis.functions * basis.eigenvalues
    assert np.linalg.norm(residual) <= 1e-8 * np.linalg.norm(reference.base.conformal @ basis.functions)


# -- item 4: Interpolator / SequenceInterpolator validate k and offset --------------------------
@pytest.mark.parametrize("options, message", [
    (dict(k_M=-3), "k_M"), (dict(k_M=500), "at most 35"), (dict(k_M=5, k_N=500), "k_N"),
    (dict(k_N=5), "needs k_M"), (dict(offset=-1.0), "positive"), (dict(offset=float("nan")), "finite"),
    (dict(offset="a"), "real number"), (dict(offset=True), "real number"),
])
def test_4_interpolators_reject_bad_basis_sizes_and_offsets(sheet, options, message):
    v, t, target = sheet
    for build in (lambda: core.Interpolator(v, target, t, **options),
                  lambda: core.SequenceInterpolator([v, target], t, **options),
                  lambda: core.interpolate(v, target, t, 0.5, **options),
                  lambda: core.shape_differences(v, target, t, **options)):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # an error, not a warning and a fallback
            with pytest.raises(MeshError, match=message):
                build()


# -- item 5: reconstruct checks that the differences belong to the mesh ------------------------
def test_5_reconstruct_rejects_reversed_triangles_another_mesh_or_another_base(sheet):
    v, t, target = sheet
    d = core.shape_differences(v, target, t)
    with pytest.raises(MeshError, match="another order"):
        core.reconstruct(v, t[:, ::-1], d)
    w, s = grid(4)
    with pytest.raises(MeshError, match="36 vertices and 50 triangles"):
        core.reconstruct(w, s, d)
    moved = v.copy()
    moved[7] += 0.1
    with pytest.raises(MeshError, match="vertex 7"):
        core.reconstruct(moved, t, d)
    with pytest.raises(MeshError, match="ShapeDifferences"):
        core.reconstruct(v, t, [d.area, d.conformal])
    assert np.allclose(core.reconstruct(v, t, d)[:, :2].std(), target[:, :2].std(), rtol=0.2)


# -- item 6: no raw exception escapes -----------------------------------------------------------
@pytest.mark.parametrize("call, message", [
    (lambda v, t, g, s: s.pose(0, 1e200), "factor"),
    (lambda v, t, g, s: s.pose_at(float("nan")), "time"),
    (lambda v, t, g, s: s.pose_at(1e20), "time"),
    (lambda v, t, g, s: core.shape_differences(v * 1e80, g * 1e80, t), "1e\\+30"),
    (lambda v, t, g, s: core.interpolate(v * 1e80, g * 1e80, t, 0.5), "1e\\+30"),
    (lambda v, t, g, s: core.shape_differences(v * 1e-80, g * 1e-80, t), "units across"),
    (lambda v, t, g, s: core.interpolate(v * 1e-80, g * 1e-80, t, 0.5), "units across"),
    (lambda v, t, g, s: core.shape_differences(v, g, t.astype(str)), "triangles"),
    (lambda v, t, g, s: core.shape_differences(v, g * 1e160, t), "target_vertices"),
    (lambda v, t, g, s: core.shape_differences(v.tolist() + [["a", 0, 0]], g, t), "numbers"),
    (lambda v, t, g, s: core.shape_differences(v, g, [[0, 1]]), "shape"),
    (lambda v, t, g, s: core.interpolate(v, g, t, "half"), "factor"),
])
def test_6_extreme_or_malformed_input_is_a_mesh_error(sheet, sequence, call, message):
    v, t, target = sheet
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow RuntimeWarnings either
        with pytest.raises(MeshError, match=message):
            call(v, t, target, sequence)


def test_6_solver_failure_is_a_recovery_error():
    from core.validation import numerical_failures

    with pytest.raises(RecoveryError, match="LinAlgError"):
        with numerical_failures("A step"):
            np.linalg.solve(np.zeros((2, 2)), np.ones(2))


def test_6_sliver_the_length_solve_cannot_resolve_is_a_recovery_error(sheet):
    """A target triangle squashed to 1e-8 of its height (accepted: above the degenerate limit)
    makes the Gauss–Newton normal matrix of the length recovery indefinite in round-off; CHOLMOD's
    refusal escaped ``reconstruct`` as a raw ``ValueError``."""
    v, t, target = sheet
    a, b, c = t[10]
    sliver = target.copy()
    middle = 0.5 * (sliver[a] + sliver[b])
    sliver[c] = middle + 1e-8 * (sliver[c] - middle)
    differences = core.shape_differences(v, sliver, t)
    with pytest.raises(RecoveryError, match="edge lengths.*sliver"):
        core.reconstruct(v, t, differences)


# -- item 7: accepted extreme input is warned about ---------------------------------------------
def test_7_stray_vertex_far_away_warns_about_precision(sheet):
    v, t, target = sheet
    stray = target.copy()
    stray[5] += 1e6
    with pytest.warns(ShapeDifferenceWarning, match="loses precision"):
        core.shape_differences(v, stray, t)
    reference = core.ReferenceShape(v, t)  # a base prepared for many targets warns the same (it was silent)
    with pytest.warns(ShapeDifferenceWarning, match="target vertices: .* loses precision"):
        reference.shape_differences(stray)
    with pytest.warns(ShapeDifferenceWarning, match="mean edge length"):
        core.ReferenceShape(v, t, offset=1e12).shape_differences(target)
    stray[5] = target[5] + 1e3  # far, but within precision: no warning
    _no_warnings(core.shape_differences, v, stray, t)
    _no_warnings(reference.shape_differences, stray)


def test_7_offset_far_from_the_mesh_scale_warns(sheet):
    v, t, target = sheet
    with pytest.warns(ShapeDifferenceWarning, match="mean edge length"):
        core.shape_differences(v, target, t, offset=1e12)
    _no_warnings(core.shape_differences, v, target, t, offset=0.1)


def test_7_fold_the_lengths_cannot_decide_warns():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    t = np.array([[0, 1, 2], [1, 3, 2]])
    folded = v.copy()
    folded[3] = [0.5, 0.5, np.sqrt(0.5)]  # 90° about the diagonal
    d = core.shape_differences(v, folded, t)
    with pytest.warns(ShapeDifferenceWarning, match="undetermined"):
        core.reconstruct(v, t, d)


def test_7_exact_reconstruction_stays_silent(sheet):
    v, t, target = sheet
    d = core.shape_differences(v, target, t)
    x = _no_warnings(core.reconstruct, v, t, d)
    edges = core.ReferenceShape(v, t).topology.edges
    lengths = lambda p: np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1)  # noqa: E731
    assert np.allclose(lengths(x), lengths(target), rtol=1e-6)


# -- item 8: default_offset validates ---------------------------------------------------------
@pytest.mark.parametrize("vertices, triangles, message", [
    (lambda v: v * np.nan, lambda t: t, "non-finite"),
    (lambda v: v, lambda t: t[:0], "no triangles"),
    (lambda v: v, lambda t: -t - 1, "negative indices"),
    (lambda v: v[:, :2], lambda t: t, "shape"),
])
def test_8_default_offset_validates(sheet, vertices, triangles, message):
    v, t, _ = sheet
    with pytest.raises(MeshError, match=message):
        core.default_offset(vertices(v), triangles(t))
    assert core.default_offset(v, t) > 0


# -- item 9: messages in the user's terms -------------------------------------------------------
def test_9_messages_name_the_users_own_indices_and_values(sheet):
    v, t, target = sheet
    big = np.where(t == 0, 1e20, t).astype(float)
    with pytest.raises(MeshError, match=r"\[1e\+20, 1, 6\]"):
        core.shape_differences(v, target, big)
    with pytest.raises(MeshError, match="target_vertices.*coordinate"):
        core.shape_differences(v, target * 1e40, t)  # overflow, not "zero area"
    flat = target.copy()
    flat[t[3]] = flat[t[3][0]]
    with pytest.raises(MeshError, match="target_vertices: triangle"):
        core.shape_differences(v, flat, t)
    with pytest.raises(MeshError, match=r"k_M .* is 36.*35"):
        core.shape_differences(v, target, t, k_M=36)


def test_9_loose_vertices_keep_the_users_numbering(sheet):
    v, t, target = sheet
    loose = np.concatenate([[[5.0, 5.0, 5.0]], v])  # vertex 0 in no triangle
    stray = np.concatenate([[[5.0, 5.0, 5.0]], target])
    stray[6] += 1e6
    with pytest.warns(ShapeDifferenceWarning, match=r"vertices \[.*\b6\b.*\]"):
        core.shape_differences(loose, stray, t + 1)
    # a degenerate triangle is named by its corners in the user's numbering by every entry point
    # (before, ReferenceShape, distortion and shape_space named them one lower)
    flat = loose.copy()
    corners = t[3] + 1
    flat[corners[2]] = 0.5 * (flat[corners[0]] + flat[corners[1]])
    message = rf"triangle 3 \(vertices \[{', '.join(str(c) for c in corners)}\]\) has zero area"
    for call in (lambda: core.ReferenceShape(flat, t + 1), lambda: core.distortion(flat, loose, t + 1),
                 lambda: core.shape_space([flat, loose], t + 1, k_M=5, k_N=None),
                 lambda: core.ReferenceShape(loose, t + 1).shape_differences(flat)):
        with pytest.raises(MeshError, match=message):
            call()


# -- item 10: no silent coercions ---------------------------------------------------------------
@pytest.mark.parametrize("call, message", [
    (lambda v, t, g, s: core.shape_differences(v + 1j, g, t), "complex"),
    (lambda v, t, g, s: s.pose(1.7, 0.5), "whole number"),
    (lambda v, t, g, s: s.pose(True, 0.5), "boolean"),
    (lambda v, t, g, s: core.shape_differences(v, g, t, k_M=10.5), "whole number"),
    (lambda v, t, g, s: core.shape_differences(v, g, t, k_M=True), "boolean"),
    (lambda v, t, g, s: core.shape_differences(v, g, t, use_extrinsic="False"), "True or False"),
    (lambda v, t, g, s: core.Interpolator(v, g, t, use_extrinsic=0), "True or False"),
    (lambda v, t, g, s: core.SequenceInterpolator([v, g], t, smooth="yes"), "True or False"),
    (lambda v, t, g, s: core.shape_differences(v, g, t + 0.5), "whole numbers"),
    (lambda v, t, g, s: core.shape_differences(v, g, t.astype(bool)), "booleans"),
])
def test_10_no_silent_coercion(sheet, sequence, call, message):
    v, t, target = sheet
    with pytest.raises(MeshError, match=message):
        call(v, t, target, sequence)


def test_pulled_back_metric_takes_vertex_indices_and_basis_sizes_only(sheet):
    """``True`` is no source vertex (it was read as vertex 1), and a basis size out of range is
    not answered with the full basis, which the pulled-back metric does not offer."""
    v, t, target = sheet
    pulled = core.pull_back(v, t, core.shape_differences(v, target, t, use_extrinsic=False))
    for source in (True, np.True_, -1, 1.5, len(v)):
        with pytest.raises(MeshError, match="source_vertex must be a vertex index"):
            pulled.geodesic_distances(source)
    assert np.array_equal(pulled.geodesic_distances(np.int32(1)), pulled.geodesic_distances(1))
    for k in (0, len(v)):
        with pytest.raises(MeshError, match=r"between 1 and \d+; got \d+\. Lower k\.$"):
            pulled.laplacian_eigenvalues(k)


def test_gap_index_errors_are_also_index_errors(sequence):
    for gap in (-1, 2, 10**20):
        with pytest.raises(IndexError, match="gap"):
            sequence.pose(gap, 0.5)


def test_whole_float_basis_size_and_numpy_scalars_are_accepted(sheet):
    v, t, target = sheet
    d = core.shape_differences(v, target, t, k_M=np.int32(8), k_N=12.0, offset=np.array(0.1, dtype=np.float32),
                               use_extrinsic=np.True_)
    assert (d.k_M, d.k_N) == (8, 12) and isinstance(d.k_M, int)


def test_basis_of_constants_only_is_rejected(sheet):
    # The first eigenfunction of each connected part is constant (λ = 0): a basis of those alone
    # gives an empty conformal difference (it reconstructed the base silently, with BLAS errors).
    v, t, target = sheet
    two_v, two_t = np.vstack([v, v + 3.0]), np.vstack([t, t + len(v)])
    two_target = np.vstack([target, target + 3.0])
    with pytest.raises(MeshError, match="k_M .* is 1.*constant"):
        core.shape_differences(v, target, t, k_M=1)
    with pytest.raises(MeshError, match="k_N .* is 2.*2 connected part"):
        core.shape_differences(two_v, two_target, two_t, k_M=5, k_N=2)
    with pytest.raises(MeshError, match="constant"):
        core.interpolate(v, target, t, 0.5, k_M=1)
    assert core.shape_differences(two_v, two_target, two_t, k_M=3, use_extrinsic=False).k_M == 3


def test_target_basis_smaller_than_the_base_basis_is_rejected(sheet):
    # Eq. (6)'s map F is k_N × k_M: with k_N < k_M it has rank k_N at most, so the area difference
    # FᵀF is singular (a pose rebuilt from it was 0.33–0.41 of the diagonal off, silently); the
    # paper's recovery assumes k_N ≥ k_M. Every entry point refuses it; k_N = k_M is accepted.
    v, t, target = sheet
    reference = core.ReferenceShape(v, t)
    builds = (lambda k_M, k_N: core.shape_differences(v, target, t, k_M=k_M, k_N=k_N),
              lambda k_M, k_N: reference.shape_differences(target, k_M=k_M, k_N=k_N),
              lambda k_M, k_N: core.Interpolator(v, target, t, k_M=k_M, k_N=k_N),
              lambda k_M, k_N: core.SequenceInterpolator([v, target], t, k_M=k_M, k_N=k_N),
              lambda k_M, k_N: core.shape_space([v, target], t, k_M=k_M, k_N=k_N),
              lambda k_M, k_N: core.Transfer(v, t, v, t, k_M=k_M, k_N=k_N))
    for build in builds:
        with pytest.raises(MeshError, match="k_N .* is 9, below k_M .* 10.*at least k_M"):
            build(10, 9)
    differences = core.shape_differences(v, target, t, k_M=10, k_N=10, use_extrinsic=False)
    assert differences.area.matrix.shape == (10, 10) and np.linalg.matrix_rank(differences.area.matrix) == 10


def test_intrinsic_only_reconstruction_warns_where_the_lengths_leave_the_pose_free():
    # Intrinsic differences fix the edge lengths (Propositions 1-2), not the pose: a sphere with one
    # vertex pushed in (a dimple, its edges within 0.1 % of the sphere's) came back without the
    # dimple, and a draped sheet flat-ish (another shape with the same lengths), silently.
    def rebuilt(v, t, target, use_extrinsic):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pose = core.reconstruct(v, t, core.shape_differences(v, target, t, use_extrinsic=use_extrinsic))
        return pose, [str(w.message) for w in caught if issubclass(w.category, ShapeDifferenceWarning)]

    def off(pose, target):  # largest distance after the best rigid motion (the differences' gauge)
        a, b = pose - pose.mean(axis=0), target - target.mean(axis=0)
        return np.abs(Rotation.align_vectors(b, a)[0].apply(a) - b).max()

    v, t = icosphere(3)
    k = 100  # a valence-6 vertex reflected through the plane of its neighbours
    ring = np.unique(t[(t == k).any(axis=1)])
    ring = ring[ring != k]
    centre = v[ring].mean(axis=0)
    normal = np.linalg.svd(v[ring] - centre)[2][2]
    dimpled = v.copy()
    dimpled[k] -= 2.0 * ((v[k] - centre) @ normal) * normal
    pose, caught = rebuilt(v, t, dimpled, False)
    assert len(caught) == 1 and "intrinsic differences only" in caught[0] and "other side" in caught[0]
    side = lambda x: (x[k] - x[ring].mean(axis=0)) @ x[k]  # > 0: the vertex out of its ring, as on the sphere
    assert side(dimpled) < 0 < side(pose)  # the lengths allowed both: the returned one is not the target's
    pose, caught = rebuilt(v, t, dimpled, True)  # the extrinsic pair determines it
    assert not caught and off(pose, dimpled) < 1e-6

    sheet, sheet_t = grid(8, jitter=0.2)
    pose, caught = rebuilt(sheet, sheet_t, drape(sheet, 1.0), False)
    assert any("1 part(s) with a boundary" in message for message in caught)

    # a coarse closed mesh bent so that no star can flip without changing its edges: the lengths pin
    # it (the icosphere itself can: each valence-5 vertex's neighbours lie in a plane)
    v, t = icosphere(1)
    target = v @ np.array([[1.2, 0.1, 0.0], [0.0, 0.9, 0.2], [0.1, 0.0, 1.0]]).T + 0.1 * np.sin(2.0 * v[:, [1, 2, 0]])
    pose, caught = rebuilt(v, t, target, False)
    assert not caught and off(pose, target) < 1e-6


# -- inputs are never modified, also on failure --------------------------------------------------
def test_inputs_unchanged_on_success_and_failure(sheet):
    v, t, target = sheet
    arrays = [v.copy(), target.copy(), t.copy()]
    d = core.shape_differences(*arrays[:2], arrays[2], k_M=10)
    core.reconstruct(arrays[0], arrays[2], d)
    core.interpolate(arrays[0], arrays[1], arrays[2], 0.5)
    with pytest.raises(MeshError):
        core.reconstruct(arrays[0], arrays[2][:, ::-1], d)
    with pytest.raises(MeshError):
        core.shape_differences(arrays[0], arrays[1], arrays[2], k_M=99)
    for got, expected in zip(arrays, (v, target, t)):
        assert np.array_equal(got, expected)
    for array in arrays:
        array.setflags(write=False)  # read-only inputs (e.g. Blender buffers) work too
    core.shape_differences(*arrays[:2], arrays[2])


@pytest.mark.parametrize("dtype", [np.float16, object])
def test_two_pose_interpolation_computes_in_float64_whatever_the_dtype(dtype):
    """A sheet 2,000 units across turned by 30°, given as float16 (a half-float cache) or as an
    object array: the same poses as from float64 (before, float16 overflowed in the seam tolerance
    and every vertex was held still: factor 1 gave ``a``, 1,000 units from ``b``; object arrays
    raised a TypeError from NumPy)."""
    v, t = grid(6)
    v = v * 1000.0
    turn = np.radians(30.0)
    rotation = np.array([[np.cos(turn), 0.0, np.sin(turn)], [0.0, 1.0, 0.0], [-np.sin(turn), 0.0, np.cos(turn)]])
    a, b = v.astype(np.float16), (v @ rotation.T).astype(np.float16)
    expected = core.Interpolator(a.astype(np.float64), b.astype(np.float64), t)
    given = core.Interpolator(a.astype(dtype), b.astype(dtype), t)
    for factor in (0.5, 1.0):
        np.testing.assert_allclose(given.pose(factor), expected.pose(factor), atol=1e-9)
    np.testing.assert_allclose(given.pose(1.0), b, atol=1e-9)


def test_a_triangle_soup_is_told_to_weld(sheet):
    """Every face split apart (a triangle soup, as some exporters write) is refused by the analyses
    with the advice to weld (Merge by Distance), naming the vertices that sit at another part's
    vertex: for the full basis and the offset surface, a truncated basis below the parts' count,
    the shape space and the distortion maps (they said only "use a connected surface" or "use
    k_M of at least <the number of faces + 1>"). Faces that only lie apart get no such advice."""
    from core.distortion_maps import DistortionAnalyzer

    v, t, target = sheet
    soup, soup_t = v[t].reshape(-1, 3), np.arange(3 * len(t)).reshape(-1, 3)
    pose = target[t].reshape(-1, 3)
    # the vertices at another face's vertex: all but the corners in a single triangle
    shared = int(np.count_nonzero(np.bincount(t.ravel(), minlength=len(v))[t.ravel()] > 1))
    calls = (lambda: core.shape_differences(soup, pose, soup_t),
             lambda: core.shape_differences(soup, pose, soup_t, k_M=10, use_extrinsic=False),
             lambda: core.shape_space([soup, pose], soup_t, k_M=10),
             lambda: core.distortion(soup, pose, soup_t),
             lambda: DistortionAnalyzer(soup, soup_t, use_extrinsic=False, k=10).pose(pose).eigenfunctions())
    for call in calls:
        with pytest.raises(MeshError, match=rf" {shared} of its {soup.size // 3} vertices sit at the place of a "
                                            r"vertex of another part.*Merge by Distance\.$"), warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)  # the distortion pose's seam folds, said apart
            call()
    apart = soup + 0.1 * np.repeat(np.arange(len(t)), 3)[:, None]  # the faces moved away from each other
    for call in (lambda: core.shape_differences(apart, apart, soup_t),
                 lambda: core.shape_differences(apart, apart, soup_t, k_M=10, use_extrinsic=False)):
        with pytest.raises(MeshError) as error:
            call()
        assert "Merge by Distance" not in str(error.value)


@pytest.mark.parametrize("factor", [1000.0, -1000.0])
def test_an_exaggeration_far_past_the_keys_leaks_no_numpy_warning(sheet, factor):
    """Exaggerated ×1000 (two poses and a sequence), the single-precision local steps of the fit
    overflow: the pose is finite and warned about as a ShapeDifferenceWarning, and no NumPy
    RuntimeWarning leaks to the caller (they did, from core/inbetween_fit.py)."""
    v, t, target = sheet
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        poses = [core.Interpolator(v, target, t).pose(factor),
                 core.SequenceInterpolator([v, target, drape(v, 1.5)], t).poses(0, [factor])[0]]
    assert all(np.isfinite(pose).all() for pose in poses)
    categories = {w.category for w in caught}
    assert ShapeDifferenceWarning in categories
    assert categories == {ShapeDifferenceWarning}, [str(w.message) for w in caught
                                                    if w.category is not ShapeDifferenceWarning]


def test_a_sliver_a_skin_opens_leaks_no_numpy_warning():
    """One triangle of a scan-like head, a T-junction sliver 1e-9 of its longest side high in the
    first key (validation accepts down to 1e-10), that a nod's skin opens to 0.12–0.32 of it in
    the next keys. The metric of the first key seen from the second (the sequence's key before
    gap 1) has a determinant that cancels to 0 in double precision: its inverse is infinite, which
    the metric's spline reads as not positive definite. The in-between is finite, and no NumPy
    "divide by zero" RuntimeWarning reaches the caller (it did, from
    core/inbetween_keys.Relative.inverse; under ``np.seterr(all="raise")`` a RecoveryError)."""
    keys = np.array([
        [[0.0, 0.0, 0.0], [0.04993732610332687, -0.017186925459870328, -0.07781815159757455],
         [0.02496866304536446, -0.008593462822332643, -0.038909075782422586]],
        [[0.0, 0.004973129495406625, -0.038127120551447735], [0.04993732610332687, -0.017186925459870328, -0.07781815159757455],
         [0.02496866304536446, -0.006992870252895855, -0.04800490882306735]],
        [[0.0, 0.03434572960889681, -0.0947165682887369], [0.04993732610332687, -0.017186925459870328, -0.07781815159757455],
         [0.02496866304536446, 0.0006597993851196193, -0.061270330202238266]],
        [[0.0, 0.019644828646134038, -0.07366795034695547], [0.04993732610332687, -0.017186925459870328, -0.07781815159757455],
         [0.02496866304536446, -0.0030926417307187704, -0.05637654502821976]]])
    tri = np.array([[0, 1, 2]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pose = core.SequenceInterpolator(list(keys), tri).poses(1, [0.5])[0]
    assert np.isfinite(pose).all()
    assert not [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]


# -- units: a scene modelled far larger or smaller than 1 ---------------------------------------


def _data(name):
    data = np.load(Path(__file__).parent / "data" / f"{name}.npz")
    return {key: data[key] for key in data.files}


@pytest.mark.parametrize("scale", [2.0 ** -70, 2.0 ** 70, 2.0 ** 96])
def test_in_betweens_scale_with_the_keys(scale):
    """Keys scaled by a power of two (1e-21, 1e21, 8e28: within the accepted 1e-30 to 1e30) give
    the in-betweens and exaggerations of the keys as given, scaled by it: such a scaling changes
    no digit of a coordinate, so they agree to 1e-9 of the diagonal (the fits' tolerances are
    relative; the difference measured is 0), with no NumPy warning. Before, the fits' single-
    precision steps under- and overflowed there: a sequence of pieces 3e-2 of its diagonal off at
    2^70 and a RecoveryError at 2^96, a skinned tentacle 1.4e-2 off at 2^70 and 4.6e-4 at 2^-70."""
    pieces, tentacle = _data("spun_pieces"), _data("skinned_tentacle")
    factors = [0.25, 0.5, 0.75]
    runs = [(pieces["keys"], lambda keys: core.SequenceInterpolator(keys, pieces["triangles"]).poses(1, factors)),
            (np.stack([tentacle["rest"], tentacle["curled"]]),
             lambda keys: np.stack([core.Interpolator(keys[0], keys[1], tentacle["triangles"]).pose(f)
                                    for f in (0.5, 1.5, -0.5)]))]
    for keys, in_betweens in runs:
        diagonal = np.linalg.norm(np.ptp(keys.reshape(-1, 3), axis=0))
        expected = in_betweens(keys)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            got = in_betweens(keys * scale)
        np.testing.assert_allclose(got / scale, expected, rtol=0, atol=1e-9 * diagonal)


@pytest.mark.parametrize("scale", [2.0 ** -70, 2.0 ** -40, 2.0 ** 40, 2.0 ** 70])
def test_the_paper_pipeline_scales_with_the_mesh(scale):
    """A base and target scaled by a power of two (1e-21 to 1e21) give the reconstruction of the
    truncated differences (k_M 20 / k_N 40 on an icosphere; the full basis too), and the pose of
    another mesh rebuilt by a transfer (intrinsic, core.interpolate with target_triangles, and
    extrinsic), of the meshes as given, scaled by it: the base is worked on at unit size
    (core.working_unit), which changes no digit of a coordinate, so they agree to 1e-9 of the
    diagonal (every solver tolerance is relative; the difference measured is 0), with no NumPy
    warning, and the differences' offset and the pulled-back metric's edge lengths (§8.3) are in the
    caller's units. Before, the truncated
    recovery's single-precision ADMM worked in the caller's units: reconstruct failed with SciPy's
    "array must not contain infs or NaNs" at 2^-70 and came out 6.5e-2 of the diagonal off (warned)
    at 2^70; a transfer failed so at 2^-70, 2^-40 and 2^70 and came out 7.5e-2 off, unwarned, at 2^40."""
    v, t = icosphere(2)
    target = v * [1.2, 1.0, 0.8] + 0.1 * np.sin(3 * v[:, [1, 2, 0]])
    va, ta = grid(8)
    vb, tb = grid(11, jitter=0.1, seed=2)
    pb = drape(vb, 1.0)

    def same_mesh(s, **basis):
        differences = core.shape_differences(v * s, target * s, t, **basis)
        return core.reconstruct(v * s, t, differences), differences.offset

    def transfer(s):
        pair = core.interpolate(va * s, pb * s, ta, 0.5, target_triangles=tb, target_rest_vertices=vb * s,
                                k_M=20, k_N=40)
        extrinsic = core.Transfer(va * s, ta, vb * s, tb, k_M=20, k_N=40, use_extrinsic=True).pose(pb * s)
        return np.concatenate([pair, extrinsic]), 0.0

    runs = [(v, lambda s: same_mesh(s, k_M=20, k_N=40)), (v, lambda s: same_mesh(s)), (va, transfer)]
    for base, run in runs:
        diagonal = np.linalg.norm(np.ptp(base, axis=0))
        expected, offset = run(1.0)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            got, scaled_offset = run(scale)
        np.testing.assert_allclose(got / scale, expected, rtol=0, atol=1e-9 * diagonal)
        assert scaled_offset == offset * scale
    # the target's metric pulled back from truncated differences: edge lengths in the caller's units
    lengths = [core.pull_back(v * s, t, core.shape_differences(v * s, target * s, t, k_M=20, k_N=40)).edge_lengths
               for s in (1.0, scale)]
    np.testing.assert_allclose(lengths[1] / scale, lengths[0], rtol=1e-9)


def test_in_betweens_do_not_follow_the_callers_arrays_written_after(sheet):
    """A caller's key arrays written over after the interpolators were made (a frame buffer filled
    again with the next frame, a pose moved in place) change none of their results: the keys at
    factors 0 and 1, and the in-betweens, are those of the keys as given. Before, the interpolators
    kept the caller's float64 arrays themselves: the keys they returned followed the caller's
    writes while the in-betweens stayed prepared from the old keys."""
    v, t, target = sheet
    a, b = v.copy(), target.copy()
    keys = np.stack([v, target, drape(v, 1.5)])
    pair, sequence = core.Interpolator(a, b, t), core.SequenceInterpolator(keys, t)
    factors = [0.0, 0.5, 1.0]
    expected = ([pair.pose(f) for f in factors], [sequence.poses(g, factors) for g in (0, 1)])
    a += 1.0
    b[:] = 0.0
    keys[1] *= 2.0
    got = ([pair.pose(f) for f in factors], [sequence.poses(g, factors) for g in (0, 1)])
    for was, now in zip(expected[0] + expected[1], got[0] + got[1]):
        np.testing.assert_array_equal(now, was)
    np.testing.assert_array_equal(got[0][0], v)  # the key as given, not as written over


def test_a_vertex_shot_far_away_is_named_not_called_a_zero_area(sheet):
    """A pose with one vertex shot 1e12 away (a simulation that exploded there) makes needles too
    thin to measure around it: the error names that vertex and how far it lies, in every entry
    point that checks poses. Before, it said the needle triangles have "zero area" and advised
    Degenerate Dissolve, which would not find them; a face flattened in place still says so."""
    v, t, target = sheet
    shot = target.copy()
    shot[5] += [0.0, 0.0, 1e12]
    message = r": vertex 5 lies 1e\+12 from the other corners of triangle \d+ .* needles too thin"
    for call, name in ((lambda: core.Interpolator(v, shot, t), "vertices_b"),
                       (lambda: core.shape_differences(v, shot, t), "target_vertices")):
        with pytest.raises(MeshError, match=f"^{name}{message}"):
            call()
    with pytest.raises(MeshError, match=r"^key pose 1: vertex 5 lies 1e\+12"):
        core.SequenceInterpolator([v, shot, target], t)
    flat = target.copy()
    a, b, c = t[3]
    flat[c] = 0.5 * (flat[a] + flat[b])
    with pytest.raises(MeshError, match="has zero area"):
        core.Interpolator(v, flat, t)
