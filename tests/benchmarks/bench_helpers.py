"""Sources for the in-between benchmark's tests (benchmarks/bench_inbetween.py): a small sheet
bending about an axis, built from scratch instead of baked by Blender."""

from __future__ import annotations

import numpy as np


def grid_bend(angles, lifts, side: int = 8):
    """Frames of a ``side`` × ``side`` sheet of unit size rolled into a circular arc of ``angles[f]``
    radians per unit length (> 0) and lifted by ``lifts[f]``: ``(frames (F, side², 3), triangles
    (m, 3))``; every frame keeps the rest lengths along the bend."""
    u, v = np.meshgrid(np.linspace(0.0, 1.0, side), np.linspace(0.0, 1.0, side), indexing="ij")
    i = np.arange(side - 1)[:, None] * side + np.arange(side - 1)[None, :]
    quads = np.stack([i, i + side, i + side + 1, i + 1], axis=-1).reshape(-1, 4)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.int64)
    poses = []
    for angle, lift in zip(angles, lifts):
        r = 1.0 / angle
        poses.append(np.stack([r * np.sin(u / r), v, r * (1.0 - np.cos(u / r)) + lift], -1).reshape(-1, 3))
    return np.stack(poses), triangles


def steady_bend(frames: int = 17, side: int = 8):
    """The sheet bending and rising at constant speed from frame 0."""
    f = np.arange(frames)
    return grid_bend(0.08 * f + 1e-9, 0.01 * f, side)
