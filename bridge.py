"""The one place where data moves between Blender and NumPy.

Reads go through float32/int32 buffers with ``foreach_get`` and come back as the float64/int64
arrays that :mod:`core` expects; writes go the other way with ``foreach_set``. Coordinates are
always in object space. Nothing else in the extension converts.
"""

from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

BASIS_NAME = "Basis"


def vertex_positions(mesh: bpy.types.Mesh) -> np.ndarray:
    """Vertex positions of ``mesh`` in object space, float64 ``(n, 3)``."""
    buffer = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.attributes["position"].data.foreach_get("vector", buffer)
    return buffer.reshape(-1, 3).astype(np.float64)


def shape_key_positions(key_block: bpy.types.ShapeKey) -> np.ndarray:
    """Coordinates stored in a shape key, float64 ``(n, 3)``."""
    buffer = np.empty(len(key_block.data) * 3, dtype=np.float32)
    key_block.data.foreach_get("co", buffer)
    return buffer.reshape(-1, 3).astype(np.float64)


def mesh_triangles(mesh: bpy.types.Mesh) -> np.ndarray:
    """The loop triangles of ``mesh`` (n-gons triangulated) as int64 ``(m, 3)`` vertex indices."""
    mesh.calc_loop_triangles()
    buffer = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", buffer)
    return buffer.reshape(-1, 3).astype(np.int64)


def evaluated_positions(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> np.ndarray:
    """Object-space vertex positions after the modifier stack (cloth, armature, ...) at the
    depsgraph's current frame, float64 ``(n, 3)``."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        return vertex_positions(mesh)
    finally:
        evaluated.to_mesh_clear()


class VertexCountChanged(ValueError):
    """The evaluated mesh does not have the vertex count of the original mesh at some frame."""


def frame_positions(context: bpy.types.Context, obj: bpy.types.Object, frames: list[int]):
    """Yield ``(frame, positions)`` for the evaluated mesh of ``obj`` at each of ``frames``
    (ascending).

    Every frame from the first to the last is visited in order, so that simulations that are not
    baked still advance one frame at a time. The scene's current frame is restored afterwards,
    also when the caller stops early.
    """
    scene = context.scene
    wanted = set(frames)
    vertex_count = len(obj.data.vertices)
    original_frame, original_subframe = scene.frame_current, scene.frame_subframe
    try:
        for frame in range(frames[0], frames[-1] + 1):
            scene.frame_set(frame)
            if frame not in wanted:
                continue
            positions = evaluated_positions(obj, context.evaluated_depsgraph_get())
            if len(positions) != vertex_count:
                raise VertexCountChanged(
                    f"At frame {frame} the evaluated mesh of '{obj.name}' has {len(positions)} "
                    f"vertices instead of {vertex_count}: a modifier changes the topology. "
                    "Disable modifiers that add or remove geometry (Subdivision, Remesh, Decimate, "
                    "...) or apply them before capturing frames.")
            yield frame, positions
    finally:
        scene.frame_set(original_frame, subframe=original_subframe)


@dataclass
class NewShapeKey:
    """A shape key to be written: its wanted name (made unique by Blender) and coordinates."""

    name: str
    positions: np.ndarray


MAX_NAME_LENGTH = 63  # Blender's limit for shape key names


def unique_key_name(obj: bpy.types.Object, name: str) -> str:
    """``name``, or ``name.001``, ``name.002``, ... if taken (Blender's own renaming would read a
    name ending in ``0.50`` as already numbered and turn it into ``0.051``)."""
    taken = set(obj.data.shape_keys.key_blocks.keys()) if obj.data.shape_keys else set()
    candidate = name[:MAX_NAME_LENGTH]
    number = 0
    while candidate in taken:
        number += 1
        candidate = f"{name[:MAX_NAME_LENGTH - 4]}.{number:03d}"
    return candidate


def add_shape_keys(obj: bpy.types.Object, new_keys: list[NewShapeKey],
                   keyframes: list[float] | None = None) -> list[str]:
    """Add each of ``new_keys`` as a new shape key with value 0 (creating the Basis first if the
    mesh has none) and return the names they got.

    With ``keyframes`` (one increasing frame per key), the key values are animated so that
    playback steps through the keys (see :func:`keyframe_key_values`). Existing keys are never
    touched and the active key stays active; a taken name gets a ``.001`` suffix
    (:func:`unique_key_name`). If anything fails, every key added here (and a Basis created here)
    is removed again before the error propagates.
    """
    had_basis = obj.data.shape_keys is not None
    active_index = obj.active_shape_key_index
    added: list[bpy.types.ShapeKey] = []
    try:
        if not had_basis:
            obj.shape_key_add(name=BASIS_NAME, from_mix=False)
        for new_key in new_keys:
            key_block = obj.shape_key_add(name=unique_key_name(obj, new_key.name), from_mix=False)
            added.append(key_block)
            key_block.value = 0.0
            key_block.data.foreach_set(
                "co", np.ascontiguousarray(new_key.positions, dtype=np.float32).ravel())
        names = [key_block.name for key_block in added]
        if keyframes is not None:
            keyframe_key_values(obj, list(zip(keyframes, names)))
        obj.data.update()
        return names
    except BaseException:
        remove_shape_keys(obj, [key_block.name for key_block in added], remove_basis=not had_basis)
        raise
    finally:
        obj.active_shape_key_index = active_index


def remove_shape_keys(obj: bpy.types.Object, names: list[str], *, remove_basis: bool = False):
    """Remove the named shape keys (and the Basis too if ``remove_basis``)."""
    key = obj.data.shape_keys
    if key is None:
        return
    for name in names:
        key_block = key.key_blocks.get(name)
        if key_block is not None:
            obj.shape_key_remove(key_block)
    if remove_basis and obj.data.shape_keys is not None and len(obj.data.shape_keys.key_blocks) == 1:
        obj.shape_key_remove(obj.data.shape_keys.key_blocks[0])
    obj.data.update()


def shape_key_value_fcurve(key: bpy.types.Key, key_name: str):
    """The F-curve animating ``key_blocks[key_name].value`` (legacy and slotted actions)."""
    animation_data = key.animation_data
    data_path = f'key_blocks["{bpy.utils.escape_identifier(key_name)}"].value'
    action = animation_data.action if animation_data else None
    if action is None:
        return None
    if hasattr(animation_data, "action_slot"):  # Blender 4.4+: layered actions with slots
        from bpy_extras import anim_utils
        channelbag = anim_utils.action_get_channelbag_for_slot(action, animation_data.action_slot)
        fcurves = channelbag.fcurves if channelbag else ()
    else:
        fcurves = action.fcurves
    return next((fcurve for fcurve in fcurves if fcurve.data_path == data_path), None)


def keyframe_key_values(obj: bpy.types.Object, timeline: list[tuple[float, str]]):
    """Keyframe the values of the named shape keys so that playback steps through them.

    ``timeline`` is ``(frame, key name)`` in increasing frame order: each key gets value 1 at its
    frame and 0 at the frames of its neighbours, with linear interpolation, so between two samples
    the mesh blends linearly from one key to the next. Only F-curves of these keys are written.
    """
    key = obj.data.shape_keys
    frames = [frame for frame, _ in timeline]
    for index, (frame, name) in enumerate(timeline):
        key_block = key.key_blocks[name]
        neighbours = [frames[i] for i in (index - 1, index + 1) if 0 <= i < len(frames)]
        for when, value in [(frame, 1.0)] + [(neighbour, 0.0) for neighbour in neighbours]:
            key_block.value = value
            key_block.keyframe_insert("value", frame=when)
        key_block.value = 0.0
        fcurve = shape_key_value_fcurve(key, name)
        if fcurve is not None:
            for point in fcurve.keyframe_points:
                point.interpolation = 'LINEAR'
            fcurve.update()
