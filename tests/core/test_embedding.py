"""Embedding of the canonical thickening from its edge lengths (§7.3) and rigid alignment."""

import sys
import warnings
from pathlib import Path

ROOT = str(Path(__file__).resolve().parents[2])
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

import numpy as np
import pytest

from core.edge_length_fit import EdgeLengthFit, refine_edge_lengths
from core.embedding import CONTINUATION_SCHEDULES, embed_base_edges, embed_thickening
from core.errors import RecoveryError, ShapeDifferenceError, ShapeDifferenceWarning
from core.mesh_topology import mesh_topology
from core.offset_surface import default_offset, offset_surface
from core.rigid_alignment import align_rigidly, rigid_alignment
from meshes import cube_with_bump, drape, grid, icosphere, random_rotation, stretch_and_bend


# -- helpers -------------------------------------------------------------------------------------


def thickening_lengths(base, triangles, target, *, offset=None, noise=0.0, seed=0):
    """(surface, exact (or noisy) thickening squared lengths of ``target``, its points)."""
    topology = mesh_topology(triangles, base.shape[0])
    surface = offset_surface(topology)
    t = default_offset(base, triangles) if offset is None else offset
    offset_positions = surface.positions(target, t)
    base_sq = topology.squared_edge_lengths(target)
    offset_sq = surface.topology.squared_edge_lengths(offset_positions)
    if noise:
        rng = np.random.default_rng(seed)
        base_sq = base_sq * (1 + noise * rng.normal(size=base_sq.shape))
        offset_sq = offset_sq * (1 + noise * rng.normal(size=offset_sq.shape))
    return surface, surface.thickening_squared_lengths(base_sq, offset_sq, t), surface.thickening_points(target, offset_positions)


def noisy_drape_with_flat_reference():
    """A strongly bent 15 × 15 drape with 1e-3 noise on its thickening lengths, and the flat
    sheet's thickening as the reference pose: (v, f, target, surface, squared, reference)."""
    v, f = grid(15)
    target = drape(v, 3.0)
    surface, squared, _ = thickening_lengths(v, f, target, noise=1e-3)
    reference = surface.thickening_points(v, surface.positions(v, default_offset(v, f)))
    return v, f, target, surface, squared, reference


def relative_errors(result, target):
    aligned = align_rigidly(result, target)
    diagonal = np.linalg.norm(np.ptp(target, axis=0))
    error = np.linalg.norm(aligned - target, axis=1)
    return np.sqrt(np.mean(error**2)) / diagonal, error.max() / diagonal


def assert_exact(base, triangles, target, **kwargs):
    surface, squared, _ = thickening_lengths(base, triangles, target, **kwargs)
    result = embed_thickening(surface, squared)
    rms, worst = relative_errors(result.base_vertices, target)
    assert rms <= 1e-6 and worst <= 1e-6, (rms, worst, result)
    assert result.residual <= 1e-8
    assert np.isfinite(result.points).all()
    return result


def fold(vertices, angle):
    """Sharp fold of a unit sheet along x = 0.5 by ``angle`` (radians)."""
    out = vertices.copy()
    right = vertices[:, 0] > 0.5
    x = vertices[right, 0] - 0.5
    out[right, 0] = 0.5 + x * np.cos(angle)
    out[right, 2] = x * np.sin(angle)
    return out


def crumple(vertices, amplitude=0.15, seed=3):
    """A crumpled sheet: smooth random displacement of several frequencies."""
    rng = np.random.default_rng(seed)
    out = vertices.copy()
    for _ in range(6):
        k = rng.normal(scale=6.0, size=(3, 3))
        phase = rng.uniform(0, 2 * np.pi, 3)
        out += amplitude / 3 * np.sin(vertices @ k + phase)
    return out


def dent(vertices, depth=0.6):
    """A sphere pushed in deeply around +z (a strongly dented ball)."""
    out = vertices.copy()
    weight = np.clip(vertices[:, 2], 0, None) ** 3
    out *= (1 - depth * weight)[:, None]
    return out


def bend_sphere(vertices, angle=2.0):
    """The upper half of a sphere rotated progressively about the x-axis (strong bending)."""
    out = vertices.copy()
    theta = angle * np.clip(vertices[:, 2], 0, None)
    c, s = np.cos(theta), np.sin(theta)
    out[:, 1], out[:, 2] = c * vertices[:, 1] - s * vertices[:, 2], s * vertices[:, 1] + c * vertices[:, 2]
    return out * np.array([1.0, 1.3, 0.8])


# -- rigid alignment ---------------------------------------------------------------------------


def test_rigid_alignment_recovers_motion_without_reflection():
    rng = np.random.default_rng(0)
    source = rng.normal(size=(50, 3))
    rotation = random_rotation(4)
    target = source @ rotation.T + np.array([1.0, -2.0, 0.5])
    R, t = rigid_alignment(source, target)
    assert np.allclose(R, rotation) and np.allclose(t, [1.0, -2.0, 0.5])
    assert np.isclose(np.linalg.det(R), 1.0)
    mirrored = source * np.array([1, 1, -1])
    R, _ = rigid_alignment(source, mirrored)
    assert np.isclose(np.linalg.det(R), 1.0)


@pytest.mark.parametrize("width", [1e-5, 1e-8])
def test_rigid_alignment_of_a_sliver_recovers_its_turn_about_its_long_side(width):
    """A sliver triangle ``width`` across for a length of 1 (alone, and with a copy of it as two
    groups of one batch), moved rigidly: its rotation comes back to within 100 ε × length / width
    (what its positions tell about the turn about its long side) and its vertices to 1e-9.
    Kabsch alone resolves that turn only to ε × (length / width)², from the cross-covariance:
    the first sliver 1.1e-6 off at 1e-5 across, 1.2e-2 at 1e-8."""
    from core.rigid_alignment import rigid_alignments

    rng = np.random.default_rng(0)
    rotation = random_rotation(7)
    tolerance = 100 * np.finfo(float).eps / width
    for _ in range(20):
        c, d = rng.uniform(-2.0, 2.0, 3), rng.standard_normal(3)
        d /= np.linalg.norm(d)
        side = np.cross(d, rng.standard_normal(3))
        side /= np.linalg.norm(side)
        sliver = np.array([c, c + d, c + 0.4 * d + width * side])
        target = sliver @ rotation.T + np.array([0.3, -0.2, 0.1])
        R, t = rigid_alignment(sliver, target)
        assert np.abs(R - rotation).max() < tolerance, np.abs(R - rotation).max()
        assert np.abs(sliver @ R.T + t - target).max() < 1e-9
        two = np.vstack([sliver, sliver + 5.0])  # two groups at once (the batched path)
        rotations, _ = rigid_alignments(two, two @ rotation.T, np.repeat([0, 1], 3), 2, np.ones(6))
        assert np.abs(rotations - rotation).max() < tolerance, np.abs(rotations - rotation).max()


def test_rigid_alignment_weighted_and_errors():
    rng = np.random.default_rng(1)
    source = rng.normal(size=(20, 3))
    target = source @ random_rotation(2).T
    target[:5] += 10.0  # outliers with zero weight
    weights = np.ones(20)
    weights[:5] = 0
    aligned = align_rigidly(source, target, weights)
    assert np.allclose(aligned[5:], target[5:])
    with pytest.raises(ShapeDifferenceError):
        rigid_alignment(source, target[:3])
    with pytest.raises(ShapeDifferenceError):
        rigid_alignment(source, target, -weights)


# -- exact embedding (full basis) ----------------------------------------------------------------


def test_flat_sheet():
    v, f = grid(12)
    assert_exact(v, f, v)


def test_sheet_draped_around_cylinder():
    v, f = grid(20)
    assert_exact(v, f, drape(v, 4.0) @ random_rotation(1).T)


def test_sheet_with_sharp_fold():
    v, f = grid(17)  # fold line x = 0.5 runs along mesh edges
    assert_exact(v, f, fold(v, 0.9 * np.pi))  # folded almost flat onto itself
    assert_exact(v, f, fold(v, -0.75 * np.pi))


def test_crumpled_sheet():
    v, f = grid(20, jitter=0.3)
    assert_exact(v, f, crumple(v))


def test_stretched_non_isometric_sheet():
    v, f = grid(15, 10, alternate=False)
    assert_exact(v, f, stretch_and_bend(v))


def test_sphere_bent_and_dented():
    v, f = icosphere(2)
    assert_exact(v, f, bend_sphere(v))
    assert_exact(v, f, dent(v))


def test_cube_inward_and_outward_bump():
    outward, f = cube_with_bump(8, 0.35)
    inward, _ = cube_with_bump(8, -0.35)
    # The two poses are exactly isometric: only the extrinsic layer tells them apart.
    assert_exact(outward, f, inward)
    assert_exact(inward, f, outward)


def test_returns_whole_thickening():
    v, f = grid(8)
    target = drape(v, 2.0)
    surface, squared, points = thickening_lengths(v, f, target)
    result = embed_thickening(surface, squared)
    assert result.points.shape == points.shape
    rms, worst = relative_errors(result.points, points)
    assert worst < 1e-6
    # Upward tetrahedra come out positively oriented.
    tets = surface.thickening_tetrahedra[: surface.centered_triangles.size]
    p = result.points[tets]
    volume = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    assert (volume > 0).all()


def test_disconnected_components_and_loose_vertex():
    v1, f1 = grid(6)
    v2, f2 = icosphere(1)
    loose = np.array([[5.0, 5.0, 5.0]])
    base = np.concatenate([v1, v2 + 3.0, loose])
    triangles = np.concatenate([f1, f2 + len(v1)])
    target = np.concatenate([drape(v1, 2.0), dent(v2) + 3.0, loose])
    surface, squared, _ = thickening_lengths(base, triangles, target)
    result = embed_thickening(surface, squared)
    assert result.components == 2
    n1 = len(v1)
    for rows in (slice(0, n1), slice(n1, n1 + len(v2))):
        rms, worst = relative_errors(result.base_vertices[rows], target[rows])
        assert worst < 1e-6
    assert np.array_equal(result.base_vertices[-1], np.zeros(3))  # loose: no edge, left at 0
    anchored = embed_thickening(surface, squared, anchor=(base, 1e-12))
    assert np.allclose(anchored.base_vertices[-1], loose[0])


def test_warm_start_and_anchor():
    v, f = grid(10)
    target = drape(v, 2.0)
    surface, squared, points = thickening_lengths(v, f, target)
    start = points + 0.01 * np.random.default_rng(0).normal(size=points.shape)
    result = embed_thickening(surface, squared, initial_points=start)
    assert result.initializer == "initial_points"
    assert relative_errors(result.base_vertices, target)[1] < 1e-6
    # A larger first damping (the transfer's, for starts a few percent off) reaches the same fit.
    damped = embed_thickening(surface, squared, initial_points=start, initial_damping=1e-3)
    assert relative_errors(damped.base_vertices, target)[1] < 1e-6
    # A strong anchor pulls towards the anchor positions (scale-aware weight).
    blend = 0.5 * (v + target)
    weak = embed_thickening(surface, squared, anchor=(blend, 1e-6))
    strong = embed_thickening(surface, squared, anchor=(blend, 10.0))
    distance = [np.linalg.norm(r.base_vertices - blend) for r in (weak, strong)]
    assert distance[1] < distance[0]
    assert weak.residual < 1e-3 < strong.residual


# -- inexact lengths -----------------------------------------------------------------------------


@pytest.mark.parametrize("noise", [1e-4, 1e-3])
def test_noisy_lengths_give_bounded_error(noise):
    # As ReferenceShape.embed calls it: the base pose's thickening is the reference start.
    v, f = grid(15)
    target = drape(v, 3.0)
    surface, squared, _ = thickening_lengths(v, f, target, noise=noise)
    reference = surface.thickening_points(v, surface.positions(v, default_offset(v, f)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = embed_thickening(surface, squared, reference_points=reference)
    assert np.isfinite(result.points).all()
    rms, worst = relative_errors(result.base_vertices, target)
    assert rms < 30 * noise and worst < 100 * noise
    assert result.residual < 10 * noise


def test_reference_start_is_raced_against_the_hinge_frames():
    # 1e-3 noise on a strongly bent 15 × 15 drape: the noisy hinge signs fold the frames
    # (error 8.5 % of the diagonal when they are the only start); the flat base pose, raced as a
    # second start, reaches the least-squares fit.
    v, f, target, surface, squared, reference = noisy_drape_with_flat_reference()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = embed_thickening(surface, squared, reference_points=reference)
    assert result.initializer == "reference_points"
    rms, worst = relative_errors(result.base_vertices, target)
    assert rms < 1e-3 and worst < 3e-3 and result.residual < 1e-3
    with pytest.raises(RecoveryError, match="reference_points"):
        embed_thickening(surface, squared, reference_points=reference[:-1])


def test_raced_starts_give_the_same_fit_in_threads_as_one_after_the_other(monkeypatch, own_pool):
    # The starts (hinge frames, reference pose) and the continuation schedules are fitted side
    # by side when there are two cores; the chosen fit must not depend on it, bit for bit.
    import core.concurrency as concurrency
    import core.embedding as em

    v, f, target, surface, squared, reference = noisy_drape_with_flat_reference()
    monkeypatch.setattr(em, "CONTINUATION_RESIDUAL", 0.0)  # make the continuations run too
    results = []
    for cores in (2, 1):
        monkeypatch.setattr(concurrency, "available_cores", lambda cores=cores: cores)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            results.append(embed_thickening(surface, squared, reference_points=reference))
    assert results[0].initializer == results[1].initializer
    # the same fit, to round-off (NumPy's and OpenBLAS's kernels may sum in an order that
    # depends on memory alignment on AVX-512 machines)
    np.testing.assert_allclose(results[0].points, results[1].points, rtol=0, atol=1e-9)



def test_a_larger_stagnation_stops_the_same_fit_earlier():
    # Unrealizable lengths (1e-2 noise) from a start away from the fit: Levenberg–Marquardt's
    # trajectory does not depend on the stagnation threshold, only where it stops, so a looser
    # one (the transfer's) stops at an earlier iterate of the same fit: no more iterations, no
    # lower residual, and still far below the start's.
    v, f = grid(12)
    target = drape(v, 2.0)
    surface, squared, points = thickening_lengths(v, f, target, noise=1e-2)
    start = points + 0.05 * np.random.default_rng(1).normal(size=points.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tight, loose = (embed_thickening(surface, squared, initial_points=start, initial_damping=1e-3,
                                         stagnation=s) for s in (1e-4, 1e-2))
    assert loose.iterations < tight.iterations
    assert tight.residual <= loose.residual < 0.5 * loose.initial_residual

def test_an_unconverged_fit_warns_once():
    v, f, target, surface, squared, reference = noisy_drape_with_flat_reference()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        embed_thickening(surface, squared, reference_points=reference, max_iterations=1)
    unconverged = [w for w in caught if issubclass(w.category, ShapeDifferenceWarning)
                   and "without converging" in str(w.message)]
    assert len(unconverged) == 1, [str(w.message) for w in caught]
    with pytest.warns(ShapeDifferenceWarning, match="without converging"):
        topology = mesh_topology(f, len(v))
        embed_base_edges(topology, topology.squared_edge_lengths(target), initial_vertices=v, max_iterations=1)


def test_continuation_deforms_the_reference_into_the_target():
    # The fallback start for fits that stay far from their lengths: a flat sheet deformed in
    # steps into a drape rolled by 5 rad (one full turn would close it), then fitted to the end.
    v, f = grid(15)
    target = drape(v, 5.0)
    surface, squared, _ = thickening_lengths(v, f, target)
    flat = surface.thickening_points(v, surface.positions(v, default_offset(v, f)))
    free = np.ones(len(flat), dtype=bool)
    scale = float(np.mean(np.sqrt(squared)))
    problem = EdgeLengthFit(surface.thickening_edges, squared, free, None, 0.0, scale, 1e-10)
    fractions, iterations = CONTINUATION_SCHEDULES[0]
    steps = problem.continuation(flat, fractions, iterations)
    halfway = np.linalg.norm(steps[: len(v)] - align_rigidly(target, steps[: len(v)]), axis=1).max()
    assert 0 < halfway < np.linalg.norm(v - align_rigidly(target, v), axis=1).max()
    result = embed_thickening(surface, squared, initial_points=steps)
    rms, worst = relative_errors(result.base_vertices, target)
    assert rms < 1e-6 and worst < 1e-5 and result.residual < 1e-8


def test_one_percent_noise_on_a_crumpled_sheet_averages_out():
    # Independent 1 % noise on every squared length: the frames are fitted to all hinges at
    # once (synchronized), so the error stays well below the noise instead of growing along
    # chains of hinges (chained frames + polish: 1.5 % RMS on this sheet).
    v, f = grid(33, jitter=0.3)
    target = crumple(drape(v, 2.0), 0.05)
    surface, squared, _ = thickening_lengths(v, f, target, noise=1e-2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = embed_thickening(surface, squared)
    rms, worst = relative_errors(result.base_vertices, target)
    assert rms < 2e-3 and worst < 1e-2, (rms, worst)
    assert result.residual < 5e-3


def test_noisy_sphere():
    v, f = icosphere(2)
    target = dent(v)
    surface, squared, _ = thickening_lengths(v, f, target, noise=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = embed_thickening(surface, squared)
    rms, _ = relative_errors(result.base_vertices, target)
    assert np.isfinite(result.points).all() and rms < 3e-2


def test_invalid_lengths_raise():
    v, f = grid(5)
    surface, squared, _ = thickening_lengths(v, f, v)
    bad = squared.copy()
    bad[3] = -1.0
    with pytest.raises(RecoveryError, match="squared edge length 3"):
        embed_thickening(surface, bad)
    bad[3] = np.nan
    with pytest.raises(RecoveryError):
        embed_thickening(surface, bad)
    with pytest.raises(RecoveryError):
        embed_thickening(surface, squared[:-1])


# -- intrinsic-only embedding --------------------------------------------------------------------


def test_embed_base_edges_fits_lengths():
    v, f = grid(10)
    topology = mesh_topology(f, len(v))
    target = stretch_and_bend(v)
    start = target + 0.01 * np.random.default_rng(0).normal(size=v.shape)
    result = embed_base_edges(topology, topology.squared_edge_lengths(target), initial_vertices=start)
    assert result.residual < 1e-6
    assert result.base_vertices.shape == v.shape


def test_refine_edge_lengths_moves_free_vertices_towards_the_lengths():
    v, f = grid(10)
    topology = mesh_topology(f, len(v))
    target = stretch_and_bend(v)
    start = target + 0.01 * np.random.default_rng(1).normal(size=v.shape)
    fixed = np.zeros(len(v), dtype=bool)
    fixed[:10] = True
    start[fixed] = target[fixed]
    squared = topology.squared_edge_lengths(target)
    x = refine_edge_lengths(start, topology.edges, squared, anchor_weight=1e-4, max_iterations=10, fixed=fixed)

    def misfit(y):
        return np.sqrt(np.mean((topology.squared_edge_lengths(y) / squared - 1.0) ** 2))

    assert misfit(x) < 0.1 * misfit(start)
    np.testing.assert_array_equal(x[fixed], start[fixed])


def test_larger_crumpled_sheet_stays_exact():
    # Gluing frames along a tree of hinges adds round-off only linearly with the tree depth, so a
    # larger crumpled sheet is exact without any polish.
    v, f = grid(60)
    result = assert_exact(v, f, crumple(drape(v, 3.0), 0.05))
    assert result.initializer == "hinge_frames" and result.iterations == 0
    assert result.residual <= 1e-11


@pytest.mark.parametrize("angle", [2.0, 2.6, -2.6])
def test_hinge_signs_are_voted_where_mesh_edge_tetrahedra_invert(angle):
    # Folds this sharp invert the mesh-edge tetrahedra along the fold line: the sign of those
    # hinges cannot be assumed and must come from the lifted vertices of the stars around them.
    v, f = grid(17, jitter=0.3)
    target = fold(v, angle)
    surface, squared, points = thickening_lengths(v, f, target)
    upward, interior = surface.centered_triangles.size, surface.base.interior_edges.size
    p = points[surface.thickening_tetrahedra[upward: upward + interior]]
    volumes = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    assert (volumes < 0).sum() >= 10
    result = assert_exact(v, f, target)
    assert result.initializer == "hinge_frames" and result.iterations == 0 and result.unresolved_choices == 0


def delaunay_disk(n: int = 400, seed: int = 0):
    """An irregular triangulation of the unit disk (valences 3–12), counter-clockwise from +z."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    points = rng.uniform(-1, 1, (3 * n, 2))
    points = points[np.linalg.norm(points, axis=1) < 1][:n]
    triangles = Delaunay(points).simplices
    vertices = np.c_[points, np.zeros(len(points))]
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    clockwise = np.cross(b - a, c - a)[:, 2] < 0
    triangles[clockwise] = triangles[clockwise][:, [0, 2, 1]]
    return vertices, triangles


def test_irregular_triangulation_with_high_valence_stars():
    v, f = delaunay_disk()
    valence = np.bincount(f.ravel())
    assert valence.max() >= 9  # stars whose 2^k sign patterns are enumerated in one batch
    x, y = v[:, 0], v[:, 1]
    bent = np.stack([np.sin(2.5 * x) / 2.5, y, (1 - np.cos(2.5 * x)) / 2.5 + 0.2 * np.sin(3 * y)], axis=1)
    result = assert_exact(v, f, bent)
    assert result.initializer == "hinge_frames"
