"""The scene's time: setting it to frames and sub-frames in turn (and back), and the time it plays at
a frame under its Time Stretching.
"""

from __future__ import annotations

import bpy
import numpy as np


def at_times(scene: bpy.types.Scene, times):
    """Set ``scene`` to each of ``times`` (frames; a fraction is a sub-frame) in turn, yielding
    it; the scene's current frame and sub-frame restored afterwards if it was moved (setting a
    frame is not free: at a cloth's start frame Blender builds the cloth again, ~35 ms at 10k
    vertices, where another frame of its baked cache takes ~0.5 ms)."""
    original_frame, original_subframe = scene.frame_current, scene.frame_subframe
    moved = False
    try:
        for time in times:
            whole = int(np.floor(time))
            scene.frame_set(whole, subframe=float(time - whole))
            moved = True
            yield time
    finally:
        if moved:
            scene.frame_set(original_frame, subframe=original_subframe)


def scene_time(scene: bpy.types.Scene, frame: float) -> float:
    """The time at which ``scene`` evaluates animation, caches and simulations at ``frame``: the
    frame itself, or scaled by the scene's *Time Stretching* (Output › Frame Range: old / new;
    what ``frame_current_final`` shows), where keyframes and a Mesh Cache must sit to play at
    ``frame``."""
    return frame * scene.render.frame_map_old / scene.render.frame_map_new
