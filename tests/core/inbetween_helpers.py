"""Analytic motions and measures shared by the in-between tests (test_sequence_inbetweens,
test_two_pose_inbetweens, test_motion_ends); no bpy."""

from __future__ import annotations

import re

import numpy as np

from meshes import grid

#: Words of a character rig that a warning about any mesh (a cloth, a scan) does not use.
RIG_WORDS = re.compile(r"skin|weight ramp|bone|\brig\b", re.IGNORECASE)


def _edges(triangles):
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def _edge_deviation(x, rest, triangles):
    e = _edges(triangles)
    lx = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)
    lr = np.linalg.norm(rest[e[:, 0]] - rest[e[:, 1]], axis=1)
    return np.abs(lx / lr - 1.0)


def _normals(v, triangles):
    return np.cross(v[triangles[:, 1]] - v[triangles[:, 0]], v[triangles[:, 2]] - v[triangles[:, 0]])


def _flipped(x, key_a, key_b, triangles):
    nx = _normals(x, triangles)
    return int(np.sum((np.einsum("ij,ij->i", nx, _normals(key_a, triangles)) < 0)
                      & (np.einsum("ij,ij->i", nx, _normals(key_b, triangles)) < 0)))


def _strip(n=30, width=6, length=2.0):
    flat, triangles = grid(n, width, size=length)
    return flat, triangles


def _bend(flat, angle, length=2.0):
    """Isometric bend of the strip (x ∈ [0, length]) onto a cylinder arc of total angle ``angle``."""
    if abs(angle) < 1e-12:
        return flat.copy()
    r = length / angle
    th = flat[:, 0] / r
    return np.stack([r * np.sin(th), flat[:, 1], r * (1 - np.cos(th))], axis=1)


def _roll(flat, t, radius=0.3):
    """A sheet rolling onto a cylinder of ``radius``: the part x < t·L wraps around it (isometric)."""
    x0 = t * flat[:, 0].max()
    out = flat.copy()
    wrapped = flat[:, 0] < x0
    th = (x0 - flat[wrapped, 0]) / radius
    out[wrapped, 0] = x0 - radius * np.sin(th)
    out[wrapped, 2] = radius * (1 - np.cos(th))
    return out
