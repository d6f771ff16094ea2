"""Shape space (paper §8.1): PCA of shape differences over a collection of poses."""

import numpy as np
import pytest

import core
from core.shape_space_pca import KINDS
from meshes import grid


def bumped(vertices, height, center=(0.5, 0.5), radius=0.3):
    """The sheet with a smooth bump of ``height`` (negative: a dent, its exact mirror image)."""
    r = np.linalg.norm(vertices[:, :2] - np.asarray(center), axis=1)
    out = vertices.copy()
    out[:, 2] += height * np.where(r < radius, np.cos(0.5 * np.pi * r / radius) ** 2, 0.0)
    return out


@pytest.fixture(scope="module")
def bump_collection():
    """Fig. 7 (top row) on a sheet: bumps of two sizes at two places, each up and down."""
    v, t = grid(14, jitter=0.2)
    poses = [v]
    for center in ((0.4, 0.4), (0.6, 0.55)):
        for height in (0.12, 0.2):
            poses += [bumped(v, height, center), bumped(v, -height, center)]
    return poses, t


@pytest.fixture(scope="module")
def bump_space(bump_collection):
    poses, t = bump_collection
    return core.shape_space(poses, t, k_M=20, k_N=40)


def rolled(vertices, curvature):
    """The sheet rolled onto a cylinder of the given curvature (isometric up to chord lengths)."""
    if curvature == 0:
        return vertices.copy()
    radius = 1.0 / curvature
    theta = (vertices[:, 0] - 0.5) / radius
    return np.stack([radius * np.sin(theta), vertices[:, 1], radius * (1 - np.cos(theta))], axis=1)


def spread(points):
    return np.linalg.norm(points - points.mean(axis=0), axis=1).max()


@pytest.mark.parametrize("kind", ["area", "conformal"])
def test_mirror_images_coincide_in_intrinsic_coordinates(bump_space, kind):
    xy = bump_space.coordinates(kind, dims=2)
    up, down = xy[1::2], xy[2::2]
    assert spread(xy) > 0
    assert np.abs(up - down).max() <= 1e-9 * spread(xy)


@pytest.mark.parametrize("kind", ["offset_area", "offset_conformal"])
def test_mirror_images_separate_in_offset_coordinates(bump_space, kind):
    points = bump_space.coordinates(kind, dims=bump_space.n_poses - 1)
    gaps = np.linalg.norm(points[1::2] - points[2::2], axis=1)
    assert gaps.min() > 0.1 * spread(points)


def test_full_rank_coordinates_keep_the_frobenius_distances(bump_collection, bump_space):
    poses, t = bump_collection
    reference = core.ReferenceShape(poses[0], t)
    matrices = [reference.shape_differences(p, k_M=20, k_N=40).offset_area.matrix for p in poses[:5]]
    points = bump_space.coordinates("offset_area", dims=bump_space.n_poses)[:5]
    for i in range(5):
        for j in range(i):
            expected = np.linalg.norm(matrices[i] - matrices[j])
            assert np.linalg.norm(points[i] - points[j]) == pytest.approx(expected, rel=1e-8)


def test_variance_ratios_sum_to_one_and_decrease(bump_space):
    for kind in KINDS:
        ratio = bump_space.explained_variance_ratio(kind)
        assert ratio.sum() == pytest.approx(1.0)
        assert np.all(np.diff(ratio) <= 1e-12)
        assert bump_space.coordinates(kind, 3).shape == (bump_space.n_poses, 3)
        assert bump_space.coordinates(kind, 3).dtype == np.float64


def test_animation_frames_lie_along_a_curve_in_playing_order():
    """Fig. 9: a sheet bending over a bar, frame after frame (nearly isometric): each frame's
    nearest neighbour in the 2-D offset embedding is the previous or the next frame."""
    v, t = grid(13, jitter=0.2)
    frames = [rolled(v, amount) for amount in np.linspace(0.0, 3.0, 10)]
    space = core.shape_space(frames, t, k_M=20, k_N=40)
    for kind in ("offset_area", "offset_conformal"):
        xy = space.coordinates(kind)
        distance = np.linalg.norm(xy[:, None] - xy[None], axis=2)
        np.fill_diagonal(distance, np.inf)
        nearest = distance.argmin(axis=1)
        assert np.all(np.abs(nearest - np.arange(len(frames))) == 1), (kind, nearest)
    # A nearly isometric motion: the intrinsic differences move far less than the extrinsic ones.
    intrinsic = spread(space.coordinates("area", 2))
    extrinsic = spread(space.coordinates("offset_area", 2))
    assert intrinsic < 0.1 * extrinsic


def test_eq5_differences_without_a_pose_basis(bump_collection):
    poses, t = bump_collection
    space = core.shape_space(poses[:5], t, k_M=20, k_N=None)
    xy = space.coordinates("area")
    assert np.abs(xy[1] - xy[2]).max() <= 1e-9 * spread(xy)
    off = space.coordinates("offset_area", dims=4)
    assert np.linalg.norm(off[1] - off[2]) > 0.1 * spread(off)


def test_bad_inputs_name_the_problem(bump_collection):
    poses, t = bump_collection
    with pytest.raises(core.MeshError, match="at least two poses"):
        core.shape_space(poses[:1], t)
    with pytest.raises(core.MeshError, match="set k_M"):
        core.shape_space(poses[:3], t, k_M=None, k_N=None)
    with pytest.raises(core.MeshError, match="pose 2"):
        core.shape_space([poses[0], poses[1], poses[2][:-1]], t, k_M=10, k_N=20)
    # named by the caller's names (the operators': shape keys, frames), the base pose too
    named = ["frame 1", "frame 5", "frame 9"]
    with pytest.raises(core.MeshError, match="^frame 9 has 195 vertices but"):
        core.shape_space([poses[0], poses[1], poses[2][:-1]], t, k_M=10, k_N=20, key_names=named)
    with pytest.raises(core.MeshError, match="^frame 1: .*non-finite"):
        core.shape_space([np.where(np.arange(len(poses[0]))[:, None] == 3, np.nan, poses[0]), poses[1], poses[2]], t,
                         k_M=10, k_N=20, key_names=named)
    with pytest.raises(core.MeshError, match="key_names must name each of the 3 poses; got 2"):
        core.shape_space(poses[:3], t, k_M=10, k_N=20, key_names=named[:2])
    space = core.shape_space(poses[:3], t, k_M=10, k_N=20)
    with pytest.raises(core.MeshError, match="kind must be one of"):
        space.coordinates("volume")
    with pytest.raises(core.MeshError, match="dims must be at least 1"):
        space.coordinates("area", 0)
    # faces that share no edge: no offset surface, and no advice to turn off what cannot be turned off
    scraps = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (2, 1, 0)], dtype=float)
    with pytest.raises(core.MeshError, match="no triangles of this mesh share an edge. Use a connected surface.$"):
        core.shape_space([scraps, 1.1 * scraps], [[0, 1, 2], [3, 4, 5]], k_M=3, k_N=None)
    # a basis too large for the mesh: no advice to use the full basis, which a shape space refuses
    with pytest.raises(core.MeshError, match=r"at most 195 .* exist\. Lower it\.$"):
        core.shape_space(poses[:3], t, k_M=400, k_N=500)


def test_poses_that_do_not_differ_have_no_spread(bump_collection):
    """Copies of one pose (a still animation): every axis is round-off (5e-17 of the differences'
    norm), so the variance shares are zero, every pose is at the origin and a warning says so
    (before, the round-off axis read as 100 % of the variance); poses moved by 1e-9 of the mesh's
    size still spread."""
    poses, t = bump_collection
    with pytest.warns(core.ShapeDifferenceWarning, match="same shape differences"):
        still = core.shape_space([poses[1]] * 4, t, k_M=12, k_N=None)
    for kind in KINDS:
        assert not still.explained_variance_ratio(kind).any()
        assert not still.coordinates(kind).any()
    rng = np.random.default_rng(3)
    nudged = core.shape_space([poses[1] + 1e-9 * rng.normal(size=poses[1].shape) for _ in range(4)], t,
                              k_M=12, k_N=None)
    assert nudged.explained_variance_ratio("area").sum() == pytest.approx(1.0)


def test_rigid_copies_in_single_precision_have_no_spread():
    """Shape keys that only turn and move the base, stored in float32 as Blender stores them,
    differ by the coordinates' rounding (a spread of 1e-7, before shown as PC shares of 60 / 25 %
    with no warning): no spread and the warning; a real pose among them still spreads."""
    from scipy.spatial.transform import Rotation

    v, t = grid(14, jitter=0.2)
    moved = [v] + [v @ Rotation.from_rotvec([0.3 * s, -0.2, 0.1 * s]).as_matrix().T + [s, -s, 0.5 * s]
                   for s in range(1, 5)]
    single = [x.astype(np.float32).astype(np.float64) for x in moved]
    with pytest.warns(core.ShapeDifferenceWarning, match="same shape differences"):
        space = core.shape_space(single, t, k_M=12, k_N=None)
    assert not any(space.explained_variance_ratio(kind).any() for kind in KINDS)
    real = core.shape_space(single + [bumped(v, 0.05).astype(np.float32).astype(np.float64)], t, k_M=12, k_N=None)
    assert real.explained_variance_ratio("offset_area")[0] > 0.99


def test_a_base_basis_of_constants_per_piece_is_refused():
    """Two separate sheets: k_M = 2 holds only the constant on each, whose conformal difference is
    empty; refused as by ``core.shape_differences`` (before, accepted: conformal coordinates 50 ×
    the area ones for bends that change no angle)."""
    v, t = grid(6)
    v2 = np.vstack([v, v + [3.0, 0.0, 0.0]])
    t2 = np.vstack([t, t + len(v)])
    poses = [v2, v2 + np.where(np.arange(len(v2))[:, None] < len(v), [0.0, 0.0, 0.0], [0.0, 0.0, 0.5])]
    with pytest.raises(core.MeshError, match="2 connected part"):
        core.shape_space(poses, t2, k_M=2, k_N=None)


def test_steps_hold_the_blas_limit_only_while_computing_a_pose(bump_collection, monkeypatch):
    """The generator behind the shape space operator computes each pose with BLAS single-threaded
    (core.concurrency's process-wide limit) and lets the limit go before it yields: the caller's
    code between steps, and the process after the generator is abandoned half-way (an operator
    cancelled) or closed, run with the process's own BLAS threads."""
    from core import concurrency, shape_space_pca

    poses, t = bump_collection
    held_while_computing = []
    original = shape_space_pca.pose_differences

    def spied(*arguments):
        held_while_computing.append(concurrency._limit_holders > 0)
        return original(*arguments)

    monkeypatch.setattr(shape_space_pca, "pose_differences", spied)
    holders = concurrency._limit_holders
    steps = shape_space_pca.shape_space_steps(poses[:4], t, k_M=8, k_N=None)
    assert next(steps) == pytest.approx(0.25)
    assert concurrency._limit_holders == holders  # between steps: released
    assert next(steps) == pytest.approx(0.5)
    assert concurrency._limit_holders == holders
    steps.close()  # abandoned half-way
    assert concurrency._limit_holders == holders
    assert held_while_computing and all(held_while_computing)
    abandoned = shape_space_pca.shape_space_steps(poses[:4], t, k_M=8, k_N=None)
    next(abandoned)
    del abandoned  # dropped without close
    assert concurrency._limit_holders == holders
