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


def unique_key_name(obj: bpy.types.Object, name: str, tail: str = "", *, keyframed: bool = False) -> str:
    """A shape key name for ``name + tail`` (see :func:`bridge.naming.unique_name`) that no key of
    ``obj`` has, nor any key of another mesh playing its keys' action (and slot: :func:`played_key_names`,
    as its action or through an NLA strip): a key's value is animated by the F-curve of its name, so
    another mesh's key of that name would be played by the new key's keyframes. Nor one a dead F-curve
    there animates (its key removed: Blender keeps the F-curve, which would play the new key at its old
    keyframes), unless the new key is ``keyframed`` (:func:`keyframe_key_values` empties that curve first,
    so a run again into a mesh whose earlier keys were deleted names its keys as before) and the curve is
    not muted, locked, given modifiers or extrapolated linearly."""
    key = obj.data.shape_keys
    if key is None:
        return unique_name(name, tail, ())
    return unique_name(name, tail, _TakenKeyNames(key, keyframed))


def played_key_names(key: bpy.types.Key) -> set[str]:
    """The names of the keys of ``key`` and of every other mesh's keys that play ``key``'s action in
    the same slot, as their action or through one of their NLA strips: the keys an F-curve of that
    action (slot) animates, where one has its name."""
    names = set(key.key_blocks.keys())
    animation = key.animation_data
    action = animation.action if animation else None
    if action is None:
        return names
    slot = getattr(animation, "action_slot", None)  # Blender 4.4+

    def plays(data) -> bool:  # AnimData or NlaStrip
        return data.action == action and getattr(data, "action_slot", None) == slot

    for other in bpy.data.shape_keys:
        played = other.animation_data
        if other == key or played is None:
            continue
        if plays(played) or any(plays(strip) for track in played.nla_tracks for strip in track.strips):
            names.update(other.key_blocks.keys())
    return names


def dead_key_curves(key: bpy.types.Key) -> dict[str, list[dict]]:
    """The keyframes (:func:`keyframes_of`) of the F-curves of ``key``'s action (slot) that animate the
    value of no key playing it (:func:`played_key_names`: keys removed since, whose F-curves Blender
    keeps), by data path: what a new key of such a name, keyframed, empties (:func:`keyframe_key_values`),
    for a take-back to give back."""
    alive = {key_value_path(name) for name in played_key_names(key)}
    return {fcurve.data_path: keyframes_of(fcurve) for fcurve in key_fcurves(key)
            if fcurve.data_path.startswith("key_blocks[") and fcurve.data_path.endswith("].value")
            and fcurve.data_path not in alive}


class _TakenKeyNames:
    """The names :func:`unique_key_name` leaves out for the keys ``key``, as a container (``in``)."""

    def __init__(self, key: bpy.types.Key, keyframed: bool):
        self.names = played_key_names(key)
        # with keyframes, a dead F-curve's name is free (emptied first), unless the curve would still
        # change what the key plays: muted, locked, with modifiers (a Noise plays without points) or
        # extrapolated linearly (the value past the first and last keyframes)
        self.paths = {fcurve.data_path for fcurve in key_fcurves(key)
                      if not keyframed or fcurve.mute or fcurve.lock or len(fcurve.modifiers)
                      or fcurve.extrapolation != 'CONSTANT'}

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
            key_block = obj.shape_key_add(name=unique_key_name(obj, new_key.name, new_key.tail,
                                                               keyframed=keyframes is not None), from_mix=False)
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


#: What :func:`keyframes_of` keeps of each keyframe: enough to put an F-curve back as it was.
KEYFRAME_FIELDS = ("handle_left_type", "handle_right_type", "co", "handle_left", "handle_right",
                   "interpolation", "easing", "type")


def keyframes_of(fcurve) -> list[dict]:
    """``fcurve``'s keyframes, each a dict of :data:`KEYFRAME_FIELDS`, for :func:`set_keyframes`."""
    return [{field: (tuple(value) if field in ("co", "handle_left", "handle_right") else value)
             for field in KEYFRAME_FIELDS for value in (getattr(point, field),)}
            for point in fcurve.keyframe_points]


def set_keyframes(fcurve, keyframes: list[dict]) -> None:
    """Give ``fcurve`` exactly ``keyframes`` (:func:`keyframes_of`), in place of those it has."""
    points = fcurve.keyframe_points
    points.clear()
    points.add(len(keyframes))
    for point, keyframe in zip(points, keyframes):
        for field in KEYFRAME_FIELDS:  # the handle types first: setting them may move the handles
            setattr(point, field, keyframe[field])
    fcurve.update()


def keyframe_key_values(obj: bpy.types.Object, timeline: list[tuple[float, str]]):
    """Keyframe the values of the named shape keys so that playback steps through them.

    ``timeline`` is ``(frame, key name)`` in increasing frame order: each key gets value 1 at its
    frame and 0 at the frames of its neighbours, with linear interpolation, so between two samples
    the mesh blends linearly from one key to the next. Only F-curves of these keys are written: new ones,
    or that of a key of the name removed since (its keyframes cleared first: :func:`unique_key_name`), so
    every point on them is one inserted here.
    """
    key = obj.data.shape_keys
    frames = [frame for frame, _ in timeline]
    for index, (frame, name) in enumerate(timeline):
        key_block = key.key_blocks[name]
        dead = shape_key_value_fcurve(key, name)  # the F-curve of a key removed since (unique_key_name)
        if dead is not None:
            dead.keyframe_points.clear()
        neighbours = [frames[i] for i in (index - 1, index + 1) if 0 <= i < len(frames)]
        for when, value in [(frame, 1.0)] + [(neighbour, 0.0) for neighbour in neighbours]:
            key_block.value = value
            key_block.keyframe_insert("value", frame=when)
        key_block.value = 0.0
        fcurve = shape_key_value_fcurve(key, name)
        if fcurve is not None:  # its own, every point inserted here
            for point in fcurve.keyframe_points:
                point.interpolation = 'LINEAR'
            fcurve.update()
