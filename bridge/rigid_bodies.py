"""Queries of the scenes' rigid body worlds: their collections, whether an object is moved by a
simulation, whether its collision shape is read from its deformed mesh.
"""

from __future__ import annotations

import bpy


def _rigid_body_worlds() -> list:
    """The rigid body worlds of the file's scenes."""
    return [scene.rigidbody_world for scene in bpy.data.scenes if scene.rigidbody_world is not None]


def rigid_body_collections() -> list:
    """The collections of the scenes' rigid body worlds (their bodies and their constraints):
    Blender gives every object linked to the first a rigid body and simulates it with the others."""
    return [c for world in _rigid_body_worlds() for c in (world.collection, world.constraints) if c is not None]


def simulated_rigid_body(obj: bpy.types.Object) -> bool:
    """Whether ``obj`` is moved as a whole by a rigid body simulation: an active rigid body that is
    dynamic and not animated, of a scene's rigid body world that is on (the simulation sets its
    world matrix; its transform channels and mesh stay as they are)."""
    body = obj.rigid_body
    if body is None or body.type != 'ACTIVE' or not body.enabled or body.kinematic:
        return False
    return any(world.enabled and world.collection is not None and obj.name in world.collection.all_objects
               for world in _rigid_body_worlds())


def unbaked_rigid_body_shape(obj: bpy.types.Object) -> bool:
    """Whether ``obj`` is a rigid body of a rigid body world that is not baked, with a collision
    shape read from its deformed mesh (Convex Hull or Mesh from Deform or Final): shape keys added
    to it change the shapes the simulation collides, and so the simulation, when it is played
    again."""
    body = obj.rigid_body
    if body is None or body.collision_shape not in {'CONVEX_HULL', 'MESH'} or body.mesh_source == 'BASE':
        return False
    return any(world.collection is not None and obj.name in world.collection.all_objects
               and not world.point_cache.is_baked for world in _rigid_body_worlds())
