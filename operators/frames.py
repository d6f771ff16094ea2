"""Operators on the evaluated animation of the active mesh (cloth, armature, any modifiers)."""

from contextlib import closing

import bpy
from bpy.props import IntProperty

from .. import bridge
from .base import (CoreSettingsProperties, GeneratorOperator, InputError, load_core,
                   surface_triangles)
from .poses import added_summary, inbetween_name


def frame_key_name(frame: int) -> str:
    return f"Frame {frame}"


class FrameRangeProperties:
    """Frame range properties; start and end default to the scene's range when not set."""

    frame_start: IntProperty(name="Start", description="First frame (default: the scene's start)")
    frame_end: IntProperty(name="End", description="Last frame (default: the scene's end)")
    frame_step: IntProperty(name="Step", min=1, default=1,
                            description="Take every n-th frame from the start")

    minimum_frames = 1

    def frames(self, context) -> list[int]:
        """The frames to read; resolved values are written back for the Redo panel."""
        scene = context.scene
        for name in ("frame_start", "frame_end"):
            if not self.properties.is_property_set(name):
                setattr(self, name, getattr(scene, name))
        frames = list(range(self.frame_start, self.frame_end + 1, self.frame_step))
        if len(frames) < self.minimum_frames:
            raise InputError(
                f"Frames {self.frame_start} to {self.frame_end} with step {self.frame_step} give "
                f"{len(frames)} frame{'s' if len(frames) != 1 else ''}, at least "
                f"{self.minimum_frames} are needed: widen the frame range or lower the step")
        return frames

    def read_frames(self, context, obj, frames: list[int], progress_share: float):
        """Yield progress while reading the evaluated mesh at ``frames``; returns the positions."""
        poses = []
        with closing(bridge.frame_positions(context, obj, frames)) as frame_reader:
            for frame, positions in frame_reader:
                poses.append(positions)
                yield progress_share * len(poses) / len(frames)
        return poses


class SHAPE_DIFFERENCES_OT_frames_to_shape_keys(FrameRangeProperties, GeneratorOperator,
                                                bpy.types.Operator):
    """Add one shape key per frame with the evaluated mesh (after cloth, armature and other
    modifiers) at that frame"""

    bl_idname = "shape_differences.frames_to_shape_keys"
    bl_label = "Frames to Shape Keys"

    def run(self, context):
        obj = context.active_object
        frames = self.frames(context)
        poses = yield from self.read_frames(context, obj, frames, 1.0)
        new_keys = [bridge.NewShapeKey(frame_key_name(frame), positions)
                    for frame, positions in zip(frames, poses)]
        self.summary = added_summary(bridge.add_shape_keys(obj, new_keys))


class SHAPE_DIFFERENCES_OT_inbetween_frames(CoreSettingsProperties, FrameRangeProperties,
                                            GeneratorOperator, bpy.types.Operator):
    """Take every n-th evaluated frame as a shape key, add in-between keys for each gap and
    keyframe the key values so playback shows the denser motion. Existing animation is kept: to
    see the keys play, disable the modifiers that made the motion (e.g. Cloth)"""

    bl_idname = "shape_differences.inbetween_frames"
    bl_label = "In-between Frames"

    frame_step: IntProperty(name="Step", min=1, default=4,
                            description="Take every n-th frame from the start as a key pose")
    count: IntProperty(name="Count", min=1, soft_max=20, default=3,
                       description="In-between keys per gap between two key poses")

    minimum_frames = 2

    def run(self, context):
        obj = context.active_object
        frames = self.frames(context)
        triangles = surface_triangles(obj)
        options = self.core_options(context, len(obj.data.vertices))
        poses = yield from self.read_frames(context, obj, frames, 0.2)
        sequence = load_core().SequenceInterpolator(poses, triangles, **options)
        new_keys, timeline = [], []
        for gap, (frame, next_frame) in enumerate(zip(frames, frames[1:])):
            new_keys.append(bridge.NewShapeKey(frame_key_name(frame), poses[gap]))
            timeline.append(frame)
            for i in range(1, self.count + 1):
                factor = i / (self.count + 1)
                new_keys.append(bridge.NewShapeKey(
                    inbetween_name(frame_key_name(frame), frame_key_name(next_frame), factor),
                    sequence.pose(gap, factor)))
                timeline.append(frame + factor * (next_frame - frame))
            yield 0.2 + 0.8 * (gap + 1) / (len(frames) - 1)
        new_keys.append(bridge.NewShapeKey(frame_key_name(frames[-1]), poses[-1]))
        timeline.append(frames[-1])
        names = bridge.add_shape_keys(obj, new_keys, keyframes=timeline)
        self.summary = added_summary(names) + f" (keyframed from frame {frames[0]} to {frames[-1]})"
