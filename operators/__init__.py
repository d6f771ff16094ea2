"""The operators of the extension; their idnames and property names are a public API."""

import bpy

from .frames import SHAPE_DIFFERENCES_OT_frames_to_shape_keys, SHAPE_DIFFERENCES_OT_inbetween_frames
from .poses import (SHAPE_DIFFERENCES_OT_exaggerate, SHAPE_DIFFERENCES_OT_inbetween,
                    SHAPE_DIFFERENCES_OT_reconstruct)
from .transfer import SHAPE_DIFFERENCES_OT_transfer_poses

classes = (
    SHAPE_DIFFERENCES_OT_frames_to_shape_keys,
    SHAPE_DIFFERENCES_OT_inbetween,
    SHAPE_DIFFERENCES_OT_exaggerate,
    SHAPE_DIFFERENCES_OT_reconstruct,
    SHAPE_DIFFERENCES_OT_inbetween_frames,
    SHAPE_DIFFERENCES_OT_transfer_poses,
)

register, unregister = bpy.utils.register_classes_factory(classes)
