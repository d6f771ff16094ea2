"""The files cache modifiers play: a Mesh Cache's path and header, and the first cache modifier of an
object whose file is not there.
"""

from __future__ import annotations

import os

import bpy
import numpy as np


def missing_cache_file(obj: bpy.types.Object) -> tuple[str, str] | None:
    """``(modifier name, path)`` of the first enabled Mesh Cache or Mesh Sequence Cache (Alembic,
    USD) modifier of ``obj`` whose file does not exist, or None. A file sequence (numbered files)
    is not checked."""
    for modifier in obj.modifiers:
        if not modifier.show_viewport:
            continue
        if modifier.type == 'MESH_CACHE':
            path = modifier.filepath
            absolute = mesh_cache_file(modifier) if path else ""
        elif modifier.type == 'MESH_SEQUENCE_CACHE' and modifier.cache_file is not None \
                and not modifier.cache_file.is_sequence:  # relative to the Cache File's own
            path = modifier.cache_file.filepath
            absolute = bpy.path.abspath(path, library=modifier.cache_file.library) if path else ""
        else:
            continue
        if not path or not os.path.isfile(absolute):
            return modifier.name, absolute or "(no file)"
    return None


def mesh_cache_file(modifier: bpy.types.MeshCacheModifier) -> str:
    """The absolute path of the file the Mesh Cache ``modifier`` plays (a relative path is relative
    to the file its object comes from)."""
    return bpy.path.abspath(modifier.filepath, library=modifier.id_data.library)


def mesh_cache_header(modifier: bpy.types.MeshCacheModifier) -> tuple[int, int, np.ndarray | None]:
    """``(samples, points, times)`` of the PC2 or MDD file the Mesh Cache ``modifier`` plays, read
    as its Format says (as Blender reads it: bytes after the samples do not count); ``times``: an
    MDD's frame times in seconds, None for a PC2. Raises ``core.MeshError`` for a file that is not a
    cache of that kind or is shorter than its header says."""
    from ..core.point_cache import read_mdd_header, read_pc2_header

    path = mesh_cache_file(modifier)
    if modifier.cache_format == 'PC2':
        points, _start, _sampling, samples = read_pc2_header(path, whole=False)
        return samples, points, None
    points, times = read_mdd_header(path, whole=False)
    return len(times), points, times
