"""Scene settings of the extension: ``scene.shape_differences``."""

import bpy
from bpy.props import FloatProperty, IntProperty, StringProperty

from ..operators.base import CoreSettings


class ShapeDifferencesSettings(CoreSettings, bpy.types.PropertyGroup):
    """Core settings (the operators' defaults) and the panel's key pickers and counts."""

    key_a: StringProperty(name="From", description="First shape key (empty: the Basis)")
    key_b: StringProperty(name="To",
                          description="Second shape key (empty: the active key, or the last one)")
    count: IntProperty(name="Count", min=1, soft_max=50, default=3,
                       description="Number of in-between keys")
    key: StringProperty(name="Key", description="Pose to exaggerate or rebuild "
                                                "(empty: the active key)")
    reference: StringProperty(name="Reference",
                              description="Pose the change is measured from (empty: the Basis)")
    factor: FloatProperty(name="Factor", default=1.5, soft_min=0.0, soft_max=3.0,
                          description="1 = the key itself, above 1 exaggerates, below 1 tones down")
    frame_step: IntProperty(name="Step", min=1, default=4,
                            description="Take every n-th frame of the scene range as a key pose")
    frame_count: IntProperty(name="In-betweens", min=1, soft_max=20, default=3,
                             description="In-between keys per gap between two key poses")
