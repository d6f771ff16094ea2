"""The operators of the extension; their idnames and property names are a public API."""

import bpy

from . import analysis, output
from .analysis import classes as analysis_classes
from .base import shutdown_worker
from .frames import (SHAPE_DIFFERENCES_OT_frames_to_shape_keys, SHAPE_DIFFERENCES_OT_inbetween_frames,
                     SHAPE_DIFFERENCES_OT_retime)
from .poses import (SHAPE_DIFFERENCES_OT_exaggerate, SHAPE_DIFFERENCES_OT_inbetween,
                    SHAPE_DIFFERENCES_OT_reconstruct)
from .transfer import SHAPE_DIFFERENCES_OT_transfer_poses

classes = (
    SHAPE_DIFFERENCES_OT_frames_to_shape_keys,
    SHAPE_DIFFERENCES_OT_inbetween,
    SHAPE_DIFFERENCES_OT_exaggerate,
    SHAPE_DIFFERENCES_OT_reconstruct,
    SHAPE_DIFFERENCES_OT_inbetween_frames,
    SHAPE_DIFFERENCES_OT_retime,
    *analysis_classes,
    SHAPE_DIFFERENCES_OT_transfer_poses,
)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    analysis.register_handlers()
    output.register_handlers()


def unregister():
    output.unregister_handlers()
    analysis.unregister_handlers()
    _unregister_classes()
    shutdown_worker()
