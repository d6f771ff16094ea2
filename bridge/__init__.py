"""The one place where data moves between Blender and NumPy.

Reads go through float32/int32 buffers with ``foreach_get`` and come back as the float64/int64
arrays that :mod:`core` expects; writes go the other way with ``foreach_set``. Coordinates are
always in object space. Nothing else in the extension converts.

The modules, one concept each:

- :mod:`mesh_data`: reading a mesh: positions, shape keys as stored and as shown, weights, the evaluated mesh
- :mod:`triangulation`: the triangles a mesh gives the core, and the polygon of each
- :mod:`scene_timing`: setting the scene to frames and sub-frames; the time it plays at a frame
- :mod:`world_space`: the world's proportions and frames poses are interpolated in
- :mod:`modifier_kinds`: simulations, modifiers that play poses, generators
- :mod:`cache_files`: the files cache modifiers play: paths, headers, files gone
- :mod:`pose_runs`: runs of identical poses read, spans of frames as messages name them
- :mod:`cache_checks`: what frames read from a Mesh Cache or Alembic / USD cache tell
- :mod:`bake_checks`: what frames read from a cloth or soft body tell: bakes gone, frames outside
- :mod:`frame_errors`: the refusals of reading frames (FrameReadError and its kinds)
- :mod:`frame_reading`: reading an object's frames (frame_positions)
- :mod:`vertex_count_refusal`: the refusal of a frame with other vertices, and its way out
- :mod:`naming`: names within Blender's length limit, and free names
- :mod:`shape_keys`: writing shape keys and keyframing their values
- :mod:`cache_object`: a new object that plays a point cache, rendering as its source
- :mod:`copied_motion`: what moves an object as a whole, copied to a new object (retimed)
- :mod:`rigid_bodies`: queries of the scenes' rigid body worlds
- :mod:`analysis_data`: what the analysis operators store: attributes, the shape space

Each name has one import path, ``bridge.<module>.<name>``: callers import the module
(``from ..bridge import frame_reading``).
"""

# every module loaded with the package, so that ``bridge.<module>`` names a module wherever the
# package is imported
from . import (mesh_data, triangulation, scene_timing, world_space, modifier_kinds, cache_files, pose_runs,
               cache_checks, bake_checks, frame_errors, frame_reading, vertex_count_refusal, naming, shape_keys,
               cache_object, copied_motion, rigid_bodies, analysis_data)  # noqa: F401
