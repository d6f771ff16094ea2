"""Poses of a differently meshed target rebuilt on the base mesh (core.transfer, paper Fig. 15)."""

import warnings

import numpy as np
import pytest
from meshes import drape, grid

import core
from core.errors import MeshError, ShapeDifferenceWarning
from core.mesh_topology import mesh_topology
from core.rigid_alignment import align_rigidly
from core.transfer import Transfer


def hausdorff_over_diagonal(a, b):
    from scipy.spatial import cKDTree

    d = max(cKDTree(a).query(b)[0].max(), cKDTree(b).query(a)[0].max())
    return d / np.linalg.norm(b.max(0) - b.min(0))


@pytest.fixture(scope="module")
def sheets():
    """A 10 × 10 base and a 12 × 12 target of the same unit square, triangulated differently."""
    base, base_tris = grid(10, jitter=0.3)
    target, target_tris = grid(12, jitter=0.3, seed=3, alternate=False)
    return base, base_tris, target, target_tris


def test_identity_map_gives_the_same_mesh_differences():
    from core.delaunay_flips import delaunay_flips

    v, t = grid(12, jitter=0.3)
    # A Delaunay mesh, which the transfer's flips of the target (core.delaunay_flips) leave as it is.
    t = delaunay_flips(v, t)
    pose = drape(v, 1.5)
    same = core.shape_differences(v, pose, t, k_M=15, k_N=30)
    across = core.shape_differences(v, pose, t, k_M=15, k_N=30, target_triangles=t,
                                    correspondence=np.arange(len(v)), target_rest_vertices=v)
    # Equal up to the target eigenbasis, which after the first pose (the meshing correction's)
    # comes from two warm-started subspace iterations instead of an exact eigensolve.
    for name in ("area", "conformal", "offset_area", "offset_conformal"):
        a, b = getattr(same, name).matrix, getattr(across, name).matrix
        assert np.linalg.norm(a - b) <= 1e-5 * np.linalg.norm(a), name


def test_remeshed_drape_is_rebuilt_on_the_base(sheets):
    base, base_tris, target, target_tris = sheets
    truth = drape(base, 1.0)  # the target's surface, sampled at the base vertices
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        differences = core.shape_differences(base, drape(target, 1.0), base_tris, target_triangles=target_tris,
                                             target_rest_vertices=target, k_M=16, k_N=32)
        rebuilt = core.reconstruct(base, base_tris, differences)
    assert rebuilt.shape == base.shape
    error = hausdorff_over_diagonal(align_rigidly(rebuilt, truth), truth)
    unchanged = hausdorff_over_diagonal(align_rigidly(base, truth), truth)
    assert error < 0.05 and error < 0.5 * unchanged


def test_vertex_map_target_sequence_and_interpolation(sheets):
    base, base_tris, target, target_tris = sheets
    vertex_map = core.transfer.closest_point_correspondence(base, target)
    keys = [target, drape(target, 1.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        sequence = core.SequenceInterpolator(keys, base_tris, base_vertices=base, target_triangles=target_tris,
                                             correspondence=vertex_map, k_M=16, k_N=32)
        end = sequence.pose(0, 1.0)
        middle = sequence.pose(0, 0.5)
    truth = drape(base, 1.0)
    assert hausdorff_over_diagonal(align_rigidly(end, truth), truth) < 0.5 * hausdorff_over_diagonal(
        align_rigidly(base, truth), truth)
    # The first key is the rest pose of the same surface: rebuilt as the base, up to the
    # truncation (the same 5 % bound as for the drape).
    assert hausdorff_over_diagonal(align_rigidly(sequence.pose(0, 0.0), base), base) < 0.05
    assert np.isfinite(middle).all() and len(sequence) == 1 and sequence.triangles.shape == base_tris.shape


def test_target_with_a_non_manifold_edge_still_transfers(sheets):
    base, base_tris, target, target_tris = sheets
    topology = mesh_topology(target_tris, len(target))
    a, b = topology.edges[topology.interior_edges[40]]
    fin_vertex = 0.5 * (target[a] + target[b]) + [0.0, 0.0, 0.05]
    rest = np.vstack([target, fin_vertex])
    triangles = np.vstack([target_tris, [[a, b, len(target)]]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        transfer = Transfer(base, base_tris, rest, triangles, k_M=16, k_N=32)
    # The fin is named; laid on the base it collapses, so the meshing correction is skipped (said).
    messages = [str(w.message) for w in caught if issubclass(w.category, ShapeDifferenceWarning)]
    assert any("1 non-manifold" in m and f"({a}, {b})" in m for m in messages)
    assert any("not corrected for the change of meshing" in m for m in messages)
    differences = transfer.differences(rest)
    assert np.isfinite(differences.offset_conformal.matrix).all()
    # At rest the target is the base surface: its differences are those of the base to itself
    # (the identity), up to the meshing error at the resolution of the coarse sheets, which is
    # small in the lowest frequencies (uncorrected here).
    assert np.allclose(differences.area.matrix[:6, :6], np.eye(6), atol=0.05)


def test_errors_in_the_users_terms(sheets):
    base, base_tris, target, target_tris = sheets
    with pytest.raises(MeshError, match="need truncated bases"):
        core.shape_differences(base, target, base_tris, target_triangles=target_tris)
    with pytest.raises(MeshError, match="out of range"):
        core.shape_differences(base, target, base_tris, target_triangles=target_tris, k_M=10, k_N=20,
                               correspondence=np.full(len(base), len(target)))
    topology = mesh_topology(base_tris, len(base))
    a, b = topology.edges[topology.interior_edges[0]]
    with pytest.raises(MeshError, match=rf"\({a}, {b}\).*Non Manifold"):
        core.shape_differences(np.vstack([base, [[0, 0, 1.0]]]), target, np.vstack([base_tris, [[a, b, len(base)]]]),
                               target_triangles=target_tris, k_M=10, k_N=20)
    transfer = Transfer(base, base_tris, target, target_tris, k_M=10, k_N=20, use_extrinsic=False)
    with pytest.raises(MeshError, match="same target mesh"):
        transfer.differences(target[:-1])


@pytest.fixture(scope="module")
def limb():
    """A closed limb (benchmarks/limb_scenes.py) meshed twice independently (400 / 520 vertices)
    and the vertex map of nearest vertices at rest: (base, base_tris, target, target_tris, map)."""
    from benchmarks import limb_scenes

    base, base_tris = limb_scenes.ring_capsule(400)
    target, target_tris = limb_scenes.sampled_capsule(520, seed=1)
    return base, base_tris, target, target_tris, core.transfer.closest_point_correspondence(base, target)


def limb_errors(rebuilt, base, phase):
    """(Hausdorff / diagonal of ``rebuilt`` and of the unchanged ``base`` to the limb's pose at
    ``phase``, that pose's diagonal)."""
    from benchmarks import limb_scenes

    truth = limb_scenes.pose(base, phase)  # the same deformation of the base's rest vertices
    error = hausdorff_over_diagonal(align_rigidly(rebuilt, truth), truth)
    unchanged = hausdorff_over_diagonal(align_rigidly(base, truth), truth)
    return error, unchanged, np.linalg.norm(np.ptp(truth, axis=0))


def test_articulated_limb_sequence_is_rebuilt_and_warm_starts_do_not_change_it(limb):
    """A closed limb bent and twisted at two joints (benchmarks/limb_scenes.py), re-meshed
    independently, with a vertex map of nearest vertices at rest — like a re-meshed scan
    sequence. Each pose of the sequence is within the judged bounds, and the warm-started
    sequence (recovery and embedding started from the previous pose) gives the pose a cold
    transfer gives: the same programs, only their starts differ."""
    from benchmarks import limb_scenes

    base, base_tris, target, target_tris, vertex_map = limb
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        warm = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40, k_N=80)
        for phase in (0.6, 0.65, 0.7):
            posed = limb_scenes.pose(target, phase)
            rebuilt = warm.pose(posed)
            error, unchanged, diagonal = limb_errors(rebuilt, base, phase)
            assert error < 0.05 and error < 0.5 * unchanged, phase
        cold = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40, k_N=80,
                        warm_start=False).pose(posed)
    # Both fit the same recovered metric and stop early (core.transfer.EMBEDDING_STAGNATION) from
    # different starts — the warm one from the previous pose moved with the target, the cold one
    # from the target carried through the map: they differ far less than either differs from the
    # truth.
    assert np.abs(rebuilt - cold).max() < 0.2 * error * diagonal


def test_a_jump_in_the_sequence_is_fitted_from_the_carried_target(limb):
    """A warm transfer fed a pose far from the previous one (a jump, not the next frame) does not
    start from the previous pose: its embedding comes from the target carried through the map,
    and the pose is rebuilt within the judged bounds."""
    from benchmarks import limb_scenes

    base, base_tris, target, target_tris, vertex_map = limb
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        transfer = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40, k_N=80)
        transfer.pose(limb_scenes.pose(target, 0.1))
        previous = transfer._last_embedding
        rebuilt = transfer.pose(limb_scenes.pose(target, 0.7))
        first = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40,
                         k_N=80).pose(limb_scenes.pose(target, 0.7))
    fitted = transfer._last_embedding
    assert fitted.initializer == "initial_points" and fitted.points is not previous.points
    # The start of the fit kept was one of the carried starts: its length residual is far above
    # the previous pose's (the criterion that skips the warm start).
    assert fitted.initial_residual > core.transfer.WARM_EMBEDDING_GROWTH * previous.residual
    error, unchanged, diagonal = limb_errors(rebuilt, base, 0.7)
    assert error < 0.05 and error < 0.5 * unchanged
    # As a transfer's first pose (the same starts; the recovery's warm start differs within its
    # tolerance).
    assert np.abs(rebuilt - first).max() < 0.2 * error * diagonal


def test_offset_surface_basis_of_the_carried_rest_starts_from_the_mesh_basis(sheets, monkeypatch):
    """Preparation solves one eigenproblem from scratch (the target mesh's); the target offset
    surface's eigenbasis starts from it, lifted, and agrees with a direct eigensolve of that
    surface: the same eigenvalues (Rayleigh quotients) within the warm solver's residual test."""
    import core.transfer as transfer_module
    from core.inner_products import pose_products
    from core.laplace_basis import laplace_basis

    base, base_tris, target, target_tris = sheets
    cold = []
    monkeypatch.setattr(transfer_module, "laplace_basis",
                        lambda *args, **kwargs: cold.append(kwargs.get("what")) or laplace_basis(*args, **kwargs))
    k = 32
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        transfer = Transfer(base, base_tris, target, target_tris, k_M=16, k_N=k)
    assert cold == ["target mesh"]
    ref = transfer.reference
    on_base = np.asarray(transfer.layers[0].push @ ref.base_positions)
    _, _, mass, conformal = pose_products(transfer.layers[1].assembler,
                                          transfer.target_surface.positions(on_base, ref.offset))
    exact = laplace_basis(mass, conformal, k).eigenvalues
    functions = transfer.layers[1]._subspace[1][:, :k]
    quotients = np.einsum("ij,ij->j", functions, conformal @ functions) / np.einsum("ij,ij->j", functions,
                                                                                   mass @ functions)
    # A Ritz value is within its residual of an eigenvalue, which the warm solver bounds by
    # WARM_RESIDUAL × λ_k (Bauer–Fike).
    assert np.abs(quotients - exact).max() <= transfer_module.WARM_RESIDUAL * exact[-1]
