"""Operators that show what the shape differences reveal (paper §8.1, distortion maps): the shape
space of the shape keys or frames of the active mesh, drawn into an image, and distortion maps
written as attributes. Neither changes positions, shape keys or animation: the shape space writes
an image and custom properties, the distortion maps write mesh attributes only.
"""

import re
import sys

import bpy
import numpy as np
from bpy.props import EnumProperty, IntProperty, StringProperty

from ..bridge import analysis_data, naming, triangulation, world_space
from ..properties import AnalysisBasis, CaptureStep
from .motion_sources import refuse_emptying_caches, simulations_emptied_by, zone_frames_dropped
from .output import require_local
from .base import (MEASURED_IN_WORLD, SCENE_SETTING, GeneratorOperator, InputError, check_basis_order,
                   check_basis_size, default_pose_key, frame_name, in_world, key_blocks_of, key_pose, mesh_pose,
                   offset_option, ran_out_of_memory, refused_in_poll, report, resolve_key, surface_triangles)
from .frames import FrameRangeProperties, frame_key_name
from .handler_guard import skipped_out_of_memory

KINDS = ("area", "conformal", "offset_area", "offset_conformal")
KIND_ITEMS = [
    ("offset_area", "Offset Area", "Area-based differences of the offset surface (extrinsic)"),
    ("offset_conformal", "Offset Conformal", "Conformal differences of the offset surface (extrinsic)"),
    ("area", "Area", "Area-based differences (intrinsic)"),
    ("conformal", "Conformal", "Conformal differences (intrinsic)"),
]
SOURCE_ITEMS = [
    ("KEYS", "Shape Keys", "Every shape key of the active mesh; the first (Basis) is the base"),
    ("FRAMES", "Frames", "The evaluated mesh (cloth, armature, any modifiers) at each frame of the "
                         "range; the first frame is the base"),
]


class AnalysisBasisProperties(AnalysisBasis):
    """The analysis operators' basis sizes (declared in :mod:`properties`) and their checks."""

    def resolved_offset(self, context):
        if self.offset:
            return offset_option(self.offset)
        return offset_option(context.scene.shape_differences.offset, SCENE_SETTING)

    def check_sizes(self, triangles, *, uses_k_n: bool = True):
        """Refuse sizes the mesh of ``triangles`` cannot have; the defaults (sizes not given) shrink
        to a small mesh (k_N to its vertex count less one, k_M to k_N), written back for the Redo
        panel. Its vertex count is of those in triangles: loose vertices have no eigenfunctions.
        ``uses_k_n=False``: only k_M is used (the distortion maps' eigenfunctions), k_N is ignored."""
        # negative sizes first, in the settings' terms: k_M must be a size here (the analysis needs a truncated basis)
        check_basis_size("k_M", self.k_m)
        if uses_k_n:
            check_basis_size("k_N", self.k_n, zero="0 for the differences in the base's basis only")
        vertex_count = int(np.unique(triangles).size)
        if uses_k_n and not self.properties.is_property_set("k_n"):
            self.k_n = min(self.k_n, vertex_count - 1)
        if not self.properties.is_property_set("k_m"):
            self.k_m = max(2, min(self.k_m, (self.k_n if uses_k_n else 0) or vertex_count - 1))
        for label, k in (("k_M", self.k_m), ("k_N", self.k_n))[:2 if uses_k_n else 1]:
            if k >= vertex_count:
                raise InputError(f"{label} = {k} is too large for a mesh with {vertex_count} vertices in faces: "
                                 f"use at most {vertex_count - 1}")
        if uses_k_n:
            check_basis_order(self.k_m, self.k_n)


def _drive(steps, start: float, share: float):
    """Run a core generator, yielding its progress mapped to ``start + share * p``; return its value."""
    while True:
        try:
            progress = next(steps)
        except StopIteration as done:
            return done.value
        yield start + share * progress


# -- shape space ------------------------------------------------------------------------------------

#: What each shape-space image was last drawn from (:func:`drawn_from`), by the image's
#: ``session_uid``, which undo and redo keep: Python state, so undo does not restore it with the file.
_DRAWN: dict[int, str] = {}


def drawn_from(data: dict, highlight: int | None) -> str:
    """The stored coordinates, variance and highlighted pose a shape-space image shows, as text to compare."""
    return repr((data["coordinates"], data["variance"], highlight))


#: The custom property that marks an image as one Shape Space draws into (:func:`shape_space_image_name`).
SHAPE_SPACE_IMAGE_MARK = "shape_differences_shape_space"


def shape_space_image_name(obj, before: dict | None) -> str:
    """The image a new shape space of ``obj`` is drawn into: the one its shape space stored ``before``
    (None: none) was drawn into, where that image is marked as Shape Space's
    (:data:`SHAPE_SPACE_IMAGE_MARK`) and no other object's stored shape space names it (a duplicated object
    copies the stored shape space, and its image with it); else "Shape Space <object>", numbered (.001, …)
    where an image has that name: the user's own, or another object's (one renamed since its shape space
    was drawn), which a run must not draw over."""
    name = before.get("image") if before else None
    image = bpy.data.images.get(name) if isinstance(name, str) else None
    if image is not None and image.get(SHAPE_SPACE_IMAGE_MARK) and not any(
            (analysis_data.stored_shape_space(other) or {}).get("image") == name
            for other in bpy.data.objects if other != obj):
        return name
    return naming.unique_name(f"Shape Space {obj.name}", "", set(bpy.data.images.keys()))


def shape_space_image(obj, data: dict, highlight: int | None = None):
    """Draw the stored shape space of ``obj`` into the image ``data['image']`` (created or resized;
    marked as Shape Space's: :data:`SHAPE_SPACE_IMAGE_MARK`)."""
    from .analysis_plot import shape_space_image as draw

    coordinates = {kind: np.asarray(data["coordinates"][kind], dtype=float).reshape(-1, 2) for kind in KINDS}
    variance = {kind: list(data["variance"][kind]) for kind in KINDS}
    pixels = draw(coordinates, variance, highlight=highlight).rgba_bottom_up()
    height, width = pixels.shape[:2]
    image = bpy.data.images.get(data["image"])
    if image is not None and tuple(image.size) != (width, height):
        image.scale(width, height)
    if image is None:
        image = bpy.data.images.new(data["image"], width, height, alpha=True, float_buffer=True)
    image.pixels.foreach_set(pixels.ravel())
    image[SHAPE_SPACE_IMAGE_MARK] = True
    image.update()
    image.preview_ensure().reload()  # the sidebar shows the preview (drawing may not create it)
    _DRAWN[image.session_uid] = drawn_from(data, highlight)
    return image


def image_pixels(name: str):
    """The image ``name`` as it is now, for :func:`restore_shape_space`: its size, pixels
    (float32, RGBA bottom-up) and what it was drawn from (:func:`drawn_from`); None where there is none."""
    image = bpy.data.images.get(name)
    if image is None:
        return None
    pixels = np.empty(image.size[0] * image.size[1] * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return tuple(image.size), pixels, _DRAWN.get(image.session_uid)


def restore_shape_space(obj, name: str, before: dict | None, images: set, pixels=None) -> None:
    """Give ``obj`` back the shape space stored on it ``before`` (None: none) and its image
    ``name``: removed where it is not one of ``images`` (those there before); else given back its
    ``pixels`` (:func:`image_pixels`, taken before it was drawn), or without them drawn again from
    ``before``."""
    image = bpy.data.images.get(name)
    if before is None:
        obj.pop(analysis_data.SHAPE_SPACE_PROPERTY, None)
    else:
        obj[analysis_data.SHAPE_SPACE_PROPERTY] = before
    if image is not None and image not in images:
        bpy.data.images.remove(image)
    elif image is not None and pixels is not None:
        size, values, drawn = pixels
        if tuple(image.size) != size:
            image.scale(*size)
        image.pixels.foreach_set(values)
        image.update()
        if drawn is None:
            _DRAWN.pop(image.session_uid, None)
        else:
            _DRAWN[image.session_uid] = drawn
    elif before is not None and before.get("image") == name:
        selected = int(before.get("selected", -1))
        shape_space_image(obj, before, highlight=selected if selected >= 0 else None)


def show_image(context, image):
    """Show ``image`` in every Image Editor of the current screen (there may be none)."""
    screen = getattr(context, "screen", None)
    for area in (screen.areas if screen else ()):
        if area.type == 'IMAGE_EDITOR':
            area.spaces.active.image = image
            area.tag_redraw()


class SHAPE_DIFFERENCES_OT_shape_space(AnalysisBasisProperties, CaptureStep, FrameRangeProperties, GeneratorOperator,
                                       bpy.types.Operator):
    """Embed the shape keys or frames of the active mesh in the plane by PCA of their four shape
    differences (paper §8.1) and draw the four embeddings into an image ("Shape Space <object>",
    shown in Image Editors); the coordinates are stored on the object"""

    bl_idname = "shape_differences.shape_space"
    bl_label = "Shape Space"
    memory_advice = "take fewer poses (raise Step or narrow the frame range) or lower k_M and k_N"

    source: EnumProperty(name="Poses", items=SOURCE_ITEMS, default='KEYS')

    minimum_frames = 2

    def run(self, context):
        obj = context.active_object
        require_local(obj, obj, "the shape space stored on it is")
        triangles = surface_triangles(obj, self)
        self.check_sizes(triangles)
        frames, matrices = None, []
        if self.source == 'KEYS':
            key_blocks = key_blocks_of(obj, 2)
            names = [key_block.name for key_block in key_blocks]
            pose_names = [f"shape key '{name}'" for name in names]
            poses = [key_pose(key_block, obj) for key_block in key_blocks]
            yield 0.0
        else:
            frames = self.frames(context)
            names = [frame_key_name(frame) for frame in frames]
            pose_names = [frame_name(frame) for frame in frames]
            poses = yield from self.read_frames(context, obj, frames, 0.1, matrices)
        from ..core.shape_space_pca import shape_space_steps

        # measured as the world shows them: each frame through its own matrix where the object's scale
        # is keyframed (shape differences do not see the rigid part), else the world's proportions
        space = world_space.frames_space(context, obj, dict(zip(frames or [], matrices)))
        poses = in_world(obj, space, poses, frames or [None] * len(poses), triangles, MEASURED_IN_WORLD,
                         invertible=False)
        space = yield from _drive(
            shape_space_steps(poses, triangles, k_M=self.k_m, k_N=self.k_n or None,
                              offset=self.resolved_offset(context), single_precision=True, key_names=pose_names),
            0.1, 0.85)
        before = analysis_data.stored_shape_space(obj)
        data = {
            "source": self.source,
            "poses": names,
            "frames": frames or [],
            "k_M": self.k_m,
            "k_N": self.k_n,
            "offset": space.offset,
            "image": shape_space_image_name(obj, before),
            "coordinates": {kind: space.coordinates(kind, 2).ravel().tolist() for kind in KINDS},
            "variance": {kind: space.explained_variance_ratio(kind)[:4].tolist() for kind in KINDS},
            "selected": -1,
        }
        # should the run fail from here, the image gets its pixels back (this object's own, drawn
        # over) or goes, where it is new, and the shape space stored before stays
        images = set(bpy.data.images)
        pixels = image_pixels(data["image"])
        self.undo_on_failure(lambda: restore_shape_space(obj, data["image"], before, images, pixels))
        image = shape_space_image(obj, data)
        obj[analysis_data.SHAPE_SPACE_PROPERTY] = data
        show_image(context, image)
        shares = ", ".join(f"{kind.replace('_', ' ')} {100 * data['variance'][kind][0]:.0f} %" for kind in KINDS)
        self.summary = (f"Shape space of {len(names)} poses drawn into image '{image.name}' "
                        f"(share of PC 1: {shares})")


class SHAPE_DIFFERENCES_OT_shape_space_select(bpy.types.Operator):
    """Select a pose of the stored shape space by its place along the first axis of one embedding
    (the paper's Fig. 8 order): makes its shape key active, or goes to its frame"""

    bl_idname = "shape_differences.shape_space_select"
    bl_label = "Select Pose"
    bl_options = {'REGISTER', 'UNDO'}

    kind: EnumProperty(name="Embedding", items=KIND_ITEMS, default='offset_area')
    rank: IntProperty(name="Rank", min=-1, default=-1,
                      description="Place along the first axis (0 = leftmost); -1 = step from the "
                                  "current selection")
    step: IntProperty(name="Step", default=1, description="With rank -1: move this many places")

    @classmethod
    def poll(cls, context):
        if analysis_data.stored_shape_space(context.active_object) is None:
            return refused_in_poll(cls, "Run Shape Space on the active mesh first")
        return True

    def execute(self, context):
        obj = context.active_object
        try:  # the active key and the selection stored on the object are written to it
            require_local(obj, obj, "the pose selected on it is")
        except InputError as error:
            report(self, {'ERROR'}, str(error))
            return {'CANCELLED'}
        before = analysis_data.stored_shape_space(obj)
        scene = context.scene
        frame, index = (scene.frame_current, scene.frame_subframe), obj.active_shape_key_index
        try:
            return self._select(context, obj)
        except Exception as error:  # any failure: the selection, frame, active key and image as they were
            try:
                if (scene.frame_current, scene.frame_subframe) != frame:
                    scene.frame_set(frame[0], subframe=frame[1])
                obj.active_shape_key_index = index
                restore_shape_space(obj, before["image"], before, set(bpy.data.images))
            except Exception as failed:  # the image is drawn again from the stored selection after undo or a reload
                print(f"Shape Differences: could not take back Select Pose: {failed!r}", file=sys.stderr)
            if not isinstance(error, MemoryError):
                raise  # a bug: Blender shows its traceback
            report(self, {'ERROR'}, ran_out_of_memory(error, "save the .blend and restart Blender, which gives "
                                                             "back the memory it holds"))
            return {'CANCELLED'}

    def _select(self, context, obj):
        data = analysis_data.stored_shape_space(obj)
        try:  # read and drawn before anything changes
            first_axis = np.asarray(data["coordinates"][self.kind], dtype=float).reshape(-1, 2)[:, 0]
            order = np.argsort(first_axis, kind="stable")
            if self.rank >= 0:
                rank = min(self.rank, len(order) - 1)
            else:
                current = int(data.get("selected", -1))
                now = int(np.flatnonzero(order == current)[0]) if current >= 0 else -1
                rank = int(np.clip(now + self.step, 0, len(order) - 1))
            pose = int(order[rank])
            name = data["poses"][pose]
            key = obj.data.shape_keys
            index = (key.key_blocks.find(name) if key else -1) if data["source"] == 'KEYS' else None
            frame = int(data["frames"][pose]) if index is None else None
            if index is not None and index < 0:
                report(self, {'ERROR'}, f"The shape key '{name}' no longer exists: run Shape Space again")
                return {'CANCELLED'}
            data["selected"] = pose
            image = shape_space_image(obj, data, highlight=pose)
        except (KeyError, IndexError, TypeError, ValueError) as error:  # edited by hand, as redraw_shape_spaces says
            report(self, {'ERROR'}, f"The shape space stored on '{obj.name}' cannot be read ({error!r}): run Shape "
                                    "Space again")
            return {'CANCELLED'}
        if index is None:
            context.scene.frame_set(frame)
        else:
            obj.active_shape_key_index = index
        obj[analysis_data.SHAPE_SPACE_PROPERTY] = data
        show_image(context, image)
        report(self, {'INFO'}, f"Selected '{name}': {rank + 1} of {len(order)} along the first "
                               f"{self.kind.replace('_', ' ')} axis")
        return {'FINISHED'}


# -- distortion maps --------------------------------------------------------------------------------

DISTORTION_SOURCE_ITEMS = [
    ("ACTIVE_KEY", "Active Key", "The active shape key (or the one named) against the Basis"),
    ("FRAMES", "Frames", "The evaluated mesh at every frame of the range against the rest mesh; "
                         "one set of attributes per frame, named with the frame"),
]
#: The kinds' names in the eigenfunction maps' attribute names ("SD Eigen Offset Area 2").
EIGEN_TITLES = {kind: kind.replace("_", " ").title() for kind in KINDS}
#: (name, per-vertex attribute of core.Distortion, per-face attribute, diverging map, centre,
#: per-vertex and per-face round-off attributes)
MAPS = (
    ("Area", "area_change_vertices", "area_change_faces", True, 0.0, "round_off_vertices", "round_off_faces"),
    ("Conformal", "conformal_vertices", "conformal_faces", False, 1.0, "round_off_vertices", "round_off_faces"),
    ("Bending", "bending_vertices", "bending_faces", True, 0.0,
     "bending_round_off_vertices", "bending_round_off_faces"),
)


#: Most eigenfunction maps Distortion Maps writes of each difference (each one a colour attribute
#: per difference and pose).
MAX_EIGENFUNCTION_MAPS = 8


def map_bytes_per_vertex(mesh, eigenfunctions: int) -> int:
    """Bytes per vertex of one pose's maps as attributes of ``mesh`` (at most: the offset surface's
    maps counted too): RGBA single-precision colours of the three maps and of ``eigenfunctions``
    per kind of difference, three single-precision values per vertex and three per face."""
    colours = len(MAPS) + len(KINDS) * eigenfunctions
    per_face = 4 * len(MAPS) * len(mesh.polygons) / max(len(mesh.vertices), 1)
    return int(np.ceil(16 * colours + 4 * len(MAPS) + per_face))


class SHAPE_DIFFERENCES_OT_distortion_maps(AnalysisBasisProperties, CaptureStep, FrameRangeProperties, GeneratorOperator,
                                           bpy.types.Operator):
    """Write distortion maps of a pose against its base as mesh attributes: area change,
    conformal (angle) distortion and bending (change of the offset surface) as colour attributes
    to show in the viewport (Solid shading › Attribute), their values per vertex and per face, and
    the leading eigenfunctions of each shape difference. Positions, keys and animation are kept"""

    bl_idname = "shape_differences.distortion_maps"
    bl_label = "Distortion Maps"
    memory_advice = "raise Step, narrow the frame range or write fewer Eigenfunctions"

    source: EnumProperty(name="Poses", items=DISTORTION_SOURCE_ITEMS, default='ACTIVE_KEY')
    key: StringProperty(name="Key", description="Pose to map (empty: the active key)")
    # soft limits only: Blender would clamp a script's 20 to 8 (or -1 to 0) silently; run() refuses them
    eigenfunctions: IntProperty(name="Eigenfunctions", soft_min=0, soft_max=MAX_EIGENFUNCTION_MAPS, default=2,
                                description="Leading eigenfunctions of each of the four differences "
                                            "to write (colour attributes 'SD Eigen <kind> <i>')")

    minimum_frames = 1

    def run(self, context):
        obj = context.active_object
        mesh = obj.data
        if not 0 <= self.eigenfunctions <= MAX_EIGENFUNCTION_MAPS:
            raise InputError(f"Eigenfunctions is {self.eigenfunctions}: write 0 to {MAX_EIGENFUNCTION_MAPS} "
                             f"(each a colour attribute per difference and pose)")
        require_local(obj, mesh, "maps written to it as attributes are")
        refuse_emptying_caches(context.scene, obj, "distortion maps written to")
        triangles = surface_triangles(obj, self)
        if self.eigenfunctions:  # the basis is of the eigenfunction maps only
            self.check_sizes(triangles, uses_k_n=False)
        key = mesh.shape_keys
        base = key_pose(key.key_blocks[0], obj) if key else mesh_pose(obj)
        times, matrices = [None], []
        if self.source == 'ACTIVE_KEY':
            key_blocks = key_blocks_of(obj, 2)
            pose_key = resolve_key(obj, self.key, "Key", default_pose_key(obj))
            if pose_key == key_blocks[0]:
                raise InputError(f"'{pose_key.name}' is the Basis, which the maps are measured from: "
                                 "pick another shape key")
            self.key = pose_key.name
            labels, poses = [""], [key_pose(pose_key, obj)]
            yield 0.0
        else:
            frames = self.frames(context)
            from ..core.validation import check_output_memory

            check_output_memory(len(frames), len(mesh.vertices), "The output of Maps of Frames",
                                "raise Step, narrow the frame range or write fewer Eigenfunctions",
                                bytes_per_point=map_bytes_per_vertex(mesh, self.eigenfunctions))
            labels = [f" f{frame}" for frame in frames]
            poses = yield from self.read_frames(context, obj, frames, 0.3, matrices)
            times = frames
        from ..core.distortion_maps import DistortionAnalyzer

        # distortion as the world shows it: each frame through its own matrix where the object's scale is
        # keyframed, the rest mesh through the first frame's, else all in the world's proportions
        space = world_space.frames_space(context, obj, dict(zip(times, matrices)))
        base, *poses = in_world(obj, space, [base, *poses], [times[0], *times], triangles, MEASURED_IN_WORLD,
                                invertible=False)
        # bending lives on the offset surface, which needs an edge shared by two faces
        edges = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        extrinsic = bool((np.unique(edges, axis=0, return_counts=True)[1] > 1).any())
        if not extrinsic:
            report(self, {'WARNING'}, f"'{obj.name}' has no edge shared by two faces: no offset surface, so no "
                                      "bending map and no offset eigenfunction maps")
        analyzer = DistortionAnalyzer(base, triangles, offset=self.resolved_offset(context), k=self.k_m,
                                      use_extrinsic=extrinsic, single_precision=True)  # Blender's coordinates
        results, unchanged = [], []
        for index, pose in enumerate(poses):
            distortion = analyzer.pose(pose, name=f"shape key '{self.key}'" if self.source == 'ACTIVE_KEY'
                                       else f"frame {frames[index]}")
            pairs = {kind: distortion.eigenfunctions(kind, self.eigenfunctions)
                     for kind in (KINDS if extrinsic else KINDS[:2])} if self.eigenfunctions else {}
            results.append((distortion, {kind: functions for kind, (_, functions) in pairs.items()}))
            if unchanged_pose(distortion):
                unchanged.append(f"'{self.key}'" if self.source == 'ACTIVE_KEY' else f"frame {frames[index]}")
            yield 0.3 + 0.65 * (index + 1) / len(poses)
        self.undo_on_failure(maps_restorer(mesh, labels))  # the maps it overwrites come back should the run fail
        self._write(mesh, triangles, base, labels, results)
        dropped = zone_frames_dropped(context.scene, obj, "distortion maps written to")
        if dropped:
            report(self, {'WARNING'}, dropped)
        if unchanged:
            report(self, {'WARNING'}, f"{', '.join(unchanged[:5])}{' …' if len(unchanged) > 5 else ''} "
                                      f"{'does' if len(unchanged) == 1 else 'do'} not change the base (every "
                                      "map is zero to the rounding of its coordinates): the maps show no distortion"
                                      + (", and the eigenfunction maps are arbitrary (every function is an "
                                         "eigenfunction of the identity)" if self.eigenfunctions else ""))
        if self.source == 'FRAMES':
            # The frame handler shows the map of the frame being played (see follow_frame).
            mesh[FRAME_MAPS_PROPERTY] = {"frames": frames, "map": "Area"}
        what = f"'{self.key}'" if self.source == 'ACTIVE_KEY' else f"{len(poses)} frames"
        written = sum(functions.shape[1] for _, eigen in results[:1] for functions in eigen.values())

        def written_map(field):  # bending is not written without an offset surface
            return getattr(results[0][0], field) is not None

        self.summary = (f"Wrote distortion maps of {what}: colour attributes "
                        f"{', '.join('SD ' + name + labels[0] for name, field, *_ in MAPS if written_map(field))}"
                        + (f" and {written} eigenfunction maps" + (" per frame" if len(poses) > 1 else "")
                           if written else ""))

    @staticmethod
    def _write(mesh, triangles, base, labels, results):
        from .analysis_plot import scalar_colors

        polygons = triangulation.loop_triangle_polygons(mesh)
        corners = base[triangles]
        weights = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
        polygon_weight = np.bincount(polygons, weights, len(mesh.polygons))
        polygon_weight[polygon_weight == 0] = 1.0
        # the colour attribute renders and exporters use where none is named: the first colour
        # attribute added becomes it, and the maps are for the viewport only
        render_color = mesh.color_attributes.default_color_name
        first = None
        for label, (distortion, eigen) in zip(labels, results):
            for name, vertex_field, face_field, diverging, centre, vertex_round_off, _ in MAPS:
                vertex_values = getattr(distortion, vertex_field)
                face_values = getattr(distortion, face_field)
                if vertex_values is None:
                    continue
                analysis_data.write_attribute(mesh, f"SD {name}{label}", 'POINT',
                                       scalar_colors(vertex_values, diverging=diverging, floor=centre,
                                                     round_off=getattr(distortion, vertex_round_off)), color=True)
                first = first or f"SD {name}{label}"
                analysis_data.write_attribute(mesh, f"sd_{name.lower()}{label}", 'POINT', vertex_values)
                per_polygon = np.bincount(polygons, weights * face_values, len(mesh.polygons)) / polygon_weight
                analysis_data.write_attribute(mesh, f"sd_{name.lower()}_face{label}", 'FACE', per_polygon)
            # eigenfunction maps of this label from an earlier run (another key, more functions)
            # would read as this pose's
            stale = re.compile(rf"SD Eigen ({'|'.join(EIGEN_TITLES.values())}) \d+{re.escape(label)}")
            for name in [a.name for a in mesh.attributes if stale.fullmatch(a.name)]:
                mesh.attributes.remove(mesh.attributes[name])
            for kind, functions in eigen.items():
                for i in range(functions.shape[1]):
                    analysis_data.write_attribute(mesh, f"SD Eigen {EIGEN_TITLES[kind]} {i + 1}{label}", 'POINT',
                                           scalar_colors(functions[:, i], diverging=True, floor=0.0), color=True)
        if first is not None:  # by name: references to attributes go stale as others are added
            mesh.color_attributes.active_color = mesh.color_attributes[first]
        mesh.color_attributes.default_color_name = render_color  # "" keeps none
        mesh.update()


def maps_restorer(mesh, labels: list[str]):
    """A function that gives ``mesh`` back the distortion maps of ``labels`` (a key's "", a frame's
    " f12") it has now (:data:`bridge.analysis_data.ANALYSIS_ATTRIBUTE`: their values, those written
    since removed; the maps of other frames, which a run of ``labels`` leaves alone, are not copied),
    its active and render colour attributes and its list of frame maps, for a run that fails while
    writing its own (:meth:`GeneratorOperator.undo_on_failure`)."""
    labels = set(labels)

    def ours(name: str) -> bool:
        match = analysis_data.ANALYSIS_ATTRIBUTE.fullmatch(name)
        return match is not None and (match.group(analysis_data.ANALYSIS_ATTRIBUTE.groups) or "") in labels  # its frame

    kept = {}
    for attribute in mesh.attributes:
        if ours(attribute.name):
            color = attribute.data_type == 'FLOAT_COLOR'
            values = np.empty(len(attribute.data) * (4 if color else 1), dtype=np.float32)
            attribute.data.foreach_get("color" if color else "value", values)
            kept[attribute.name] = (attribute.domain, color, values)
    active = mesh.color_attributes.active_color_name
    render = mesh.color_attributes.default_color_name
    frame_maps = mesh.get(FRAME_MAPS_PROPERTY)
    frame_maps = frame_maps.to_dict() if hasattr(frame_maps, "to_dict") else frame_maps

    def restore():
        for name in [a.name for a in mesh.attributes if ours(a.name) and a.name not in kept]:
            mesh.attributes.remove(mesh.attributes[name])
        for name, (domain, color, values) in kept.items():
            analysis_data.write_attribute(mesh, name, domain, values, color=color)
        if active in mesh.color_attributes:
            mesh.color_attributes.active_color_name = active
        mesh.color_attributes.default_color_name = render
        if frame_maps is None:
            mesh.pop(FRAME_MAPS_PROPERTY, None)
        else:
            mesh[FRAME_MAPS_PROPERTY] = frame_maps
        mesh.update()

    return restore


#: A pose whose maps are all at most this (or the size of the coordinates' rounding,
#: ``core.Distortion.round_off_faces``) does not change the base: its leading eigenfunctions are arbitrary.
UNCHANGED_STRETCH = 1e-9


def unchanged_pose(distortion) -> bool:
    """Whether every per-face value of ``distortion``'s maps (a ``core.Distortion``), measured from
    its neutral value (area change and bending 0, conformal ratio 1), is within
    :data:`UNCHANGED_STRETCH` or the face's round-off (``round_off_faces``)."""
    for _, _, face_field, _, centre, _, round_off in MAPS:
        values = getattr(distortion, face_field)
        if values is not None and not np.all(np.abs(values - centre) <= np.maximum(getattr(distortion, round_off),
                                                                                     UNCHANGED_STRETCH)):
            return False
    return True

#: Custom property (on the mesh) listing the frames that have distortion maps.
FRAME_MAPS_PROPERTY = "shape_differences_frame_maps"


@skipped_out_of_memory("while showing the distortion map of the frame")
def follow_frame(scene, _depsgraph=None):
    """After a frame change, make each mesh's distortion map of that frame (or of the last mapped
    frame before it) the active colour attribute, so playback shows the maps frame by frame. Only
    which colour attribute is active changes, and only while a frame's map is the active one: the
    map shown is the one whose prefix it has (SD Area, SD Conformal, SD Bending), so picking one in
    the list sticks, and picking any other colour attribute (the user's own, a map of a key) stops
    the following until a frame's map is picked again. A mesh whose change would empty the cache of
    an unbaked simulation (its own cloth after its bake was freed, one reacting to it as a collider:
    :func:`~.motion_sources.simulations_emptied_by`) keeps the map it shows: a change of its active colour
    attribute marks that cache outdated, and Blender empties it at the simulation's start."""
    for obj in scene.objects:
        mesh = obj.data if obj.type == 'MESH' else None
        if mesh is None or FRAME_MAPS_PROPERTY not in mesh:
            continue
        active = mesh.color_attributes.active_color
        kind = next((name for name, *_ in MAPS if active is not None
                     and re.fullmatch(rf"SD {name} f-?\d+", active.name)), None)
        if kind is None:  # another colour attribute was picked: leave it
            continue
        # the frames mapped, by any run (an earlier run's maps stay beside a later one's)
        found = (re.fullmatch(rf"SD {kind} f(-?\d+)", attribute.name) for attribute in mesh.color_attributes)
        frames = sorted(int(match.group(1)) for match in found if match)
        shown = [frame for frame in frames if frame <= scene.frame_current] or frames[:1]
        attribute = mesh.color_attributes.get(f"SD {kind} f{shown[-1]}")
        if attribute is None or (active is not None and active.name == attribute.name):
            continue
        if any(simulations_emptied_by(scene, obj)):  # switching would empty their caches: the map stays
            continue
        mesh.color_attributes.active_color = attribute


@skipped_out_of_memory("while drawing the shape space images again",
                       "skipped there (an image may show an earlier selection, or nothing), and tried again at "
                       "the next undo, redo or file load")
def redraw_shape_spaces(*_):
    """After a .blend is opened, and after undo and redo: draw the image of each shape space stored
    on its objects again from the stored coordinates and selection where it does not show them or
    holds no pixels. A generated image is not saved with the file (it came back missing, or blank
    where something held it), and undo and redo restore the stored shape space but not an image's
    pixels (an undone Select Pose stayed highlighted, a redone Shape Space came back blank)."""
    for obj in bpy.data.objects:
        data = analysis_data.stored_shape_space(obj)
        if data is None or obj.library is not None:
            continue
        try:
            selected = int(data.get("selected", -1))
            highlight = selected if selected >= 0 else None
            image = bpy.data.images.get(data["image"])
            if image is not None and image.has_data and _DRAWN.get(image.session_uid) == drawn_from(data, highlight):
                continue  # it shows them: drawing takes some 50 ms, and undo runs this at every step
            shape_space_image(obj, data, highlight=highlight)
        except (KeyError, TypeError, ValueError) as error:  # a property edited by hand: leave it
            print(f"Shape Differences: the shape space stored on '{obj.name}' cannot be drawn ({error})")


HANDLERS = ((bpy.app.handlers.frame_change_post, follow_frame), (bpy.app.handlers.load_post, redraw_shape_spaces),
            (bpy.app.handlers.undo_post, redraw_shape_spaces), (bpy.app.handlers.redo_post, redraw_shape_spaces))


def register_handlers():
    for handlers, handler in HANDLERS:
        if handler not in handlers:
            handlers.append(handler)


def unregister_handlers():
    for handlers, handler in HANDLERS:
        if handler in handlers:
            handlers.remove(handler)


classes = (
    SHAPE_DIFFERENCES_OT_shape_space,
    SHAPE_DIFFERENCES_OT_shape_space_select,
    SHAPE_DIFFERENCES_OT_distortion_maps,
)
