"""Sidebar panel and scene settings."""

import bpy

from .panel import classes as panel_classes
from .properties import ShapeDifferencesSettings

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(
    (ShapeDifferencesSettings, *panel_classes))


def register():
    _register_classes()
    bpy.types.Scene.shape_differences = bpy.props.PointerProperty(type=ShapeDifferencesSettings)


def unregister():
    del bpy.types.Scene.shape_differences
    _unregister_classes()
