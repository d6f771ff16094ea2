"""View3D › Sidebar › "Shape Diff": settings and the operators with their key pickers."""

import bpy


class ShapeDiffPanel:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Shape Diff"

    def split_layout(self):
        """The panel layout with labels on the left, as Blender's property panels have."""
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        return layout


class VIEW3D_PT_shape_differences(ShapeDiffPanel, bpy.types.Panel):
    bl_label = "Shape Differences"

    def draw(self, context):
        layout = self.split_layout()
        settings = context.scene.shape_differences
        column = layout.column(align=True)
        column.prop(settings, "k_m")
        column.prop(settings, "k_n")
        layout.prop(settings, "offset")
        layout.prop(settings, "use_extrinsic")


def set_output(operator, settings, output_setting: str):
    """Pass the panel's output choice (``output_setting`` of the scene settings) and cache file
    to an operator button."""
    operator.output = getattr(settings, output_setting)
    operator.filepath = settings.filepath


def shape_keys_of(context):
    """The shape key datablock of the active mesh object, or None."""
    obj = context.active_object
    return obj.data.shape_keys if obj is not None and obj.type == 'MESH' else None


class VIEW3D_PT_shape_differences_poses(ShapeDiffPanel, bpy.types.Panel):
    bl_label = "Poses"
    bl_parent_id = "VIEW3D_PT_shape_differences"

    def draw(self, context):
        layout = self.split_layout()
        settings = context.scene.shape_differences
        # the output first: Transfer Keys (Animation panel) follows it onto a target that has no
        # shape keys yet
        layout.prop(settings, "pose_output")
        if settings.pose_output == 'CACHE':
            layout.prop(settings, "filepath")
        shape_keys = shape_keys_of(context)
        if shape_keys is None:
            obj = context.active_object
            text = ("The active mesh has no shape keys" if obj is not None and obj.type == 'MESH'
                    else "Select a mesh with shape keys: the active object is not a mesh")
            layout.label(text=text, icon='INFO')
            return

        def key_picker(column, name):
            column.prop_search(settings, name, shape_keys, "key_blocks", icon='SHAPEKEY_DATA')

        column = layout.column()
        key_picker(column, "key_a")
        key_picker(column, "key_b")
        column.prop(settings, "count")
        operator = column.operator("shape_differences.inbetween", icon='IPO_LINEAR')
        operator.key_a, operator.key_b, operator.count = (
            settings.key_a, settings.key_b, settings.count)
        set_output(operator, settings, "pose_output")

        layout.separator()
        column = layout.column()
        key_picker(column, "key")
        key_picker(column, "reference")
        column.prop(settings, "factor")
        row = column.row(align=True)
        operator = row.operator("shape_differences.exaggerate", icon='FORCE_FORCE')
        operator.key, operator.reference, operator.factor = (
            settings.key, settings.reference, settings.factor)
        set_output(operator, settings, "pose_output")
        operator = row.operator("shape_differences.reconstruct", icon='FILE_REFRESH')
        operator.key = settings.key
        set_output(operator, settings, "pose_output")


class VIEW3D_PT_shape_differences_animation(ShapeDiffPanel, bpy.types.Panel):
    bl_label = "Animation"
    bl_parent_id = "VIEW3D_PT_shape_differences"

    def draw(self, context):
        layout = self.split_layout()
        scene = context.scene
        settings = scene.shape_differences
        column = layout.column(align=True)
        # the range the operators default to: the preview range where it is on, as the timeline shows
        preview = "_preview" if scene.use_preview_range else ""
        column.prop(scene, f"frame{preview}_start", text="Preview Start" if preview else "Frame Start")
        column.prop(scene, f"frame{preview}_end", text="End")
        layout.prop(settings, "frame_step")
        layout.prop(settings, "output")
        if settings.output == 'CACHE':
            layout.prop(settings, "filepath")
        # With cache output the same operator bakes the evaluated frames into a cache object.
        label = "Frames to Cache" if settings.output == 'CACHE' else "Frames to Shape Keys"
        operator = layout.operator("shape_differences.frames_to_shape_keys", text=label, icon='KEYFRAME')
        operator.frame_step = settings.frame_step
        set_output(operator, settings, "output")
        layout.prop(settings, "frame_count")
        operator = layout.operator("shape_differences.inbetween_frames", icon='ANIM')
        operator.frame_step, operator.count = settings.frame_step, settings.frame_count
        set_output(operator, settings, "output")
        layout.prop(settings, "speed")
        operator = layout.operator("shape_differences.retime", icon='TIME')
        operator.frame_step, operator.speed = settings.frame_step, settings.speed
        set_output(operator, settings, "output")

        # Transfer: poses of another selected mesh (any connectivity) onto the active one.
        row = layout.row(align=True)
        operator = row.operator("shape_differences.transfer_poses", text="Transfer Keys", icon='MOD_DATA_TRANSFER')
        operator.source = 'KEYS'
        set_output(operator, settings, "pose_output")
        operator = row.operator("shape_differences.transfer_poses", text="Transfer Frames", icon='MOD_DATA_TRANSFER')
        operator.source, operator.frame_step = 'FRAMES', settings.frame_step
        set_output(operator, settings, "output")


class VIEW3D_PT_shape_differences_analysis(ShapeDiffPanel, bpy.types.Panel):
    """Shape space and distortion maps (operators/analysis.py); results stored on the object."""

    bl_label = "Analysis"
    bl_parent_id = "VIEW3D_PT_shape_differences"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        from ..bridge.analysis_data import stored_shape_space

        layout = self.layout
        row = layout.row(align=True)
        row.operator("shape_differences.shape_space", text="Space of Keys", icon='SHAPEKEY_DATA').source = 'KEYS'
        row.operator("shape_differences.shape_space", text="Space of Frames", icon='ANIM').source = 'FRAMES'
        data = stored_shape_space(context.active_object)
        if data is not None:
            column = layout.column(align=True)
            column.label(text=f"{len(data['poses'])} poses, k {data['k_M']}/{data['k_N'] or '-'}; PC 1 / PC 2 share:")
            for kind, variance in data["variance"].items():
                shares = " / ".join(f"{100 * value:.1f} %" for value in list(variance)[:2])
                column.label(text=f"  {kind.replace('_', ' ').title()}: {shares}")
            image = bpy.data.images.get(data["image"])
            if image is not None and image.preview is not None:
                layout.template_icon(icon_value=image.preview.icon_id, scale=8.0)
            row = layout.row(align=True)
            for text, step, icon in (("Previous", -1, 'TRIA_LEFT'), ("Next", 1, 'TRIA_RIGHT')):
                operator = row.operator("shape_differences.shape_space_select", text=text, icon=icon)
                operator.kind, operator.rank, operator.step = 'offset_area', -1, step
        layout.separator()
        row = layout.row(align=True)
        row.operator("shape_differences.distortion_maps", text="Maps of Active Key",
                     icon='MOD_VERTEX_WEIGHT').source = 'ACTIVE_KEY'
        row.operator("shape_differences.distortion_maps", text="Maps of Frames", icon='ANIM').source = 'FRAMES'


classes = (
    VIEW3D_PT_shape_differences,
    VIEW3D_PT_shape_differences_poses,
    VIEW3D_PT_shape_differences_animation,
    VIEW3D_PT_shape_differences_analysis,
)
