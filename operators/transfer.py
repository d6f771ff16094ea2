"""Transfer poses from a differently meshed object onto the active mesh (issue 21, paper Fig. 15)."""

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ..bridge import world_space
from ..properties import PATH_OPTIONS, CaptureStep, PoseOutput
from .base import (REBUILT_IN_WORLD, BasisSizeProperties, GeneratorOperator, InputError, check_memory,
                   check_world_scale, edit_mode_problem, key_blocks_of, key_pose, load_core, mesh_pose,
                   refused_in_poll, reported_error, surface_triangles, triangle_faces)
from .frames import FrameRangeProperties, frame_key_name
from .output import PoseWriter
from .poses import scene_frames

#: Basis sizes used when the settings ask for the full basis (0), which a map between two
#: meshes cannot use (paper §6.3; the paper's Figs. 11 and 14).
DEFAULT_K_M, DEFAULT_K_N = 100, 200


def _world(obj, positions, matrix=None):
    """``positions`` of ``obj`` in world space, through ``matrix`` (4 × 4; default: its world
    matrix now)."""
    matrix = np.array(obj.matrix_world if matrix is None else matrix, dtype=np.float64)
    return positions @ matrix[:3, :3].T + matrix[:3, 3]


def _local(obj, positions):
    matrix = np.linalg.inv(np.array(obj.matrix_world, dtype=np.float64))
    return positions @ matrix[:3, :3].T + matrix[:3, 3]


def about_mesh(obj, role: str, job):
    """``yield from`` this to run ``job`` (an operator's :meth:`compute` of a core call whose
    refusals concern ``obj``'s mesh alone) with those refusals naming the object, its ``role``
    and the faces (two meshes are in play: the core's "triangle 7" or "Edge (3, 4)" says not
    of which)."""
    try:
        return (yield from job)
    except load_core().MeshError as error:
        message = reported_error(error, triangle_faces(obj, obj.data.loop_triangles))
        if f"'{obj.name}'" not in message:
            message = f"'{obj.name}' ({role}): {message}"
        raise InputError(message) from error


def read_correspondence(obj, name: str, n_source: int) -> np.ndarray:
    """The integer point attribute ``name`` of the active mesh: each vertex's matched vertex of
    the source mesh."""
    attribute = obj.data.attributes.get(name)
    if attribute is None or attribute.domain != 'POINT' or attribute.data_type not in {'INT', 'INT8'}:
        raise InputError(
            f"'{obj.name}' has no integer vertex attribute '{name}' holding the matched source vertex "
            "of each vertex: import the map as an Integer / Vertex attribute, or choose Closest Points")
    values = np.empty(len(obj.data.vertices), dtype=np.int32)
    attribute.data.foreach_get("value", values)
    bad = np.flatnonzero((values < 0) | (values >= n_source))
    if bad.size:
        raise InputError(
            f"Attribute '{name}' maps vertex {int(bad[0])} of '{obj.name}' to source vertex "
            f"{int(values[bad[0]])}, but the source has {n_source} vertices ({bad.size} such vertices)")
    return values.astype(np.int64)


def read_map_files(obj, source, map_file: str, source_map_file: str, one_based: bool) -> np.ndarray:
    """The correspondence from map files: ``map_file`` alone holds one source vertex per vertex of
    the active mesh ``obj``; with ``source_map_file`` both are template maps (``.vts``: for each
    template vertex, its vertex on the mesh), composed active → template → source. Vertices of the
    active mesh that no template vertex lands on are unmatched (-1)."""
    core = load_core()
    if not map_file:
        raise InputError("Set the Map File (one source vertex per line for each vertex of the active mesh, or "
                         "the active mesh's template map), or choose another Map")
    n_base, n_source = len(obj.data.vertices), len(source.data.vertices)
    first = core.read_vertex_map(bpy.path.abspath(map_file))
    if source_map_file:
        second = core.read_vertex_map(bpy.path.abspath(source_map_file))
        return core.template_correspondence(
            first, second, n_base, n_source, one_based=one_based,
            names=(f"the Map File (template map of '{obj.name}', {n_base} vertices)",
                   f"the Source Template Map (template map of '{source.name}', {n_source} vertices)"))
    if first.size != n_base:
        raise InputError(
            f"The Map File has {first.size} entries but '{obj.name}' has {n_base} vertices: a per-vertex map "
            "lists the matched source vertex of every vertex of the active mesh, in order (for two template "
            ".vts files, also set the Source Template Map)")
    from ..core.vertex_maps import vertex_map_indices

    return vertex_map_indices(first, n_source, one_based=one_based,
                              what=f"the Map File (vertices of '{source.name}', {n_source} in all)")


class SHAPE_DIFFERENCES_OT_transfer_poses(CaptureStep, PoseOutput, BasisSizeProperties, FrameRangeProperties, PoseWriter,
                                          GeneratorOperator, bpy.types.Operator):
    """Rebuild the poses of another selected mesh (shape keys or animation frames, any
    connectivity) on the active mesh from their shape differences through a functional map, as
    shape keys or as a point cache on a new object. The two meshes are matched by closest points
    at rest (they must overlap there), by a vertex attribute holding the map, or by map files (one
    index per vertex, or two template .vts maps)"""

    bl_idname = "shape_differences.transfer_poses"
    bl_label = "Transfer Poses"
    memory_advice = "transfer fewer frames (raise Step or narrow the frame range) or lower k_M and k_N"

    source: EnumProperty(
        name="Poses", default='KEYS',
        items=[('KEYS', "Shape Keys", "Every shape key of the source after its Basis (the Basis is its rest pose)"),
               ('FRAMES', "Frames", "The source's evaluated mesh at each frame (cloth, armature, any "
                                    "modifiers); its undeformed mesh is the rest pose")])
    matching: EnumProperty(
        name="Map", default='CLOSEST',
        items=[('CLOSEST', "Closest Points", "Match every vertex to the closest point of the source's rest "
                                             "pose (the two meshes must overlap at rest, in world space)"),
               ('ATTRIBUTE', "Attribute", "Read the map from an integer vertex attribute of the active mesh"),
               ('FILE', "File", "Read the map from a file: the matched source vertex of each vertex, one per "
                                "line, or two template maps (.vts) composed")])
    map_attribute: StringProperty(
        name="Attribute", default="correspondence",
        description="Integer vertex attribute of the active mesh: the matched source vertex of each vertex")
    map_file: StringProperty(
        name="Map File", subtype='FILE_PATH', default="", options=PATH_OPTIONS,
        description="Text file with one index per line: the matched source vertex of each vertex of the active "
                    "mesh; or, with a Source Template Map, the active mesh's template map (.vts)")
    source_map_file: StringProperty(
        name="Source Template Map", subtype='FILE_PATH', default="", options=PATH_OPTIONS,
        description="The source's template map (.vts: for each template vertex, its source vertex). When set, "
                    "the Map File is the active mesh's template map and the two are composed; active vertices "
                    "no template vertex lands on take their match from their neighbours")
    one_based: BoolProperty(
        name="1-Based Indices", default=True,
        description="Indices in the map files start at 1 (MATLAB, .vts files of FAUST_r, SCAPE_r, SHREC'19); "
                    "off: at 0")

    @classmethod
    def poll(cls, context):
        if not super().poll(context):
            return False
        if not any(o.type == 'MESH' and o != context.active_object for o in context.selected_objects):
            return refused_in_poll(
                cls, "Also select the mesh whose poses to transfer (the active mesh is the one to move)")
        return True

    def _source_object(self, context):
        others = [o for o in context.selected_objects if o.type == 'MESH' and o != context.active_object]
        if len(others) != 1:
            raise InputError(
                f"Select exactly one other mesh as the source of the poses ({len(others)} selected besides "
                "the active mesh)")
        editing = edit_mode_problem(others[0])
        if editing:
            raise InputError(f"{editing} (the source of the poses)")
        return others[0]

    def _basis_sizes(self, options, n_base: int, n_source: int):
        k_n = options["k_N"] or min(DEFAULT_K_N, n_source - 1)  # a set k_N is checked by core_options
        from ..core.transfer_checks import resolved_functions

        # k_N ≥ k_M (core.validation.check_basis_sizes), and no more than the source resolves
        k_m = options["k_M"] or min(DEFAULT_K_M, n_base - 1, k_n, resolved_functions(n_source))
        return k_m, k_n

    def _source_poses(self, context, source):
        """Yield progress while reading the poses; returns (names, frames, rest positions, poses),
        in object space of the source, the source's world matrix with each pose (frames: at
        that frame, so that a source moved as a whole by its keyframes, constraints or parent is
        transferred with that motion; keys: played one a frame from the start of playback, as the
        other operators' keys are) and the one its rest is laid in the world with: placed as at
        the current frame (where the target is laid on it for closest points), and of frames
        stretched as the first frame is (a source whose scale is keyframed is measured against its
        rest in the proportions its frames show, whatever the current frame's). Frames are read as
        the frame operators read them: an unbaked simulation computed from its start, its
        generators after the motion set aside."""
        if self.source == 'KEYS':
            key_blocks = key_blocks_of(source)
            rest = key_pose(key_blocks[0], source)
            names = [kb.name for kb in key_blocks[1:]]
            return (names, scene_frames(context, len(names)), rest,
                    [key_pose(kb, source) for kb in key_blocks[1:]],
                    [source.matrix_world.copy()] * len(names), source.matrix_world.copy())
        frames = self.frames(context)
        # the frames read (the source's vertices) and the poses written (the active mesh's)
        check_memory(len(frames), max(len(source.data.vertices), len(context.active_object.data.vertices)),
                     "The output", "raise Step or narrow the frame range", work=None)
        matrices = []
        poses = yield from self.read_frames(context, source, frames, 0.05, matrices)
        return ([frame_key_name(f) for f in frames], [float(f) for f in frames], mesh_pose(source),
                poses, matrices, world_space.with_proportions(source.matrix_world, matrices[0]))

    def run(self, context):
        obj = context.active_object
        source = self._source_object(context)
        triangles = surface_triangles(obj)
        # the active mesh as the world shows it, where the poses are rebuilt: refused there if its
        # world matrix flattens it (its scale, or a parent's), before any work
        positions = mesh_pose(obj)
        base = _world(obj, positions)
        check_world_scale(obj, REBUILT_IN_WORLD, poses=[(positions, base)], triangles=triangles)
        source_triangles = surface_triangles(source)
        n_base, n_source = len(obj.data.vertices), len(source.data.vertices)
        options = self.core_options(context, n_base, n_source)
        k_m, k_n = self._basis_sizes(options, n_base, n_source)
        self.check_output(obj)
        correspondence = None
        if self.matching == 'ATTRIBUTE':
            correspondence = read_correspondence(obj, self.map_attribute, n_source)
        elif self.matching == 'FILE':
            correspondence = read_map_files(obj, source, self.map_file, self.source_map_file, self.one_based)
        names, frames, rest, poses, matrices, rest_matrix = yield from self._source_poses(context, source)
        if not poses:
            raise InputError(f"'{source.name}' has no pose to transfer")
        yield 0.05
        core = load_core()
        # Intrinsic differences only (core.Transfer's default), so no offset surface and no Extrinsic
        # setting: the offset layer's transferred lengths are too noisy to embed.
        # The active mesh is prepared (and checked) on its own first, so that a refusal of its mesh
        # says which of the two meshes to fix; the source's rest pose is named in the core's checks.
        reference = yield from about_mesh(obj, "the mesh the poses move", self.compute(
            0.05, core.ReferenceShape, base, triangles, name=f"the mesh of '{obj.name}'",
            use_extrinsic=False))
        transfer = yield from self.compute(
            0.1, core.Transfer, base, triangles, _world(source, rest, rest_matrix), source_triangles,
            correspondence=correspondence, k_M=k_m, k_N=k_n, reference=reference,
            target_name=f"the rest pose of '{source.name}' in the world",
            target_label=f"'{source.name}' (the source of the poses)", doing=f"preparing '{source.name}'")
        rebuilt = []
        for i, pose in enumerate(poses):
            world = yield from self.compute(0.1 + 0.9 * i / len(poses), transfer.pose,
                                            _world(source, pose, matrices[i]), doing=f"pose {i + 1}/{len(poses)}")
            rebuilt.append(_local(obj, world))
        self.summary = self.write_poses(
            context, obj, rebuilt, names=[f"{source.name} {name}" for name in names], frames=frames,
            label=f"Transfer {source.name}") + f" (k_M = {k_m}, k_N = {k_n})"
