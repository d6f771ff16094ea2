"""Per-triangle deformation fields (core/deformation_fields.py) against independent formulas."""

import numpy as np
from scipy.linalg import expm, logm, polar
from scipy.spatial.transform import Rotation

import core.deformation_fields as df


def _random_triangles(count=200, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(count, 3, 3))  # corners p0, p1, p2


def test_tangent_frames_are_orthonormal_and_project_the_edges():
    corners = _random_triangles()
    edges = corners[:, [1, 2, 0]] - corners
    columns, coordinates = df.tangent_frames(edges)
    frames = columns.transpose(1, 2, 0)  # (m, 3, 3) with columns t1, t2, n
    assert np.allclose(np.einsum("kab,kac->kbc", frames, frames), np.eye(3), atol=1e-13)
    assert np.allclose(np.linalg.det(frames), 1.0)
    normals = np.cross(edges[:, 0], -edges[:, 2])
    assert np.allclose(columns[2], normals / np.linalg.norm(normals, axis=1, keepdims=True))
    # the closed-form coordinates are the projections on (t1, t2)
    assert np.allclose(coordinates, np.einsum("kcd,kdj->kcj", edges, frames[:, :, :2]), atol=1e-13)


def test_planar_polar_matches_scipy_and_exp_inverts_log():
    rng = np.random.default_rng(1)
    maps = rng.normal(size=(100, 2, 2))
    maps[np.linalg.det(maps) < 0] *= np.array([[1, 1], [-1, -1]])  # positive determinants
    (cos, sin), stretch = df.planar_polar(maps)
    for k in range(len(maps)):
        rotation, symmetric = polar(maps[k])  # maps = rotation @ symmetric
        assert np.allclose([[cos[k], -sin[k]], [sin[k], cos[k]]], rotation, atol=1e-12)
        assert np.allclose(stretch[k], symmetric[[0, 0, 1], [0, 1, 1]], atol=1e-12)
    packed = lambda s: np.array([[s[0], s[1]], [s[1], s[2]]])  # noqa: E731
    logs = df.log_stretch(stretch)
    for k in range(len(maps)):
        assert np.allclose(packed(logs[k]), logm(packed(stretch[k])).real, atol=1e-10)
    small = 1e-7 * rng.normal(size=(20, 3))  # the series branch
    for log in (logs, small):
        exps = df.exp_stretch(log)
        for k in range(len(log)):
            assert np.allclose(packed(exps[k]), expm(packed(log[k])), rtol=1e-12, atol=1e-14)


def test_rotation_vectors_of_frames_match_scipy_at_every_angle():
    """Also the turned frames of several components against the products written out."""
    rng = np.random.default_rng(2)
    angles = np.r_[np.linspace(0, np.pi, 60), [1e-9, np.pi - 1e-9]]
    axes = rng.normal(size=(len(angles), 3))
    rotvecs = angles[:, None] * axes / np.linalg.norm(axes, axis=1, keepdims=True)
    base = Rotation.random(len(angles), random_state=3).as_matrix()
    columns = base.transpose(2, 0, 1).copy()
    rows = lambda frames: np.ascontiguousarray(frames.transpose(0, 2, 1))  # noqa: E731
    turned = df.rotated_frames(rotvecs, np.eye(3)[None], np.zeros(len(angles), dtype=int), rows(columns))
    recovered = df.frame_rows_rotation_vectors(rows(turned), rows(columns))
    expected = Rotation.from_rotvec(rotvecs).as_matrix()
    assert np.allclose(Rotation.from_rotvec(recovered).as_matrix(), expected, atol=1e-9)
    assert np.allclose(recovered[:-1], rotvecs[:-1], atol=1e-9)  # angle < π: the vector itself
    cos, sin = np.cos(angles), np.sin(angles)
    pieces = Rotation.random(2, random_state=4).as_matrix()
    component = np.arange(len(angles)) % 2
    turned = df.turned_frame_rows(rows(columns), (cos, sin), pieces, component)
    planar = np.zeros((len(angles), 3, 3))
    planar[:, 0, 0], planar[:, 0, 1], planar[:, 1, 0], planar[:, 1, 1], planar[:, 2, 2] = cos, -sin, sin, cos, 1
    expected = pieces[component] @ base @ planar  # columns: the images of the frame
    assert np.allclose(turned, expected.transpose(2, 1, 0), atol=1e-13)
