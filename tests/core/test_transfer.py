"""Poses of a differently meshed target rebuilt on the base mesh (core.transfer, paper Fig. 15)."""

import re
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


def _fanned_sheet(n, block):
    """An ``n × n`` grid's vertices with every ``block × block`` cells made one polygon and
    triangulated as a fan from its corner, as Limited Dissolve and an n-gon triangulation leave a
    curved surface: slivers along each polygon's sides (its interior grid vertices loose)."""
    vertices, _ = grid(n)
    triangles = []
    for j in range(0, n - 1, block):
        for i in range(0, n - 1, block):
            ring = ([(j, i + k) for k in range(block)] + [(j + k, i + block) for k in range(block)]
                    + [(j + block, i + block - k) for k in range(block)] + [(j + block - k, i) for k in range(block)])
            ids = [y * n + x for y, x in ring]
            triangles += [[ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1)]
    return vertices, np.array(triangles, dtype=np.int64)


def test_fanned_slivers_of_a_curved_target_are_flipped_away():
    # On a rolled sheet the fans' slivers stand off the surface: their normals are meaningless, and
    # a test of the angle between normals kept them (pose 3.9 % RMS of the diagonal off, 11 % at
    # most). Flipped, the target is the Delaunay triangulation of the same surface, so the pose is as
    # accurate as from a regular triangulation of the sheet (the truncation's error).
    def rolled(v, radius):
        angle = v[:, 0] / radius
        return np.column_stack([radius * np.sin(angle), v[:, 1], radius * (1 - np.cos(angle))])

    base, base_tris = grid(13, jitter=0.3)
    errors = []
    for target, target_tris in (grid(25), _fanned_sheet(25, 2)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            transfer = Transfer(rolled(base, 0.5), base_tris, rolled(target, 0.5), target_tris, k_M=16, k_N=32)
            pose = transfer.pose(rolled(target, 0.3))
        truth = rolled(base, 0.3)
        errors.append(np.linalg.norm(align_rigidly(pose, truth) - truth, axis=1).max())
    assert errors[1] <= 2 * errors[0], errors


def test_a_target_in_other_units_is_rebuilt_at_its_size(sheets, monkeypatch):
    # Shape differences carry the target's size (areas × size²); at 1 % of the base's size they
    # were past the recovery's area floor and the pose came out several times too large, and 5 %
    # larger the pose was twice as far off. Rebuilt at the base's size and scaled, the pose scales
    # with the target (to round-off, through the iterative solvers): the same pose as the target at
    # the base's size rebuilt at the size measured for it (0.3 % off 1 through this map).
    base, base_tris, target, target_tris = sheets
    vertex_map = core.transfer.closest_point_correspondence(base, target)
    poses = {}
    for size in (1.0, 1.05, 0.01, 100.0):
        with warnings.catch_warnings(), monkeypatch.context() as patch:
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            if size == 1.0:  # the size as measured, not taken as the base's
                patch.setattr(core.transfer, "SIZE_TOLERANCE", 0.0, raising=False)
            transfer = Transfer(base, base_tris, size * target, target_tris, correspondence=vertex_map, k_M=16, k_N=32)
            poses[size] = transfer.pose(size * drape(target, 1.0)) / size
    for size, pose in poses.items():
        assert np.abs(pose - poses[1.0]).max() <= 1e-6, size


def test_a_target_of_the_base_size_is_rebuilt_as_without_scaling(sheets, monkeypatch):
    """Measured through a vertex map, a target of the base's own size is a fraction of a percent
    off 1; within core.transfer.SIZE_TOLERANCE it is taken as 1, so the pose is bit for bit the one
    rebuilt with no size normalization at all (before: rescaled by the measured 1.0034, 1e-3 off)."""
    base, base_tris, target, target_tris = sheets
    vertex_map = core.transfer.closest_point_correspondence(base, target)
    poses, sizes = [], []
    for how in ("measured", "default", "none"):
        with warnings.catch_warnings(), monkeypatch.context() as patch:
            warnings.simplefilter("ignore", ShapeDifferenceWarning)
            if how == "measured":
                patch.setattr(core.transfer, "SIZE_TOLERANCE", 0.0, raising=False)
            elif how == "none":
                patch.setattr(core.transfer, "target_size", lambda *args: 1.0)
            transfer = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=16, k_N=32)
            poses.append(transfer.pose(drape(target, 1.0)))
            sizes.append(transfer.size)
    assert sizes[0] != 1.0 and abs(sizes[0] - 1.0) <= 0.01  # the case in point: within SIZE_TOLERANCE
    assert not np.array_equal(poses[0], poses[2])  # scaling by it changes the pose
    assert sizes[1] == 1.0 and np.array_equal(poses[1], poses[2])


def test_a_part_of_the_base_the_target_does_not_have_is_warned(sheets):
    # A small square floating a third of the sheet's width above it (a hat, a button) that the
    # target does not have: closest points squashed it onto the sheet, silently.
    base, base_tris, target, target_tris = sheets
    patch, patch_tris = grid(3, size=0.2)
    both = np.vstack([base, patch + [0.3, 0.3, 0.3]])
    both_tris = np.vstack([base_tris, patch_tris + len(base)])
    for vertices, triangles, warned in ((both, both_tris, True), (base, base_tris, False)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            Transfer(vertices, triangles, target, target_tris, k_M=12, k_N=24)
        messages = [str(w.message) for w in caught if "connected part(s) of the base" in str(w.message)]
        assert len(messages) == warned, messages
        if warned:
            assert f"the part of vertex {len(base)}, 9 vertices" in messages[0]


def test_a_fold_is_not_flipped_but_a_sliver_standing_on_the_edge_is():
    from core.delaunay_flips import delaunay_flips

    pair = np.array([[0, 1, 2], [1, 0, 3]])
    for dihedral, flipped in ((44.0, True), (46.0, False)):  # two triangles mirrored about their edge
        half = np.radians(dihedral) / 2
        v = np.array([[-1, 0, 0], [1, 0, 0], [0, 0.3 * np.cos(half), 0.3 * np.sin(half)],
                      [0, -0.3 * np.cos(half), 0.3 * np.sin(half)]])
        assert (not np.array_equal(delaunay_flips(v, pair, max_dihedral_degrees=45.0), pair)) == flipped
    # a sliver: corner 2 a hundredth of the edge off it, standing up (its normal 73° from the other's)
    v = np.array([[-1, 0, 0], [1, 0, 0], [0.1, 0.003, 0.01], [0, -0.8, 0]])
    assert not np.array_equal(delaunay_flips(v, pair, max_dihedral_degrees=45.0), pair)


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
        transfer = Transfer(base, base_tris, rest, triangles, k_M=16, k_N=32, use_extrinsic=True)
    # The fin is named; laid on the base it collapses, so the meshing correction is skipped (said).
    messages = [str(w.message) for w in caught if issubclass(w.category, ShapeDifferenceWarning)]
    assert any("1 non-manifold" in m and f"({a}, {b})" in m for m in messages)
    assert any("not corrected for the change of meshing" in m for m in messages)
    # ... by the map, in those terms: the target's own faces have area (before, it advised
    # removing degenerate faces, as for a target that has them)
    collapsed = [m for m in messages if m.startswith("The map collapses 1 of the target's triangles")]
    assert len(collapsed) == 1 and str(len(target)) in collapsed[0]
    assert not any("Remove degenerate faces" in m for m in messages)
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
    # k_N beyond the target's eigenfunctions: refused before any work, in the target's terms (before:
    # a warning that its connectivity could not be laid on the base, then the error at the first
    # pose, advising the full basis, which a transfer refuses)
    n = len(target)
    with pytest.raises(MeshError, match=rf"k_N .* is {n}, but the target mesh has {n} vertices.* Lower it\.$"):
        Transfer(base, base_tris, target, target_tris, k_M=10, k_N=n)
    transfer = Transfer(base, base_tris, target, target_tris, k_M=10, k_N=20, use_extrinsic=False)
    with pytest.raises(MeshError, match="same target mesh"):
        transfer.differences(target[:-1])
    # a remeshed copy placed beside the base: closest points cannot match it (before: a flat sheet
    # with warnings about the recovery); given a map it transfers
    beside = target + [3.0, 0.0, 0.0]
    with pytest.raises(MeshError, match=r"do not overlap at rest: .* \(\d+\.\d of its edge lengths\)"):
        Transfer(base, base_tris, beside, target_tris, k_M=10, k_N=20)
    nearest = np.argmin(np.linalg.norm(base[:, None] - target[None], axis=2), axis=1)
    Transfer(base, base_tris, beside, target_tris, k_M=10, k_N=20, correspondence=nearest)
    # placed half beside: transferred, with the reason its result is distorted (before: only
    # warnings about degenerate faces and k)
    with warnings.catch_warnings(record=True) as caught:  # with those about the distortion it causes
        warnings.simplefilter("always")
        Transfer(base, base_tris, target + [0.5, 0.0, 0.0], target_tris, k_M=10, k_N=20, use_extrinsic=False)
    assert any(re.search(r"\d+ % of the base's vertices .* overlap only in part", str(w.message)) for w in caught)
    # a map onto one vertex (an attribute never filled) or one row: refused (before: the target
    # squashed to that vertex, with warnings about its faces)
    row = np.flatnonzero(np.isclose(target[:, 1], target[:, 1].min()))
    for onto, what in ((np.zeros(len(base), dtype=int), "a point"), (row[np.arange(len(base)) % len(row)], "a line")):
        with pytest.raises(MeshError, match=f"lays the base on {what} of the target"):
            Transfer(base, base_tris, target, target_tris, k_M=10, k_N=20, correspondence=onto)


def test_a_target_whose_rest_pose_welds_into_no_triangle_is_refused_by_its_name(sheets):
    """A target rest pose flattened onto a line (an object scaled to nearly 0 along an axis, laid
    in the world) has every vertex coincide with others there: welding them leaves no triangle.
    Refused as a mesh without area, naming the pose as the caller does (it raised NumPy's "zero-size
    array to reduction operation" from the weld's orientation step)."""
    base, base_tris = sheets[:2]
    target, target_tris = grid(12)  # rows of vertices at one height: each row welds into one vertex
    with pytest.raises(MeshError, match=r"^target rest vertices: every triangle has zero area"):
        Transfer(base, base_tris, target * [1e-20, 1.0, 1.0], target_tris, k_M=10, k_N=20)
    jittered, jittered_tris = sheets[2:]  # welds no row: its triangles are measured and have no area
    for flattened, triangles in ((target * [1e-20, 1.0, 1.0], target_tris), (jittered * [1e-20, 1.0, 1.0], jittered_tris)):
        with pytest.raises(MeshError, match=r"^the rest pose of 'Cloth': every triangle has zero area"):
            Transfer(base, base_tris, flattened, triangles, k_M=10, k_N=20, target_name="the rest pose of 'Cloth'")


def test_a_target_with_a_hole_where_the_base_is_closed_is_warned(sheets):
    """A closed sphere's target at rest is the sphere, meshed otherwise, with a cap of 5 % of its
    area cut out: closest points lay the base over the cap on its rim, and the transfer says so with
    the share of the base's area there (at most the cap's; before, silent: the overlap check counts
    only base vertices more than two target edges off). A given correspondence (each base vertex's
    nearest target vertex, as a map made without the hole in mind; or unmatched over the hole, as a
    template map leaves it) lays them on the rim as well and is warned the same way (before,
    silent). The whole sphere, and two sheets with one boundary meshed differently, are not warned,
    with or without a map."""
    from scipy.spatial import cKDTree

    from meshes import icosphere, random_rotation

    base, base_tris = icosphere(3)
    target, target_tris = icosphere(3)
    target = target @ random_rotation(2).T  # other vertices on the same sphere
    cap = 0.05  # a cap of height h has area 2πh: a share h / 2 of the sphere's
    kept = target_tris[target[target_tris].mean(axis=1)[:, 2] < 1 - 2 * cap]
    used = np.unique(kept)  # the holed target's vertices: the map points to none of the cap's
    nearest = used[cKDTree(target[used]).query(base)[1]]
    unmatched = np.where(base[:, 2] < 1 - 2 * cap, nearest, -1)
    pattern = r"(\d+\.\d) % of the base's area \(\d+ vertices\) lies over a hole in the target"
    sheet_map = core.transfer.closest_point_correspondence(sheets[0], sheets[2])
    cases = (((base, base_tris, target, target_tris), None, False),
             ((base, base_tris, target, target_tris), cKDTree(target).query(base)[1], False),
             ((base, base_tris, target, kept), None, True), ((base, base_tris, target, kept), nearest, True),
             ((base, base_tris, target, kept), unmatched, True), (sheets, None, False), (sheets, sheet_map, False))
    for meshes, correspondence, warned in cases:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            Transfer(*meshes, correspondence=correspondence, k_M=10, k_N=20, use_extrinsic=False)
        shares = [float(m.group(1)) for w in caught if (m := re.search(pattern, str(w.message)))]
        assert bool(shares) == warned, correspondence
        if warned:
            assert 0 < shares[0] <= 100 * cap


#: The warning of meshes not laid on each other at rest: the share of the base's area and the farthest distance.
OFF_SURFACE = (r"(\d+\.\d) % of the base's area \(\d+ vertices\) lies off the target's surface at rest, more than a "
               r"target edge length from it or half of one past its edge \(up to ([\d.e-]+),")


def _off_surface(base, base_tris, target, target_tris, slide):
    """The share of the base's area (%) and the farthest distance the transfer's warning of meshes
    not laid on each other gives for the target slid by ``slide`` along x at rest, or None when it
    does not warn."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Transfer(base, base_tris, target + [slide, 0.0, 0.0], target_tris, k_M=10, k_N=20)
    found = [m for w in caught if (m := re.search(OFF_SURFACE, str(w.message)))]
    assert len(found) <= 1
    return (float(found[0].group(1)), float(found[0].group(2))) if found else None


def test_a_target_slid_against_the_base_is_warned():
    """Closest points of a closed target slid against the base (a sphere moved by 1.7 of its edge
    lengths: less than the two edges the overlap check counts) match the base to other points of
    the target than its own, and the transfer says so: the share of the base's area more than a
    target edge off the target's surface (where that distance exceeds an edge, about 1 − 1 / 1.7
    of the sphere's area) and how far, at most the slide (and the depth of the target's triangles
    under the sphere; before, silent). In place, the same
    target is not warned."""
    from core.transfer_checks import mean_edge_length
    from meshes import icosphere, random_rotation

    base, base_tris = icosphere(3)
    target, target_tris = icosphere(3)
    target = target @ random_rotation(2).T
    edge = mean_edge_length(target, mesh_topology(target_tris, len(target)).edges)
    assert _off_surface(base, base_tris, target, target_tris, 0.0) is None
    slide = 1.7 * edge
    share, farthest = _off_surface(base, base_tris, target, target_tris, slide)
    assert 0.5 * (1 - 1 / 1.7) <= share / 100 <= 1.5 * (1 - 1 / 1.7)
    assert edge < farthest <= slide + edge ** 2 / 2  # and the target's chords under the sphere


def test_a_sheet_slid_in_its_own_plane_is_warned(sheets):
    """A sheet's target slid in its own plane by less than a target edge lies on the base's surface
    everywhere but past the base's edge (the cloth sheet slid by 0.78 of an edge: 1.66 → 3.04 % of
    the diagonal off; before, silent): closest points squash the base's border strip onto the
    target's rim, and the transfer says so once that edge lies more than half a target edge past
    the target's. The share is the base's column left uncovered (lumped area of its vertices at
    x = 0) and the farthest distance the slide; slid by 0.3 edge (the rounding of two boundaries),
    or in place, the same target is not warned."""
    from core.geometry import lumped_vertex_areas
    from core.mesh_topology import triangle_areas
    from core.transfer_checks import mean_edge_length

    base, base_tris, target, target_tris = sheets
    edge = mean_edge_length(target, mesh_topology(target_tris, len(target)).edges)
    areas = lumped_vertex_areas(base_tris, triangle_areas(base, base_tris), len(base))
    column = 100 * areas[base[:, 0] == 0.0].sum() / areas.sum()
    assert _off_surface(base, base_tris, target, target_tris, 0.0) is None
    assert _off_surface(base, base_tris, target, target_tris, 0.3 * edge) is None
    share, farthest = _off_surface(base, base_tris, target, target_tris, 0.8 * edge)
    assert share == pytest.approx(column, abs=0.05)
    assert farthest == pytest.approx(0.8 * edge, rel=5e-3)


def test_outlying_matches_of_a_given_map_are_left_out(sheets):
    """A vertex map with 3 of its 100 entries sent to random far target vertices (stray matches,
    as a map file or a functional map's conversion holds): those matches are found — no other —
    and left out, so every base vertex is laid on the target within a target edge of where the
    clean map lays it (the affine fit of its neighbours), and the pose is as close to the truth as
    the clean map's (before: the stray matches pulled their neighbours' fits across the target,
    silently)."""
    base, base_tris, target, target_tris = sheets
    clean = core.transfer.closest_point_correspondence(base, target)
    rng = np.random.default_rng(1)
    stray = rng.choice(np.flatnonzero(np.linalg.norm(base[:, :2] - 0.5, axis=1) < 0.35), 3, replace=False)
    noisy = clean.copy()
    for i in stray:  # a target vertex over half the sheet away
        noisy[i] = rng.choice(np.flatnonzero(np.linalg.norm(target - base[i], axis=1) > 0.5))
    posed, truth = drape(target, 1.0), drape(base, 1.0)
    images, errors, caught_messages = [], [], []
    for vertex_map in (clean, noisy):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            transfer = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=16, k_N=32)
            errors.append(hausdorff_over_diagonal(align_rigidly(transfer.pose(posed), truth), truth))
        images.append(np.asarray(transfer._pull_back @ target[transfer.target_used]))
        caught_messages.append([str(w.message) for w in caught if "from where their neighbours' matches" in str(w.message)])
    assert not caught_messages[0]
    assert len(caught_messages[1]) == 1 and caught_messages[1][0].startswith("3 of the correspondence's 100 matches")
    assert f"base vertex {min(stray)})" in caught_messages[1][0]
    edge = 1.0 / 11  # the target grid's spacing
    assert np.linalg.norm(images[1] - images[0], axis=1).max() < edge
    unchanged = hausdorff_over_diagonal(align_rigidly(base, truth), truth)
    assert errors[1] < 1.5 * errors[0] and errors[1] < 0.5 * unchanged


def test_a_basis_larger_than_a_coarse_target_resolves_is_warned(limb):
    """k_M base functions through a target of fewer than 3 k_M vertices (the 400-vertex limb onto
    a 97-vertex sampling of it) are warned, with the k_M the target resolves; that k_M is not."""
    from benchmarks import limb_scenes

    base, base_tris = limb[:2]
    target, target_tris = limb_scenes.sampled_capsule(100, seed=1)
    n = len(np.unique(target_tris))
    pattern = rf"k_M is (\d+) base eigenfunctions, but the target mesh has only {n} vertices.*Lower k_M to (\d+) or less"
    advised = []
    for k_M in (40, n // 3):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            Transfer(base, base_tris, target, target_tris, k_M=k_M, k_N=2 * k_M)
        found = [m for w in caught if (m := re.search(pattern, str(w.message)))]
        assert bool(found) == (k_M > n / 3), k_M
        advised += [int(m.group(2)) for m in found]
    assert advised == [n // 3]


def test_a_correspondence_that_turns_the_base_inside_out_is_warned():
    """A nearly symmetric closed blob (a small bump on one side) matched to its re-meshed copy left to
    right (x -> -x), as a functional map of a symmetric shape may: every base triangle lands on the
    target facing inwards, so each transferred pose is the target's surface inside out (signed
    volume -5.1 against +5.2 through the right map; before, silent). The right map, and the
    mirrored map of an open sheet (no inside), are not warned."""
    from scipy.spatial import cKDTree

    from meshes import icosphere, random_rotation

    def blob(p):
        return p * (1 + 0.05 * np.exp(-8 * ((p[:, 0] - 0.7) ** 2 + p[:, 1] ** 2 + (p[:, 2] - 0.5) ** 2)))[:, None]

    base, base_tris = icosphere(3)
    target, target_tris = icosphere(3)
    base, target = blob(base), blob(target @ random_rotation(2).T)  # other vertices on the same blob
    tree = cKDTree(target)
    sheet, sheet_tris, sheet_target, sheet_target_tris = (*grid(10, jitter=0.3), *grid(12, jitter=0.3, seed=3))
    sheet_mirror = cKDTree(sheet_target).query(sheet * [-1, 1, 1] + [1, 0, 0])[1]
    pattern = "turns 1 of 1 closed part"
    for meshes, correspondence, warned in (((base, base_tris, target, target_tris), tree.query(base)[1], False),
                                           ((base, base_tris, target, target_tris), tree.query(base * [-1, 1, 1])[1], True),
                                           ((sheet, sheet_tris, sheet_target, sheet_target_tris), sheet_mirror, False)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            transfer = Transfer(*meshes, correspondence=correspondence, k_M=10, k_N=20, use_extrinsic=False)
        assert any(pattern in str(w.message) for w in caught) == warned
        if warned:  # what it warns of: the base's triangles facing inwards on the target
            carried = transfer._pull_back @ meshes[2]
            corners = carried[meshes[1]] - carried.mean(axis=0)
            assert np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])).sum() < 0


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
    # Both fit their lengths from the target carried through the map; only the recovery's start
    # differs (the previous pose's solution, within its tolerance). The fit converges (it has no
    # early stop to keep it at its start), so it carries those differences along the bending the
    # lengths barely constrain (0.37 × the error here): closer than either is to the truth.
    assert np.abs(rebuilt - cold).max() < error * diagonal


def test_a_jump_in_the_sequence_is_fitted_from_the_carried_target(limb):
    """With the offset layer (its thickening embedded from the previous pose when warm), a warm
    transfer fed a pose far from the previous one (a jump, not the next frame) does not start from
    the previous pose: its embedding comes from the target carried through the map, and the pose
    is rebuilt within the judged bounds."""
    from benchmarks import limb_scenes

    base, base_tris, target, target_tris, vertex_map = limb
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        transfer = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40, k_N=80,
                            use_extrinsic=True)
        transfer.pose(limb_scenes.pose(target, 0.1))
        previous = transfer._last_embedding
        rebuilt = transfer.pose(limb_scenes.pose(target, 0.7))
        first = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40,
                         k_N=80, use_extrinsic=True).pose(limb_scenes.pose(target, 0.7))
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


def test_intrinsic_transfer_fits_the_recovered_lengths_from_the_carried_target(limb):
    """By default only the intrinsic pair is transferred: no offset layer on either side, and each
    pose is the base mesh fitted to the recovered edge lengths from the target pose carried through
    the map, stopped once its residual reaches core.transfer.INTRINSIC_EMBEDDING_TOLERANCE (far
    below the carried pose's, which holds the map's and the change of mesh's errors), within the
    judged bounds."""
    from core.edge_length_fit import relative_residuals, rms

    from benchmarks import limb_scenes

    base, base_tris, target, target_tris, vertex_map = limb
    posed = limb_scenes.pose(target, 0.7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        transfer = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40, k_N=80)
        assert not transfer.reference.use_extrinsic and len(transfer.layers) == 1
        rebuilt = transfer.pose(posed)
    ref = transfer.reference
    metric = ref.recover_metric(transfer.differences(posed), tolerance=core.transfer.RECOVERY_TOLERANCE,
                                rho_scale=core.transfer.RECOVERY_RHO_SCALE)
    carried = np.asarray(transfer._pull_back @ transfer._target_positions(posed))
    edges, squared = ref.topology.edges, metric.base.squared_lengths
    fit = transfer._last_embedding
    assert fit.initializer == "initial_points"
    residual = rms(relative_residuals(rebuilt[ref.used_vertices], edges, squared))
    carried_residual = rms(relative_residuals(carried, edges, squared))
    assert residual <= core.transfer.INTRINSIC_EMBEDDING_TOLERANCE < 0.2 * carried_residual
    error, unchanged, _ = limb_errors(rebuilt, base, 0.7)
    assert error < 0.05 and error < 0.5 * unchanged


def test_a_tangled_carried_pose_is_refitted_from_its_projection(limb):
    """A carried pose tangled at the scale of edges (as a sparse map's extrapolated vertices can
    be) stops the intrinsic fit far short of the lengths; the transfer then also fits the carried
    pose's projection on the base's k_M functions, which is smooth, and keeps the lower residual —
    here one that reaches the stopping tolerance."""
    import core.transfer as transfer_module
    from benchmarks import limb_scenes

    base, base_tris, target, target_tris, vertex_map = limb
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        transfer = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=40, k_N=80)
    ref = transfer.reference
    posed = limb_scenes.pose(base, 0.3)[ref.used_vertices]
    metric = ref.pose_metric(posed)  # lengths that some pose realizes exactly
    edge = np.sqrt(metric.base.squared_lengths).mean()
    rng = np.random.default_rng(0)
    offsets = 2.0 * edge * rng.normal(size=posed.shape)  # a fifth of the vertices, ~2 edges away
    tangled = posed + offsets * (rng.random(len(posed)) < 0.2)[:, None]
    tolerance = transfer_module.INTRINSIC_EMBEDDING_TOLERANCE
    alone = ref.embed_result(metric, initial=tangled, initial_damping=transfer_module.EMBEDDING_DAMPING,
                             stagnation=transfer_module.EMBEDDING_STAGNATION, tolerance=tolerance)
    assert alone.residual > 10 * tolerance  # stuck: the case the refit is for
    assert transfer._embed(metric, tangled).residual <= tolerance


def test_offset_surface_basis_of_the_carried_rest_starts_from_the_mesh_basis(sheets, monkeypatch):
    """Preparation solves one eigenproblem from scratch (the target mesh's); the target offset
    surface's eigenbasis starts from it, lifted, and agrees with a direct eigensolve of that
    surface: the same eigenvalues (Rayleigh quotients) within the warm solver's residual test."""
    import core.transfer_layers as layers_module
    from core.inner_products import pose_products
    from core.laplace_basis import laplace_basis

    base, base_tris, target, target_tris = sheets
    cold = []
    monkeypatch.setattr(layers_module, "laplace_basis",
                        lambda *args, **kwargs: cold.append(kwargs.get("what")) or laplace_basis(*args, **kwargs))
    k = 32
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        transfer = Transfer(base, base_tris, target, target_tris, k_M=16, k_N=k, use_extrinsic=True)
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
    assert np.abs(quotients - exact).max() <= layers_module.WARM_RESIDUAL * exact[-1]


def test_partial_map_fills_unmatched_vertices_from_matched_neighbours(sheets):
    """A map that matches only 60 % of the base vertices (random; the others -1, as a composition
    of template maps leaves them) still locates every base vertex on the target — within a target
    edge of where the full map puts it (the affine fit is exact for maps affine over the ring) —
    and the pose is rebuilt within twice the full map's error (and half the unchanged base's)."""
    base, base_tris, target, target_tris = sheets
    full = core.transfer.closest_point_correspondence(base, target)
    partial = full.copy()
    partial[np.random.default_rng(4).random(len(base)) >= 0.6] = -1
    posed = drape(target, 1.0)
    truth = drape(base, 1.0)
    errors, images = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        for vertex_map in (full, partial):
            transfer = Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=16, k_N=32)
            images.append(np.asarray(transfer._pull_back @ target[transfer.target_used]))
            errors.append(hausdorff_over_diagonal(align_rigidly(transfer.pose(posed), truth), truth))
    edge = 1.0 / 11  # the target grid's spacing
    assert np.linalg.norm(images[1] - images[0], axis=1).max() < edge
    unchanged = hausdorff_over_diagonal(align_rigidly(base, truth), truth)
    assert errors[1] < 2 * errors[0] and errors[1] < 0.5 * unchanged


def test_partial_maps_that_cannot_work_are_refused(sheets):
    base, base_tris, target, target_tris = sheets
    vertex_map = np.full(len(base), -1)
    vertex_map[:5] = core.transfer.closest_point_correspondence(base[:5], target)
    with pytest.raises(MeshError, match=r"matches only 5 % of the base vertices .* at least 10 %"):
        Transfer(base, base_tris, target, target_tris, correspondence=vertex_map, k_M=10, k_N=20)
    with pytest.raises(MeshError, match="or -1 for an unmatched base vertex"):
        Transfer(base, base_tris, target, target_tris, correspondence=np.full(len(base), -2), k_M=10, k_N=20)
    # A second sheet of the base that the map does not reach at all.
    two = np.vstack([base, base + [2.0, 0.0, 0.0]])
    two_tris = np.vstack([base_tris, base_tris + len(base)])
    vertex_map = np.concatenate([core.transfer.closest_point_correspondence(base, target), np.full(len(base), -1)])
    with pytest.raises(MeshError, match=rf"Base vertex {len(base)} is in a part of the base mesh where the map matches no"):
        Transfer(two, two_tris, target, target_tris, correspondence=vertex_map, k_M=10, k_N=20)


def test_template_maps_compose_to_the_direct_map(tmp_path):
    """Two .vts-style template maps (1-based) compose to the base → target map they encode; base
    vertices no template vertex lands on are unmatched; files are read and errors are named."""
    rng = np.random.default_rng(2)
    n_base, n_target = 50, 70
    direct = rng.integers(0, n_target, n_base)
    landing = rng.permutation(n_base)[:40]  # template vertex i lands on base vertex landing[i]
    landing = np.concatenate([landing, landing[:3]])  # three base vertices hit twice
    base_vts, target_vts = landing + 1, direct[landing] + 1
    target_vts[-3:] = 1  # the second landing disagrees: the first template vertex wins
    composed = core.template_correspondence(base_vts, target_vts, n_base, n_target)
    hit = np.zeros(n_base, bool)
    hit[landing] = True
    assert np.array_equal(composed[hit], direct[hit]) and np.all(composed[~hit] == -1)
    np.savetxt(tmp_path / "base.vts", base_vts, fmt="%d")
    np.savetxt(tmp_path / "target.vts", target_vts.astype(float))  # 1.000000000000000000e+00 style
    read = [core.read_vertex_map(tmp_path / name) for name in ("base.vts", "target.vts")]
    assert np.array_equal(core.template_correspondence(*read, n_base, n_target), composed)
    with pytest.raises(MeshError, match="different lengths"):
        core.template_correspondence(base_vts[:-1], target_vts, n_base)
    zero_based = base_vts - 1
    zero_based[0] = 0
    with pytest.raises(MeshError, match=r"Entry 0 of the base's template map is 0, but 1-based indices .* run "
                                        r"from 1 to 50.*map is 0-based"):
        core.template_correspondence(zero_based, target_vts, n_base)
    with pytest.raises(MeshError, match=r"run from 1 to 70"):
        core.template_correspondence(base_vts, target_vts + n_target, n_base, n_target)
    (tmp_path / "bad.vts").write_text("1\n2.5\n")
    with pytest.raises(MeshError, match="not a whole vertex index"):
        core.read_vertex_map(tmp_path / "bad.vts")
    with pytest.raises(MeshError, match="does not exist"):
        core.read_vertex_map(tmp_path / "missing.vts")
    # a whole number beyond int64 (it was cast to -2**63, silently; composed: 2**63 − 1)
    (tmp_path / "huge.vts").write_text("1\n2\n1e20\n")
    with pytest.raises(MeshError, match=r"holds 1e\+20 at entry 2, beyond any vertex index"):
        core.read_vertex_map(tmp_path / "huge.vts")
    with pytest.raises(MeshError, match=r"target's template map holds 1e\+20 at entry 2"):
        core.template_correspondence([1, 2, 3], [1.0, 2.0, 1e20], 5)


def test_split_seams_slivers_and_loose_target_vertices(sheets):
    """A target as exporters and decimators leave it — a seam of coincident duplicated vertices,
    a zero-area sliver, a loose vertex the map points to — gives the same differences as the
    clean target (duplicates welded, the sliver left out, the loose match treated as unmatched),
    with warnings for what was dropped."""
    base, base_tris, target, target_tris = sheets
    vertex_map = core.transfer.closest_point_correspondence(base, target)
    n = len(target)
    seam = np.arange(14, 22)  # interior vertices of the second row, duplicated
    copies = n + np.arange(seam.size)
    tris = target_tris.copy()
    # Triangles above the row use the copies: the seam splits the sheet along the row.
    upper = np.isin(tris, seam).any(axis=1) & (target[tris][:, :, 1].mean(axis=1) > target[seam, 1].mean())
    for s, c in zip(seam, copies):
        tris[upper] = np.where(tris[upper] == s, c, tris[upper])
    sliver = [[0, 1, 2]]  # three collinear vertices of the bottom side: zero area
    hostile = np.vstack([target, target[seam], [[0.5, 0.5, 0.0]]])
    hostile_map = vertex_map.copy()
    hostile_map[0] = n + seam.size  # the loose vertex
    posed = drape(target, 1.0)
    hostile_posed = np.vstack([posed, posed[seam], [[0.5, 0.5, 0.0]]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dirty = Transfer(base, base_tris, hostile, np.vstack([tris, sliver]), correspondence=hostile_map,
                         k_M=16, k_N=32, use_extrinsic=False).differences(hostile_posed)
    messages = " ".join(str(w.message) for w in caught)
    assert "1 triangle(s) of zero area" in messages and "treated as unmatched" in messages
    clean_map = vertex_map.copy()
    clean_map[0] = -1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ShapeDifferenceWarning)
        clean = Transfer(base, base_tris, target, target_tris, correspondence=clean_map, k_M=16, k_N=32,
                         use_extrinsic=False).differences(posed)
    for name in ("area", "conformal"):
        a, b = getattr(clean, name).matrix, getattr(dirty, name).matrix
        assert np.allclose(a, b, atol=1e-9 * np.abs(a).max()), name


def _turn(angle):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


@pytest.mark.parametrize("sizes", [(16, 21), (16, 18)])
def test_a_transfer_between_symmetric_meshes_does_not_depend_on_rounding(sizes, monkeypatch):
    # An icosphere rebuilt on a finer one, at a k_M that ends a group of equal eigenvalues: a
    # 1e-9 rad turn, other units, or the target's vertices numbered otherwise change the inputs by
    # rounding only. With the recovery's solvers run to 1e-9 (relative), the pose is then the same
    # to what those solvers leave (measured 1e-10–1e-8 of the diagonal). Preimages of target
    # vertices above the base's inner edges extrapolated from whichever triangle rounding picks, or
    # a target basis warm-started from an eigensolver's arbitrary part of an eigenspace, move it
    # by 1.7e-3–4.4e-3.
    from meshes import icosphere, stretch_and_bend

    monkeypatch.setattr(core.transfer, "RECOVERY_TOLERANCE", 1e-9)
    base, base_tris = icosphere(2)
    target, target_tris = icosphere(3)
    pose = stretch_and_bend(target)
    k_M, k_N = sizes
    order = np.random.default_rng(0).permutation(len(target))

    def rebuilt(scale, angle, numbering=None):
        turn = _turn(angle) * scale
        tris, vertices, posed = target_tris, target, pose
        if numbering is not None:
            tris, vertices, posed = np.argsort(numbering)[target_tris], target[numbering], pose[numbering]
        transfer = Transfer(base @ turn.T, base_tris, vertices @ turn.T, tris, k_M=k_M, k_N=k_N)
        return transfer.pose(posed @ turn.T) @ np.linalg.inv(turn).T

    reference = rebuilt(1.0, 0.0)
    diagonal = np.linalg.norm(np.ptp(reference, axis=0))
    for changed in (rebuilt(1.0, 1e-9), rebuilt(1e-3, 0.0), rebuilt(1.0, 0.0, order)):
        assert np.abs(changed - reference).max() <= 1e-7 * diagonal


def test_a_transfer_moves_under_rounding_no_more_than_its_recovery_tolerance():
    # The same at the shipped recovery tolerance: the recovered lengths are only that accurate
    # (relative), so a rounding-size change of the inputs may move the pose by about that much of its
    # size (measured 5e-5 of the diagonal; 7e-4–1.2e-3 with the preimages and start above).
    from meshes import icosphere, stretch_and_bend

    base, base_tris = icosphere(2)
    target, target_tris = icosphere(3)
    pose = stretch_and_bend(target)

    def rebuilt(scale, angle):
        turn = _turn(angle) * scale
        transfer = Transfer(base @ turn.T, base_tris, target @ turn.T, target_tris, k_M=16, k_N=21)
        return transfer.pose(pose @ turn.T) @ np.linalg.inv(turn).T

    reference = rebuilt(1.0, 0.0)
    diagonal = np.linalg.norm(np.ptp(reference, axis=0))
    for changed in (rebuilt(1.0, 1e-9), rebuilt(1e3, 0.0), rebuilt(1e-3, 0.0)):
        assert np.abs(changed - reference).max() <= core.transfer.RECOVERY_TOLERANCE * diagonal


def test_coincident_target_vertices_weld_to_the_lowest_of_their_cluster():
    """Target vertices within the weld distance of each other, chains of them included, are welded
    to the lowest-numbered one, as the components of the full distance matrix say; 3,000 of them at
    one place (a part collapsed to a point) make one cluster, not 4.5 M pairs."""
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial.distance import cdist

    from core.transfer_checks import WELD_DISTANCE, coincident_vertices

    rng = np.random.default_rng(3)
    rest = rng.uniform(0.0, 1.0, (6000, 3))
    rest[::2] = rest[1] + 1e-12 * rng.standard_normal((3000, 3))  # every other vertex at one place
    chain = np.array([5991, 5993, 5995, 5997])
    rest[chain] = rest[5991] + np.outer(np.arange(4), [0.9, 0.0, 0.0]) * WELD_DISTANCE * np.sqrt(3.0)
    used = np.arange(1, 6000)
    points = rest[used]
    reach = WELD_DISTANCE * np.linalg.norm(np.ptp(points, axis=0))
    labels = connected_components(cdist(points, points) <= reach, directed=False)[1]
    lowest = np.full(labels.max() + 1, len(used))
    np.minimum.at(lowest, labels, np.arange(len(used)))
    expected = np.arange(len(rest))
    expected[used] = used[lowest[labels]]
    welded = coincident_vertices(rest, used)
    np.testing.assert_array_equal(welded, expected)
    assert np.all(welded[chain] == 5991)  # a chain 0.9 of the weld distance a step, 2.7 end to end
    assert np.all(welded[2::2] == 1)
    assert coincident_vertices(rng.uniform(0.0, 1.0, (50, 3)), np.arange(50)) is None


def _with_a_sliver_and_a_fin(vertices, triangles):
    """``vertices``, ``triangles`` of an open sheet with a sliver (a vertex halfway along a boundary
    edge, in a triangle of no area along it) and a fin (a triangle on an inner edge, standing up):
    a target a transfer accepts, warning about each."""
    edges = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    # the boundary edge as its triangle runs along it, so that the sliver runs along it the other way
    runs = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    a, b = next(run for run in runs if counts[np.all(unique == np.sort(run), axis=1)][0] == 1)
    u, v = unique[counts == 2][len(unique) // 4]
    n = len(vertices)
    added = [(vertices[a] + vertices[b]) / 2, (vertices[u] + vertices[v]) / 2 + [0.0, 0.0, 0.2]]
    return np.vstack([vertices, added]), np.vstack([triangles, [[b, a, n], [u, v, n + 1]]])


@pytest.mark.parametrize("label", [None, "'Cloth' (the source of the poses)"])
def test_warnings_about_the_target_mesh_name_it_as_the_caller_does(sheets, label):
    """A target with a sliver and a fin, whose resolution is below k_M, is transferred with a
    warning about each, which names it ``target_label`` (the operator: the source object, where "the
    target mesh" read as the active one) or, by default, "the target mesh"."""
    from core.transfer_checks import TARGET_LABEL, sentence

    base, base_tris, target, target_tris = sheets
    target, target_tris = _with_a_sliver_and_a_fin(target, target_tris)
    named = label or TARGET_LABEL
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Transfer(base, base_tris, target, target_tris, k_M=60, k_N=120, use_extrinsic=False,
                 **({} if label is None else {"target_label": label}))
    messages = [str(w.message) for w in caught if issubclass(w.category, ShapeDifferenceWarning)]
    opening = re.escape(sentence(named))
    expected = [rf"^{opening} has 1 triangle\(s\) of zero area at rest \(triangle {len(target_tris) - 2}, ",
                rf"^{opening} has 1 non-manifold or inconsistently oriented edge\(s\) ",
                rf"^k_M is 60 base eigenfunctions, but {re.escape(named)} has only \d+ vertices"]
    for pattern in expected:
        assert any(re.search(pattern, message) for message in messages), (pattern, messages)
    assert TARGET_LABEL == "the target mesh" and (label is None or not any("target mesh" in m for m in messages))
