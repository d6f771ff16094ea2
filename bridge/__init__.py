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
- :mod:`frame_reading`: reading an object's frames (frame_positions) and its refusals (FrameReadError and its
  kinds; a frame with other vertices, and its way out)
- :mod:`frame_checks`: what frames read tell of the cache or simulation that played them: a Mesh Cache or
  Alembic / USD cache (frames outside, held, another mesh), a cloth or soft body (bakes gone, frames outside)
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
from . import (mesh_data, triangulation, scene_timing, world_space, modifier_kinds, cache_files, frame_reading,
               frame_checks, naming, shape_keys, cache_object, copied_motion, rigid_bodies, analysis_data)  # noqa: F401
