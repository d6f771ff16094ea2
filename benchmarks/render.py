"""Matplotlib drawing of triangle meshes for the benchmark pictures (no Blender needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw_mesh(ax, vertices: np.ndarray, triangles: np.ndarray, values: np.ndarray, bounds, *, cmap="coolwarm",
              title: str = "", view=(15, -70)):
    """Shade ``triangles`` ``(m, 3)`` of ``vertices`` ``(n, 3)`` on a 3D axis, coloured by per-triangle
    ``values`` in [0, 1] and darkened by how much each face turns away from the viewer's y axis;
    ``bounds`` = (low, high) corners shared by the panels of one figure."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    lo, hi = bounds
    p0 = vertices[triangles[:, 0]]
    normals = np.cross(vertices[triangles[:, 1]] - p0, vertices[triangles[:, 2]] - p0)
    light = np.abs(normals[:, 1]) / np.maximum(np.linalg.norm(normals, axis=1), 1e-300)
    colors = pyplot().get_cmap(cmap)(np.clip(values, 0.0, 1.0))
    colors[:, :3] *= (0.55 + 0.45 * light)[:, None]
    ax.add_collection3d(Poly3DCollection(vertices[triangles], facecolors=colors, edgecolors="none"))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-9 * np.max(hi - lo)))
    ax.view_init(elev=view[0], azim=view[1])
    ax.set_axis_off()
    ax.set_title(title, fontsize=8)


def common_bounds(poses) -> tuple[np.ndarray, np.ndarray]:
    """Low and high corners of the bounding box of several ``(n, 3)`` poses."""
    return np.min([p.min(0) for p in poses], axis=0), np.max([p.max(0) for p in poses], axis=0)


def save(fig, path, top: float = 1.0) -> None:
    """Lay out and write ``fig``; ``top`` < 1 keeps that fraction of the height free of axes
    (``tight_layout`` does not make room for a ``suptitle`` above 3-D axes)."""
    fig.tight_layout(rect=(0.0, 0.0, 1.0, top))
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    pyplot().close(fig)
