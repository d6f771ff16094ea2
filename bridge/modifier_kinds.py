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

#: Blender's modifiers of its deform-only kind (``ModifierTypeType::OnlyDeform``: they hand the next one the
#: same mesh, its positions changed or not): a stack of these alone before a cloth gives it no Rest Shape Key,
#: in Blender 4.2–5.0 (``operators.frames.cloth_rest_is_input``). A Particle System and a Surface (a force
#: field's) are of that kind though they move nothing; a UV Project or a Normal Edit, which move nothing
#: either, are not, and behind them the key is read (measured: docs/inbetween-measurements.md, *The cloth's
#: Rest Shape Key*).
DEFORM_ONLY_MODIFIERS = {'ARMATURE', 'CAST', 'CLOTH', 'COLLISION', 'CORRECTIVE_SMOOTH', 'CURVE', 'DISPLACE', 'HOOK',
                         'LAPLACIANDEFORM', 'LAPLACIANSMOOTH', 'LATTICE', 'MESH_CACHE', 'MESH_DEFORM',
                         'PARTICLE_SYSTEM', 'SHRINKWRAP', 'SIMPLE_DEFORM', 'SMOOTH', 'SOFT_BODY', 'SURFACE',
                         'SURFACE_DEFORM', 'WARP', 'WAVE'}


def enabled_before(obj, modifier) -> list:
    """The modifiers of ``obj`` enabled in the viewport that come before ``modifier`` in its stack (what
    ``modifier`` is given: the mesh they make of the object's)."""
    stack = list(obj.modifiers)
    return [m for m in stack[:stack.index(modifier)] if m.show_viewport]


def simulations(objects):
    """``(object, modifier)`` for each cloth or soft body modifier of ``objects`` enabled in the
    viewport (the ones that move the mesh the frames are read from)."""
    for obj in objects:
        for modifier in obj.modifiers:
            if modifier.type in SIMULATION_MODIFIERS and modifier.show_viewport:
                yield obj, modifier
