"""Handlers Blender calls on its own (frame change, file load, undo and redo, save) that never throw
a :class:`MemoryError` into it: where memory runs out inside one, that call is skipped and said once
per handler and session on the console. A handler has no operator to report to, and Blender prints
a traceback of each failing call: at every frame of playback, for a frame-change handler. The next
call tries again (memory may have been freed meanwhile); what the handler keeps up (a map shown per
frame, an image drawn again) is only for show, or said where it matters (a cache not copied).
"""

from __future__ import annotations

import functools
import sys

import bpy

#: The handlers (by name) whose running out of memory was said this session.
_SAID: set[str] = set()


def skipped_out_of_memory(doing: str, skipped: str = "skipped there, and tried again each time"):
    """A decorator making a function a persistent Blender handler whose call is skipped where memory
    runs out, said once: ``doing`` what the handler does, in the user's words ("while showing the
    distortion map of each frame"), ``skipped`` what that leaves and what to do."""
    def guard(handler):
        @functools.wraps(handler)
        def guarded(*args):
            try:
                return handler(*args)
            except MemoryError as error:
                if handler.__name__ not in _SAID:
                    _SAID.add(handler.__name__)
                    said = " ".join(str(error).split())
                    print(f"Shape Differences: ran out of memory{f' ({said})' if said else ''} {doing}: "
                          f"{skipped} (said once); close other programs to free memory", file=sys.stderr)
            return None
        return bpy.app.handlers.persistent(guarded)
    return guard
