"""Distortion maps: area change, conformal distortion, bending and the difference eigenfunctions."""

import warnings

import numpy as np
import pytest

import core
from core.distortion_maps import DistortionAnalyzer
from meshes import capped_cylinder, grid, icosphere


def bumped(vertices, height, radius=0.3):
    r = np.linalg.norm(vertices[:, :2] - 0.5, axis=1)
    out = vertices.copy()
    out[:, 2] += height * np.where(r < radius, np.cos(0.5 * np.pi * r / radius) ** 2, 0.0)
    return out


@pytest.fixture(scope="module")
def sheet():
    return grid(15, jitter=0.3)


def test_uniform_scaling_changes_areas_only(sheet):
    v, t = sheet
    d = core.distortion(v, 1.5 * v, t)
    assert np.allclose(d.area_change_faces, 2 * np.log(1.5), atol=1e-12)
    assert np.allclose(d.area_change_vertices, 2 * np.log(1.5), atol=1e-12)
    assert np.allclose(d.conformal_faces, 1.0, atol=1e-6)
    # A flat sheet stays flat: its offset surface scales with it, nothing bends.
    assert np.allclose(d.bending_faces, 0.0, atol=1e-9)
    assert np.allclose(d.bending_vertices, 0.0, atol=1e-9)
    values, functions = d.eigenfunctions("area", 3)
    assert np.allclose(values, 1.5**2, rtol=1e-9)
    assert functions.shape == (len(v), 3)


def test_a_stretch_along_x_is_conformal_distortion_two(sheet):
    v, t = sheet
    stretched = v * np.array([2.0, 1.0, 1.0])
    d = core.distortion(v, stretched, t)
    assert np.allclose(d.conformal_faces, 2.0, rtol=1e-9)
    assert np.allclose(d.conformal_vertices, 2.0, rtol=1e-9)
    assert np.allclose(d.area_change_faces, np.log(2.0), atol=1e-12)


@pytest.mark.parametrize("height", [1e-3, 5e-10])
def test_conformal_distortion_of_a_thin_triangle_is_its_singular_value_ratio(height):
    """A triangle whose height is 5e-10 of its base passes the mesh checks; its conformal ratio is
    that of the singular values of its deformation gradient (before: laid out from its squared
    edge lengths it came out flat and the solve raised numpy's LinAlgError)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, height, 0], [0.5, 1, 0], [0.5, -1, 0.0]])
    t = np.array([[0, 1, 2], [0, 2, 3], [2, 1, 3], [0, 4, 1]])
    shear = np.array([[1.0, 0.3, 0.0], [0.0, 1.1, 0.0], [0.0, 0.0, 1.0]])
    pose = v @ shear.T
    d = core.distortion(v, pose, t)
    singular = np.linalg.svd(shear[:2, :2], compute_uv=False)  # the same map on every triangle
    assert np.allclose(d.conformal_faces, singular[0] / singular[1], rtol=1e-6)


def test_mirror_image_bumps_have_the_same_metric_and_opposite_bending(sheet):
    v, t = sheet
    analyzer = DistortionAnalyzer(v, t)
    up, down = analyzer.pose(bumped(v, 0.15)), analyzer.pose(bumped(v, -0.15))
    assert np.allclose(up.area_change_faces, down.area_change_faces, atol=1e-12)
    assert np.allclose(up.conformal_faces, down.conformal_faces, atol=1e-9)
    centre = np.argmin(np.linalg.norm(v[:, :2] - 0.5, axis=1))
    # The offset surface (outside of +z) expands over the top of a bump and shrinks in a dent.
    assert up.bending_vertices[centre] > 0 > down.bending_vertices[centre]
    corner = 0
    assert up.bending_vertices[corner] == pytest.approx(0.0, abs=1e-9)


def test_leading_area_eigenfunction_sits_where_the_pose_grows(sheet):
    v, t = sheet
    pose = v.copy()
    left = v[:, 0] < 0.4
    pose[:, 0] = np.where(left, 1.6 * v[:, 0], 0.64 + (v[:, 0] - 0.4))  # the left part stretches
    values, functions = core.distortion(v, pose, t, k=30).eigenfunctions("area", 1)
    assert values[0] > 1.2
    weight = functions[:, 0] ** 2
    assert weight[left].sum() > 0.8 * weight.sum()


@pytest.mark.parametrize("kind", ["conformal", "offset_area", "offset_conformal"])
def test_every_kind_has_eigenfunctions(kind):
    v, t = icosphere(2)
    pose = v * np.array([1.3, 1.0, 0.8])
    values, functions = core.distortion(v, pose, t, k=25).eigenfunctions(kind, 4)
    assert values.shape == (4,) and functions.shape == (len(v), 4)
    assert np.all(np.isfinite(functions)) and np.allclose(np.abs(functions).max(axis=0), 1.0)
    assert np.all(np.diff(np.abs(np.log(values))) <= 1e-12)


def test_eigenfunction_signs_do_not_depend_on_rounding():
    # The icosphere stretched along its axes: several leading eigenfunctions are odd under a mirror
    # of the pose, their maximum and minus their minimum equal; signed by the largest value, they
    # flip (the whole function changes by 2) under a 1e-9 rad turn or other units of both meshes.
    from meshes import stretch_and_bend

    v, t = icosphere(2)
    pose = stretch_and_bend(v)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    turn = np.eye(3) + np.sin(1e-9) * k + (1 - np.cos(1e-9)) * k @ k

    def functions(transform):
        d = DistortionAnalyzer(v @ transform.T, t, k=25).pose(pose @ transform.T)
        return {kind: d.eigenfunctions(kind, 4)[1] for kind in core.distortion_maps.KINDS}

    reference = functions(np.eye(3))
    for changed in (functions(turn), functions(1e3 * np.eye(3)), functions(1e-3 * np.eye(3))):
        for kind, f in reference.items():
            # the eigenproblem's rounding (measured 6e-14–2e-11); an eigenvalue gap ≥ 1e-3 apart
            assert np.abs(changed[kind] - f).max() <= 1e-9, kind


def test_signed_unit_functions_pick_one_sign_for_both():
    from core.distortion_maps import SIGN_TIE, signed_unit_functions

    rng = np.random.default_rng(4)
    odd = rng.standard_normal(20)
    odd = np.concatenate([[0.0], odd, -odd])  # its cubes cancel: the first value not near zero decides
    lopsided = np.concatenate([[1.0], -0.9 * np.ones(2), np.zeros(38)])  # largest value 1, cubes negative
    functions = np.column_stack([odd, lopsided])
    for scale in (1.0, -1.0, 3.0, -1e-3):
        signed = signed_unit_functions(scale * functions)
        assert np.allclose(np.abs(signed).max(axis=0), 1.0)
        assert np.allclose(signed, signed_unit_functions(functions), rtol=0, atol=1e-15)
    signed = signed_unit_functions(functions)
    assert signed[1, 0] > 0 and abs(np.sum(signed[:, 0] ** 3)) <= SIGN_TIE
    assert np.sum(signed[:, 1] ** 3) > 0 and signed[0, 1] == -1.0


def test_bad_kind_and_pose(sheet):
    v, t = sheet
    with pytest.raises(ValueError, match="kind must be one of"):
        core.distortion(v, v, t).eigenfunctions("volume")
    with pytest.raises(core.MeshError):
        core.distortion(v, v[:-1], t)


def test_a_rigid_copy_in_single_precision_is_round_off():
    """A shape key that only turns and moves its mesh, stored in float32 as Blender stores keys,
    changes edge lengths by the coordinates' rounding (1e-7 to 1e-5, not 0): every map stays
    within its face's ``round_off_faces`` (the operator draws such maps in their neutral colour,
    before: the round-off stretched to full contrast). A real stretch of 1 % far from the origin,
    and one of 1e-4 on a sheet whose few thin columns of triangles have edges 50 × shorter, stay
    above it (with one size for the whole mesh, from its shortest edges, both were hidden)."""
    from scipy.spatial.transform import Rotation

    v, t = icosphere(3)
    turned = v @ Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix().T + [3.0, -10.0, 0.5]
    single = [x.astype(np.float32).astype(np.float64) for x in (v, turned)]
    d = core.distortion(*single, t)
    assert 0.0 < d.round_off_faces.max() < 1e-3
    assert np.all(np.abs(d.area_change_faces) <= d.round_off_faces)
    assert np.all(np.abs(d.conformal_faces - 1.0) <= d.round_off_faces)
    assert np.all(np.abs(d.bending_faces) <= d.round_off_faces)
    assert np.all(np.abs(d.bending_vertices) <= d.round_off_vertices)
    far, t = grid(21)
    far = far + [1000.0, 0.0, 0.0]
    stretched = far * [1.0, 1.01, 1.0]
    d = core.distortion(far.astype(np.float32).astype(np.float64), stretched.astype(np.float32).astype(np.float64), t)
    assert np.all(np.abs(d.area_change_faces) > d.round_off_faces)
    thin, t = grid(21)
    thin[:, 0] = np.where(thin[:, 0] > 0.5, thin[:, 0], thin[:, 0] * 0.02)  # half the columns 50 × narrower
    d = core.distortion(thin, thin * [1.0, 1.0001, 1.0], t, single_precision=True)
    wide = thin[t].mean(axis=1)[:, 0] > 0.5
    assert np.all(np.abs(d.area_change_faces[wide]) > d.round_off_faces[wide])


@pytest.mark.parametrize("offset", [100.0, 1e4])
def test_a_scanned_rigid_copy_far_out_bends_within_round_off(offset):
    """A scan-like sphere (the convex hull of random points: slivers beside fat triangles) turned
    and moved, in float32, far from the origin: its bending stays within round-off (before, with
    each face's own height, faces beside slivers bent by up to 2 × their bound: the operator's "does
    not change the base" warning was not given and four arbitrary eigenfunction maps were written)."""
    from scipy.spatial import ConvexHull
    from scipy.spatial.transform import Rotation

    points = np.random.default_rng(1).normal(size=(600, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    t = ConvexHull(points).simplices.copy()
    inward = np.einsum("ij,ij->i", np.cross(points[t[:, 1]] - points[t[:, 0]], points[t[:, 2]] - points[t[:, 0]]),
                       points[t].mean(axis=1)) < 0
    t[inward] = t[inward][:, ::-1]
    rest = (points + offset).astype(np.float32).astype(np.float64)
    moved = (rest - rest.mean(axis=0)) @ Rotation.from_euler("xyz", [30, 50, 70], degrees=True).as_matrix().T
    moved = (moved + rest.mean(axis=0) + 0.37).astype(np.float32).astype(np.float64)
    d = core.distortion(rest, moved, t, single_precision=True)
    assert np.all(np.abs(d.bending_faces) <= d.bending_round_off_faces)
    assert np.all(np.abs(d.bending_vertices) <= d.bending_round_off_vertices)


def test_arguments_are_checked(sheet):
    """Basis sizes and counts the maps cannot have are refused in the user's terms (before: k = 1
    gave a conformal eigenvalue of −0.5, k = 10⁶ and 2.5 were accepted, count −1 returned every
    function but one); a basis the mesh cannot have is refused where eigenfunctions are asked
    for, not for the maps, which do not use it (60 separate patches: maps with k = 50)."""
    v, t = sheet
    for k, message in ((0, "at least 1"), (2.5, "whole number")):
        with pytest.raises(core.MeshError, match=message):
            core.distortion(v, v, t, k=k)
    for k, message in ((1, "constant on each part"), (10**6, "Lower it.")):
        with pytest.raises(core.MeshError, match=message):
            core.distortion(v, 1.1 * v, t, k=k).eigenfunctions("area", 2)
    patch, patch_triangles = grid(3)
    patches = np.vstack([patch + [3.0 * i, 0.0, 0.0] for i in range(60)])
    many = np.vstack([patch_triangles + len(patch) * i for i in range(60)])
    maps = core.distortion(patches, 1.2 * patches, many, k=50)
    assert np.allclose(maps.area_change_faces, 2 * np.log(1.2))
    d = core.distortion(v, v, t, k=10)
    for count, message in ((-1, "at least 0"), (2.5, "whole number")):
        with pytest.raises(core.MeshError, match=message):
            d.eigenfunctions("area", count)
    with pytest.raises(core.MeshError, match="kind must be one of"):
        d.eigenfunctions("volume")
    small, triangles = grid(4)  # 16 vertices: the default basis (50) shrinks to 15
    assert core.distortion(small, 1.1 * small, triangles).eigenfunctions("area", 20)[1].shape == (16, 15)


@pytest.mark.parametrize("sides", [32, 64, 128])
def test_a_turned_cylinder_with_fan_caps_is_round_off(sides):
    """Blender splits a cylinder's n-gon caps into fans of long flat triangles, whose angles the
    rounding turns by its size over their height, and whose offset points (t out along their
    normals) by t over the height times that: turned and moved in single precision, every map
    stays within its round-off (before, 31 of 252 faces and the whole bending map read as change,
    and the shape space of such keys as PC shares of 58 / 27 / 15 %)."""
    from scipy.spatial.transform import Rotation

    v, t = capped_cylinder(sides)
    keys = [v] + [v @ Rotation.from_rotvec([0.3 * s, -0.7, 0.2]).as_matrix().T + [s, 2.0, -1.0] for s in range(1, 5)]
    keys = [x.astype(np.float32).astype(np.float64) for x in keys]
    for key in keys[1:]:
        d = core.distortion(keys[0], key, t)
        assert np.all(np.abs(d.area_change_faces) <= d.round_off_faces)
        assert np.all(np.abs(d.conformal_faces - 1.0) <= d.round_off_faces)
        assert np.all(np.abs(d.bending_faces) <= d.bending_round_off_faces)
        assert np.all(np.abs(d.bending_vertices) <= d.bending_round_off_vertices)
    with pytest.warns(core.ShapeDifferenceWarning, match="same shape differences"):
        core.shape_space(keys, t, k_M=10, k_N=None)



def split_along_middle(vertices, triangles):
    """``vertices`` (n, 3), ``triangles`` (m, 3) of a grid cut along its middle column of vertices
    into two pieces that do not share them (as an export split at a UV seam leaves it): the
    vertices with the seam's copies appended, the triangles, the seam's vertices and their copies."""
    middle = np.unique(np.round(vertices[:, 0], 9))
    middle = middle[len(middle) // 2]
    seam = np.flatnonzero(np.isclose(vertices[:, 0], middle))
    copies = len(vertices) + np.arange(seam.size)
    renumber = np.arange(len(vertices))
    renumber[seam] = copies
    right = vertices[triangles].mean(axis=1)[:, 0] > middle
    split = triangles.copy()
    split[right] = renumber[triangles[right]]
    return np.concatenate([vertices, vertices[seam]]), split, seam, copies


def folded(vertices, degrees, hinge):
    """``vertices`` with those beyond x = ``hinge`` turned up about that line by ``degrees``."""
    out = vertices.copy()
    beyond = out[:, 0] > hinge + 1e-9
    distance, angle = out[beyond, 0] - hinge, np.radians(degrees)
    out[beyond, 0], out[beyond, 2] = hinge + distance * np.cos(angle), distance * np.sin(angle)
    return out


def test_a_fold_along_a_seam_the_pieces_do_not_see_is_warned():
    """Pieces of a mesh split along a seam have their maps each on its own: a fold along the seam
    is bending the welded mesh shows there and the split one cannot (0 everywhere), so it warns,
    naming the fold's angle; an in-plane stretch, a rigid motion in single precision far out and
    the welded mesh fold nothing the maps miss."""
    v, t = grid(12)
    hinge = np.unique(np.round(v[:, 0], 9))[len(np.unique(np.round(v[:, 0], 9))) // 2]
    split, triangles, seam, copies = split_along_middle(v, t)
    welded = core.distortion(v, folded(v, 60.0, hinge), t)
    assert np.abs(welded.bending_vertices[seam]).min() > 0.1  # the fold, on the welded mesh
    with pytest.warns(core.ShapeDifferenceWarning, match=r"split along seams \(11 seam edge.*11 of them fold by "
                                                         r"up to 60° in pose vertices.*Merge by Distance"):
        apart = core.distortion(split, folded(split, 60.0, hinge), triangles)
    assert np.abs(apart.bending_vertices).max() < 1e-6  # none but round-off: what the warning is about
    turn = np.linalg.qr(np.random.default_rng(2).normal(size=(3, 3)))[0]
    quiet = [split * [1.0, 1.3, 1.0], (split @ turn.T + 1000.0).astype(np.float32).astype(np.float64)]
    with warnings.catch_warnings():
        warnings.simplefilter("error", core.ShapeDifferenceWarning)
        for pose in quiet:
            core.distortion(split, pose, triangles)
        core.distortion(v, folded(v, 60.0, hinge), t)


def test_a_shape_space_of_folds_along_a_seam_warns():
    """Poses that differ only by a fold along a seam have the same differences piece by piece: the
    shape space of the split mesh has no spread, and says why."""
    v, t = grid(12)
    hinge = np.unique(np.round(v[:, 0], 9))[len(np.unique(np.round(v[:, 0], 9))) // 2]
    split, triangles, _, _ = split_along_middle(v, t)
    poses = [folded(split, degrees, hinge) for degrees in (0.0, 30.0, 60.0, 90.0)]
    with pytest.warns(core.ShapeDifferenceWarning, match=r"split along seams.*up to 90° in the poses: the shape "
                                                         r"differences describe each piece on its own"):
        core.shape_space(poses, triangles, k_M=20, k_N=40)
