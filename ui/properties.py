"""Scene settings of the extension: ``scene.shape_differences``, the sidebar's values and the
operators' defaults, built from the same property mixins as the operators."""

import bpy

from ..properties import (CoreSettings, ExaggeratedPose, FrameInbetweens, KeyPair, KeyStep,
                          SidebarOutputs, Speed)


class ShapeDifferencesSettings(CoreSettings, KeyPair, ExaggeratedPose, KeyStep, FrameInbetweens,
                               Speed, SidebarOutputs, bpy.types.PropertyGroup):
    """Core settings (the operators' defaults), the panel's key pickers, counts and outputs."""
