"""The extension loads like Blender loads it, exposes its public operator API and panel, and
keeps SciPy and cvxpy out of start-up."""

import os
import subprocess
import sys
import textwrap

import pytest

bpy = pytest.importorskip("bpy")

from dev_extension import MODULE, REPO_ROOT  # noqa: E402  (scripts/, put on sys.path by conftest)

SIZES = {"k_m", "k_n"}
BASIS = SIZES | {"use_extrinsic"}
CORE = BASIS | {"offset"}
OUTPUT = {"output", "filepath"}
#: The in-betweens' operators: their rotations come from the poses, and no offset distance changes them.
INBETWEENS = ("inbetween", "exaggerate", "inbetween_frames", "retime")
OPERATOR_PROPERTIES = {
    "frames_to_shape_keys": {"frame_start", "frame_end", "frame_step"} | OUTPUT,
    "inbetween": {"key_a", "key_b", "count"} | BASIS | OUTPUT,
    "exaggerate": {"key", "reference", "factor"} | BASIS | OUTPUT,
    "reconstruct": {"key"} | CORE | OUTPUT,
    "inbetween_frames": {"frame_start", "frame_end", "frame_step", "count"} | BASIS | OUTPUT,
    "retime": {"frame_start", "frame_end", "frame_step", "speed", "filepath"} | BASIS | OUTPUT,
    "shape_space": {"source", "frame_start", "frame_end", "frame_step", "k_m", "k_n", "offset"},
    "shape_space_select": {"kind", "rank", "step"},
    "distortion_maps": {"source", "key", "eigenfunctions", "frame_start", "frame_end", "frame_step", "k_m", "offset"},
    "transfer_poses": {"source", "matching", "map_attribute", "frame_start", "frame_end", "frame_step"} | SIZES | OUTPUT,
}


@pytest.mark.parametrize("name", sorted(OPERATOR_PROPERTIES))
def test_operator_public_api(extension, name):
    rna = getattr(bpy.ops.shape_differences, name).get_rna_type()
    assert OPERATOR_PROPERTIES[name] <= set(rna.properties.keys())


@pytest.mark.parametrize("name", INBETWEENS)
def test_the_inbetweens_take_no_offset(extension, name):
    """The in-betweens do not use the offset surface's distance (``core.Interpolator``: the rotations
    come from the poses): their operators have no Offset t, so a value set in the Redo panel or by a
    script cannot be silently ignored; a script passing one gets Blender's error naming it (before:
    accepted, and the in-betweens bit for bit those at any other offset)."""
    assert "offset" not in getattr(bpy.ops.shape_differences, name).get_rna_type().properties.keys()
    with pytest.raises(TypeError, match="offset"):
        getattr(bpy.ops.shape_differences, name)(offset=0.1)


@pytest.mark.parametrize("keyword", ["offset", "use_extrinsic"])
def test_transfer_takes_no_offset_nor_extrinsic(bpy_empty, extension, keyword):
    """*Transfer Poses* transfers intrinsic differences (``core.Transfer``'s default): no offset surface
    enters it, so it has neither Offset t nor Extrinsic, and a script passing one gets Blender's error
    naming it (before: both accepted, and the poses bit for bit those at any other value)."""
    from blender_scenes import transfer_pair

    transfer_pair(extension.bridge, 6, 4)  # the operator's poll passes: a source selected
    operator = bpy.ops.shape_differences.transfer_poses
    assert keyword not in operator.get_rna_type().properties.keys()
    with pytest.raises(TypeError, match=keyword):
        operator(**{keyword: 0.1 if keyword == "offset" else False})


def test_operators_register_and_undo():
    for name in OPERATOR_PROPERTIES:
        operator_class = getattr(bpy.types, f"SHAPE_DIFFERENCES_OT_{name}")
        assert {'REGISTER', 'UNDO'} <= operator_class.bl_options


def test_scene_settings(bpy_empty):
    settings = bpy.context.scene.shape_differences
    assert (settings.k_m, settings.k_n, settings.offset, settings.use_extrinsic) == (0, 0, 0.0, True)


def test_sidebar_panel(extension):
    panel = bpy.types.VIEW3D_PT_shape_differences
    assert (panel.bl_space_type, panel.bl_region_type, panel.bl_category) == (
        'VIEW_3D', 'UI', "Shape Diff")
    for child in ("VIEW3D_PT_shape_differences_poses", "VIEW3D_PT_shape_differences_animation"):
        assert getattr(bpy.types, child).bl_parent_id == "VIEW3D_PT_shape_differences"


def test_disable_and_enable_again(extension):
    import addon_utils
    addon_utils.disable(MODULE, default_set=True)
    assert not hasattr(bpy.types.Scene, "shape_differences")
    addon_utils.enable(MODULE, default_set=True)
    assert bpy.ops.shape_differences.inbetween.get_rna_type()
    assert hasattr(bpy.types.Scene, "shape_differences")


def test_enabling_does_not_import_scipy_or_cvxpy(tmp_path):
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(REPO_ROOT / "scripts")!r})
        import dev_extension
        dev_extension.enable()
        print("LOADED", sorted(m for m in ("scipy", "cvxpy", "clarabel") if m in sys.modules))
    """)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            env=env, timeout=120)
    assert "LOADED []" in result.stdout, result.stdout + result.stderr


class RecordingLayout:
    """Stands in for a UILayout (panels do not draw headless): checks that every property,
    key picker and operator the panel draws exists, and records the operators' settings."""

    def __init__(self):
        self.operators, self.labels, self.props = [], [], []

    def column(self, align=False):
        return self

    row = column

    def label(self, text="", icon='NONE'):
        self.labels.append(text)

    def separator(self):
        pass

    def prop(self, data, name, **_options):
        assert name in data.bl_rna.properties, name
        self.props.append(name)

    def prop_search(self, data, name, search_data, search_name, **_options):
        assert name in data.bl_rna.properties and search_name in search_data.bl_rna.properties

    def operator(self, idname, **_options):
        module, name = idname.split(".")
        properties = getattr(getattr(bpy.ops, module), name).get_rna_type().properties
        recorded = OperatorButton(idname, properties)
        self.operators.append(recorded)
        return recorded


class OperatorButton:
    def __init__(self, idname, properties):
        object.__setattr__(self, "idname", idname)
        object.__setattr__(self, "settings", {})
        object.__setattr__(self, "properties", properties)

    def __setattr__(self, name, value):
        assert name in self.properties, f"{self.idname} has no property {name}"
        self.settings[name] = value


def draw_panels(extension, layout=None):
    """Draw every Shape Diff panel into a RecordingLayout; return the operator buttons."""
    layout = RecordingLayout() if layout is None else layout
    for name in ("VIEW3D_PT_shape_differences", "VIEW3D_PT_shape_differences_poses",
                 "VIEW3D_PT_shape_differences_animation", "VIEW3D_PT_shape_differences_analysis"):
        panel = getattr(bpy.types, name)
        panel_self = type("PanelSelf", (), {"layout": layout,
                                            "split_layout": panel.split_layout})()
        panel.draw(panel_self, bpy.context)
    return [(button.idname, button.settings) for button in layout.operators]


def test_panel_draws_settings_and_operators(bpy_empty, extension):
    from blender_scenes import posed_grid
    bpy.ops.mesh.primitive_grid_add()
    # a mesh without shape keys (a transfer's target): the Poses panel still shows the output that
    # Transfer Keys follows
    layout = RecordingLayout()
    draw_panels(extension, layout)
    assert "The active mesh has no shape keys" in layout.labels and "pose_output" in layout.props
    assert [idname for idname, _ in draw_panels(extension)] == [
        "shape_differences.frames_to_shape_keys", "shape_differences.inbetween_frames",
        "shape_differences.retime", *["shape_differences.transfer_poses"] * 2, *["shape_differences.shape_space"] * 2,
        *["shape_differences.distortion_maps"] * 2]
    bpy.context.scene.use_preview_range = True  # the Animation panel shows the preview range then
    assert len(draw_panels(extension)) == 9
    bpy.context.scene.use_preview_range = False

    posed_grid(extension.bridge, 4)
    settings = bpy.context.scene.shape_differences
    settings.key_a, settings.key_b, settings.count, settings.factor = "Curl", "Bend", 5, 2.0
    buttons = dict(draw_panels(extension))
    # Select Pose appears once a shape space is stored (tests/blender/test_analysis_operators.py).
    assert set(buttons) == {f"shape_differences.{name}" for name in OPERATOR_PROPERTIES} - {
        "shape_differences.shape_space_select"}
    assert buttons["shape_differences.inbetween"] == {"key_a": "Curl", "key_b": "Bend",
                                                      "count": 5, "output": 'SHAPE_KEYS',
                                                      "filepath": ""}
    assert buttons["shape_differences.retime"]["output"] == 'CACHE'
    settings.pose_output, settings.speed = 'CACHE', 0.25
    buttons = dict(draw_panels(extension))
    assert buttons["shape_differences.exaggerate"]["output"] == 'CACHE'
    assert buttons["shape_differences.retime"]["speed"] == 0.25
    assert buttons["shape_differences.exaggerate"]["factor"] == 2.0


def test_poses_panel_says_what_is_missing(bpy_empty, extension):
    """No mesh active: the Poses panel says so (before: "The active mesh has no shape keys" for a
    camera or for nothing at all)."""
    for make, expected in ((lambda: None, "the active object is not a mesh"),
                           (lambda: bpy.ops.object.camera_add(), "the active object is not a mesh"),
                           (lambda: bpy.ops.mesh.primitive_grid_add(), "The active mesh has no shape keys")):
        make()
        layout = RecordingLayout()
        draw_panels(extension, layout)
        assert any(expected in text for text in layout.labels), layout.labels


def test_properties_are_declared_once(bpy_empty):
    """The operators and the scene settings share one declaration of each property (the
    mixins of properties.py): same type, default and limits; ui does not import operators."""
    settings = bpy.context.scene.shape_differences.bl_rna.properties
    shared = {"inbetween": ["key_a", "key_b", "count", "k_m", "k_n", "use_extrinsic"],
              "exaggerate": ["key", "reference", "factor"], "retime": ["speed", "frame_step"],
              "reconstruct": ["k_m", "k_n", "offset", "use_extrinsic"], "transfer_poses": ["k_m", "k_n"],
              "inbetween_frames": [("count", "frame_count")]}
    for operator, names in shared.items():
        properties = getattr(bpy.ops.shape_differences, operator).get_rna_type().properties
        for name in names:
            mine, scene_name = (name, name) if isinstance(name, str) else name
            a, b = properties[mine], settings[scene_name]
            assert (a.type, a.description) == (b.type, b.description), name
            if a.type in ('INT', 'FLOAT'):
                assert (a.default, a.hard_min, a.hard_max) == (b.default, b.hard_min, b.hard_max)
    source = (REPO_ROOT / "ui" / "properties.py").read_text() + (REPO_ROOT / "ui" / "panel.py").read_text()
    assert "..operators" not in source and "operators.base" not in source


def test_path_properties_accept_paths_relative_to_the_blend(bpy_empty):
    """Every file path property takes '//' paths (relative to the .blend) without Blender 5's
    warning that the property does not support them."""
    owners = [getattr(bpy.ops.shape_differences, name).get_rna_type() for name in OPERATOR_PROPERTIES]
    owners.append(bpy.context.scene.shape_differences.bl_rna)
    paths = [p for rna in owners for p in rna.properties if p.type == 'STRING' and p.subtype == 'FILE_PATH']
    assert {p.identifier for p in paths} == {"filepath", "map_file", "source_map_file"}
    if not hasattr(paths[0], "is_path_supports_blend_relative"):
        pytest.skip("this Blender has no blend-relative path option")
    assert all(p.is_path_supports_blend_relative for p in paths)
