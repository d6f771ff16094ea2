"""The kinds of modifiers the frames' reading tells apart: simulations, modifiers that play poses of
their own, generators; and an object's enabled simulations.
"""

from __future__ import annotations

#: Modifiers that simulate and keep a point cache (emptied when the object's mesh data changes,
#: marked outdated when its modifiers change at a frame past its start).
SIMULATION_MODIFIERS = {'CLOTH', 'SOFT_BODY'}
#: Modifiers that replace the positions of their mesh with poses of their own (a simulation's frames,
#: a cache's samples): the mesh's shape keys do not show under them, and a generator after them works
#: on what they play (applied, it would give them other vertices than they hold).
POSE_REPLACING_MODIFIERS = SIMULATION_MODIFIERS | {'MESH_CACHE', 'MESH_SEQUENCE_CACHE'}
#: Modifiers that add or remove vertices (Blender's Generate category; Geometry Nodes apart, which
#: may carry the motion itself).
GENERATE_MODIFIERS = {'ARRAY', 'BEVEL', 'BOOLEAN', 'BUILD', 'DECIMATE', 'EDGE_SPLIT', 'MASK', 'MIRROR',
                      'MULTIRES', 'REMESH', 'SCREW', 'SKIN', 'SOLIDIFY', 'SUBSURF', 'TRIANGULATE', 'WELD',
                      'WIREFRAME'}


def simulations(objects):
    """``(object, modifier)`` for each cloth or soft body modifier of ``objects`` enabled in the
    viewport (the ones that move the mesh the frames are read from)."""
    for obj in objects:
        for modifier in obj.modifiers:
            if modifier.type in SIMULATION_MODIFIERS and modifier.show_viewport:
                yield obj, modifier
