"""Every user-facing property of the extension, declared once as a mixin (the glTF-Blender-IO
pattern). The operators and the scene settings (``scene.shape_differences``, the sidebar's
defaults) both inherit from these, so a name, range, default and tooltip is written in one place.

This module imports only ``bpy``'s properties and types: ``ui`` and ``operators`` both build on it.
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

#: Options of a path property: Blender 5.0 warns when a path property without
#: 'PATH_SUPPORTS_BLEND_RELATIVE' is given a path relative to the .blend ('//'); 4.2 does not know
#: the option.
PATH_OPTIONS = ({'ANIMATABLE', 'PATH_SUPPORTS_BLEND_RELATIVE'}
                if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties else {'ANIMATABLE'})


class BasisSizes:
    """The core's basis sizes: the scene settings and each core operator have them, *Transfer
    Poses* these alone (it transfers intrinsic differences: no offset surface, no Extrinsic).
    Soft limits only: Blender would clamp a script's −5 to 0 (the full basis) silently; the core
    reports them (``core.validation``), and the operators by their labels."""

    k_m: IntProperty(
        name="k_M", soft_min=0, default=0,
        description="Basis size on the base pose: Laplacian eigenfunctions of the base mesh and of its "
                    "offset surface (eqs. 5-6); 0 = full basis, exact")
    k_n: IntProperty(
        name="k_N", soft_min=0, default=0,
        description="Basis size on the target pose (functional map from the vertex correspondence, "
                    "eq. 6); needs k_M; 0 = target not truncated (eq. 5)")


class BasisSettings(BasisSizes):
    """The basis sizes and the core's Extrinsic switch: the in-betweens (*In-between*,
    *Exaggerate*, *In-between Frames*, *Retime*) have these alone: their rotations come from the
    poses, and no offset surface's distance changes them."""

    use_extrinsic: BoolProperty(
        name="Extrinsic", default=True,
        description="Use extrinsic (offset surface) shape differences as well as intrinsic ones")


class CoreSettings(BasisSettings):
    """The core's settings with the offset surface's distance: the scene settings and
    *Reconstruct* have them. The
    offset has a soft limit only, as the sizes: the operators report a negative one by its label
    (``operators.base.offset_option``), where Blender would take the automatic distance silently."""

    offset: FloatProperty(
        name="Offset t", soft_min=0.0, default=0.0, subtype='DISTANCE',
        description="Distance of the offset surface that carries the extrinsic information; "
                    "0 = automatic (scales with the mesh). Reconstruct and the analysis measure on it; "
                    "the in-betweens and Transfer Poses do not use it")


class AnalysisBasis:
    """Basis sizes and offset of the analysis operators. The shape space needs a truncated basis, so
    they do not follow the scene's k_M / k_N, whose default is the full basis. Soft limits only, as
    in :class:`CoreSettings`."""

    k_m: IntProperty(name="k_M", soft_min=2, default=50,
                     description="Basis size on the base: the differences compared are k_M × k_M")
    k_n: IntProperty(name="k_N", soft_min=0, default=100,
                     description="Basis size on each pose (eq. 6); 0 = differences in the base's basis "
                                 "only (eq. 5), much faster")
    offset: FloatProperty(name="Offset t", soft_min=0.0, default=0.0, subtype='DISTANCE',
                          description="Offset surface distance; 0 = the scene setting, or automatic")


def _count_property(description: str):
    # No hard minimum: Blender would clamp 0 to 1 silently; the operators report counts below 1.
    return IntProperty(name="Count", soft_min=1, soft_max=20, default=3, description=description)


class KeyPair:
    """The two shape keys an in-between goes from and to, and how many in-betweens."""

    key_a: StringProperty(name="From", description="First shape key (empty: the Basis)")
    key_b: StringProperty(
        name="To", description="Second shape key (empty: the active key, or the last one)")
    count: _count_property("Number of in-between poses, evenly spaced between the two keys")


class PoseKey:
    """The shape key to exaggerate or rebuild."""

    key: StringProperty(name="Key", description="Pose to exaggerate or rebuild "
                                                "(empty: the active key)")


class ExaggeratedPose(PoseKey):
    """The pose to exaggerate, the reference it is measured from, the factor."""

    reference: StringProperty(name="Reference",
                              description="Pose the change is measured from (empty: the Basis)")
    factor: FloatProperty(name="Factor", default=1.5, soft_min=0.0, soft_max=3.0,
                          description="1 = the key itself, above 1 exaggerates, below 1 tones down")


def _step_property(default: int, description: str):
    # No hard minimum: Blender would clamp 0 (or a negative step) to 1 silently; the operators report steps below 1.
    return IntProperty(name="Step", soft_min=1, default=default, description=description)


class KeyStep:
    """Key poses every n-th frame of the animation."""

    frame_step: _step_property(4, "Take every n-th frame from the start as a key pose")


_PER_GAP = "In-between poses per gap between two key frames"


class InbetweensPerGap:
    """In-betweens per gap between two key frames (an operator's ``count``)."""

    count: _count_property(_PER_GAP)


class FrameInbetweens:
    """The same for the scene settings, where ``count`` is the Poses panel's."""

    frame_count: _count_property(_PER_GAP)


class CaptureStep:
    """Frames to capture: every n-th."""

    frame_step: _step_property(1, "Take every n-th frame from the start")


class Speed:
    """Playback speed of a retimed animation."""

    speed: FloatProperty(
        name="Speed", default=0.5, soft_min=0.1, soft_max=4.0,  # speed <= 0 is reported, not clamped
        description="Playback speed of the retimed motion: 0.5 = twice as slow (twice the frames), "
                    "1 = the original timing with the dropped frames rebuilt, 2 = twice as fast")


OUTPUT_ITEMS = (
    ('SHAPE_KEYS', "Shape Keys",
     "Add the poses as shape keys of the active object (its modifiers still deform them)"),
    ('CACHE', "Point Cache",
     "Write the poses to a PC2 file played by a Mesh Cache modifier on a new object (a copy of "
     "the mesh: poses of shape keys under copies of its modifiers, as the keys are; captured "
     "frames without the modifiers that moved them); the active object stays as it was"),
)


def _output_property(default: str):
    return EnumProperty(name="Output", items=OUTPUT_ITEMS, default=default,
                        description="Where the poses go")


_FILEPATH = StringProperty(
    name="Cache File", subtype='FILE_PATH', default="", options=PATH_OPTIONS,
    description="PC2 file for Point Cache output (an existing file is never overwritten: a "
                "numbered name is used); empty = a file named after the new object in a 'caches' "
                "folder beside the .blend (Blender's temporary folder while the .blend is unsaved); "
                "a relative path is taken beside the saved .blend (the folder Blender was started "
                "from while the .blend is unsaved)")


class PoseOutput:
    """Output choice of operators on shape keys: shape keys unless asked otherwise."""

    output: _output_property('SHAPE_KEYS')
    filepath: _FILEPATH


class AnimationOutput:
    """Output choice of operators on a modifier-driven animation: a cache on a new object,
    because keys added to the animated object are deformed again by its modifiers."""

    output: _output_property('CACHE')
    filepath: _FILEPATH


class SidebarOutputs:
    """The sidebar's output choices: one for the Poses panel, one for the Animation panel."""

    pose_output: _output_property('SHAPE_KEYS')
    output: _output_property('CACHE')
    filepath: _FILEPATH
