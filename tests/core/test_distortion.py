"""Distortion maps: area change, conformal distortion, bending and the difference eigenfunctions."""

import numpy as np
import pytest

import core
from core.distortion_maps import DistortionAnalyzer
from meshes import grid, icosphere


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
    values, functions = core.distortion(v, pose, t, k=20).eigenfunctions(kind, 4)
    assert values.shape == (4,) and functions.shape == (len(v), 4)
    assert np.all(np.isfinite(functions)) and np.allclose(np.abs(functions).max(axis=0), 1.0)
    assert np.all(np.diff(np.abs(np.log(values))) <= 1e-12)


def test_bad_kind_and_pose(sheet):
    v, t = sheet
    with pytest.raises(ValueError, match="kind must be one of"):
        core.distortion(v, v, t).eigenfunctions("volume")
    with pytest.raises(core.MeshError):
        core.distortion(v, v[:-1], t)
