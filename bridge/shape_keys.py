"""Writing shape keys: new keys with their coordinates and free names, removed again on failure, and
keyframes of their values that step playback through them.
"""

from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

from .naming import unique_name

BASIS_NAME = "Basis"


@dataclass
class NewShapeKey:
    """A shape key to be written: its wanted name and coordinates. ``name`` may be shortened to
    fit Blender's limit; ``tail`` (e.g. the factor) is always kept."""

    name: str
    positions: np.ndarray
    tail: str = ""


def unique_key_name(obj: bpy.types.Object, name: str, tail: str = "") -> str:
    """A shape key name for ``name + tail`` (see :func:`bridge.naming.unique_name`) that no key of
    ``obj`` has, no F-curve of its keys' action (its slot's) animates, and no key of another mesh
    playing that action (and slot) has: a new key of such a name would have its keyframes written
    into that F-curve, which may be another mesh's (an action shared between meshes) or a deleted
    key's, and its value played by it."""
    key = obj.data.shape_keys
    if key is None:
        return unique_name(name, tail, ())
    return unique_name(name, tail, _TakenKeyNames(key))


class _TakenKeyNames:
    """The names :func:`unique_key_name` leaves out for the keys ``key``, as a container (``in``)."""

    def __init__(self, key: bpy.types.Key):
        self.names = set(key.key_blocks.keys())
        self.paths = {fcurve.data_path for fcurve in key_fcurves(key)}
        animation = key.animation_data
        action = animation.action if animation else None
        if action is not None:
            slot = getattr(animation, "action_slot", None)  # Blender 4.4+
            for other in bpy.data.shape_keys:
                played = other.animation_data
                if other != key and played is not None and played.action == action and \
                        getattr(played, "action_slot", None) == slot:
                    self.names.update(other.key_blocks.keys())

    def __contains__(self, name: str) -> bool:
        return name in self.names or key_value_path(name) in self.paths


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
            key_block = obj.shape_key_add(name=unique_key_name(obj, new_key.name, new_key.tail),
                                           from_mix=False)
            added.append(key_block)
            key_block.value = 0.0
            # ``points``: the bulk write (:func:`bridge.mesh_data.stored_key_positions`)
            key_block.points.foreach_set(
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
    """Remove the named shape keys (and the Basis too if ``remove_basis``). The active key, where it
    is not one of them, stays active (Blender moves the active index down on each removal)."""
    key = obj.data.shape_keys
    if key is None:
        return
    active = obj.active_shape_key.name if obj.active_shape_key is not None else None
    for name in names:
        key_block = key.key_blocks.get(name)
        if key_block is not None:
            obj.shape_key_remove(key_block)
    if remove_basis and obj.data.shape_keys is not None and len(obj.data.shape_keys.key_blocks) == 1:
        obj.shape_key_remove(obj.data.shape_keys.key_blocks[0])
    elif active in key.key_blocks:
        obj.active_shape_key_index = key.key_blocks.find(active)
    obj.data.update()


def key_value_path(key_name: str) -> str:
    """The data path of the value of the shape key ``key_name``, as its F-curve names it."""
    return f'key_blocks["{bpy.utils.escape_identifier(key_name)}"].value'


def key_fcurves(key: bpy.types.Key):
    """The F-curves of ``key``'s action that animate it (legacy actions, or the slot it plays in
    Blender 4.4+'s slotted ones); none without an action."""
    animation_data = key.animation_data
    action = animation_data.action if animation_data else None
    if action is None:
        return ()
    if hasattr(animation_data, "action_slot"):  # Blender 4.4+: layered actions with slots
        from bpy_extras import anim_utils
        channelbag = anim_utils.action_get_channelbag_for_slot(action, animation_data.action_slot)
        return channelbag.fcurves if channelbag else ()
    return action.fcurves


def shape_key_value_fcurve(key: bpy.types.Key, key_name: str):
    """The F-curve animating ``key_blocks[key_name].value`` (legacy and slotted actions)."""
    data_path = key_value_path(key_name)
    return next((fcurve for fcurve in key_fcurves(key) if fcurve.data_path == data_path), None)


def keyframe_key_values(obj: bpy.types.Object, timeline: list[tuple[float, str]]):
    """Keyframe the values of the named shape keys so that playback steps through them.

    ``timeline`` is ``(frame, key name)`` in increasing frame order: each key gets value 1 at its
    frame and 0 at the frames of its neighbours, with linear interpolation, so between two samples
    the mesh blends linearly from one key to the next. Only F-curves of these keys are written, and only
    the keyframes inserted here are made linear.
    """
    key = obj.data.shape_keys
    frames = [frame for frame, _ in timeline]
    for index, (frame, name) in enumerate(timeline):
        key_block = key.key_blocks[name]
        neighbours = [frames[i] for i in (index - 1, index + 1) if 0 <= i < len(frames)]
        inserted = [(frame, 1.0)] + [(neighbour, 0.0) for neighbour in neighbours]
        for when, value in inserted:
            key_block.value = value
            key_block.keyframe_insert("value", frame=when)
        key_block.value = 0.0
        fcurve = shape_key_value_fcurve(key, name)
        if fcurve is not None and len(fcurve.keyframe_points):  # only the points inserted here
            points = fcurve.keyframe_points
            for when, _ in inserted:  # the point at that frame (stored in single precision: the nearest)
                min(points, key=lambda point: abs(point.co[0] - when)).interpolation = 'LINEAR'
            fcurve.update()
