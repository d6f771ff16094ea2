"""The refusals of reading an object's frames as poses of its mesh (the message says why).
"""

from __future__ import annotations


class FrameReadError(ValueError):
    """The frames of an object cannot be read as the poses of its mesh (the message says why)."""


class VertexCountChanged(FrameReadError):
    """The evaluated mesh does not have the vertex count of the original mesh at some frame."""


class NotEvaluated(FrameReadError):
    """The object is not in the depsgraph (disabled in viewports): its modifiers are not computed."""


class CacheFileMissing(FrameReadError):
    """A cache modifier of the object reads a file that is not there: every frame is its rest mesh."""


class CacheFileUnfit(FrameReadError):
    """A cache modifier of the object reads a file that Blender cannot play on its mesh: a Mesh
    Cache of another vertex count or a damaged file (every frame is its rest mesh), or a cache whose
    frames are another mesh's vertices or this one's in another order (played scrambled)."""


class BakeFilesMissing(FrameReadError):
    """A cloth or soft body baked to disk plays none of its frames (its files are not where Blender
    looks, and every frame is the rest mesh), or holds one of its frames over frames read whose
    files are missing (a copy of the folder cut short); or a Geometry Nodes simulation zone baked to
    disk has none of its files where Blender looks, and would be simulated again."""
