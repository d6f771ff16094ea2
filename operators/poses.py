"""Operators on the shape keys of the active mesh: in-between, exaggerate, reconstruct."""

import bpy

from ..bridge import mesh_data, modifier_kinds, triangulation, world_space
from ..bridge.naming import shorten
from ..properties import ExaggeratedPose, KeyPair, PoseKey, PoseOutput
from .base import (INBETWEENED_IN_WORLD, CoreSettingsProperties, GeneratorOperator, InbetweenSettingsProperties,
                   InputError, check_memory, default_pose_key, in_world, key_blocks_of, load_core, playback_range,
                   require_count, require_distinct, resolve_key, surface_triangles)
from .motion_sources import moves_vertices
from .output import PoseWriter


def format_factor(factor: float) -> str:
    """A factor with two decimals, or three where two would lose it (0.125, 0.333)."""
    text = f"{factor:.3f}"
    return text[:-1] if text.endswith("0") else text


def inbetween_name(name_a: str, name_b: str, factor: float) -> tuple[str, str]:
    """(head, tail) of an in-between key's name: the keys may be shortened, the factor never."""
    return f"Inbetween {shorten(name_a, 22)}-{shorten(name_b, 22)}", f" {format_factor(factor)}"


def scene_frames(context, count: int) -> list[float]:
    """``count`` consecutive frames from the start of the playback range (the preview range where
    it is on): where a cache shows key poses."""
    start = playback_range(context.scene)[0]
    return [float(start + i) for i in range(count)]


def rest_option(rest, factor: float, first, triangles) -> dict:
    """``{"rest_pose": rest}`` with every edge of ``rest`` (n, 3) ``factor`` × as long (the rest
    lengths Shrinking sets, ``frames.rest_length_factor``; scaled about its centroid, any point would
    do), or ``{}`` where the core would refuse that rest against the first key ``first`` (n, 3) over
    ``triangles`` (m, 3) (``core.rest_pose_scale``: past 2 × or under half its size, not its rest)."""
    from ..core import rest_pose_scale

    if factor != 1.0:
        centre = rest.mean(axis=0)
        rest = centre + factor * (rest - centre)
    return {"rest_pose": rest} if rest_pose_scale.scale_taken(rest_pose_scale.rest_scale(rest, first, triangles)) \
        else {}


def cloth_input_is_basis(obj) -> bool:
    """Whether the cloth simulating ``obj`` (its first cloth modifier enabled in the viewport) is given the
    mesh itself at its first frame, the shape its keys are made on: no modifier enabled before it moves,
    adds or removes vertices (an Armature, a Subdivision Surface: the cloth's rest is what they make of the
    mesh there, or a mesh of other vertices). True where no cloth simulates ``obj``. Whether the cloth's
    springs are built from that mesh at all (not with Dynamic Mesh, nor a Rest Shape Key Blender reads) is
    ``frames.rest_length_factor``'s, which a sequence's rest shares."""
    for modifier in obj.modifiers:
        if modifier.type != 'CLOTH' or not modifier.show_viewport:
            continue
        return not any(m.type in modifier_kinds.GENERATE_MODIFIERS or moves_vertices(m)
                       for m in modifier_kinds.enabled_before(obj, modifier))
    return True


def basis_rest(obj, space, first, triangles) -> dict:
    """``{"rest_pose": positions (n, 3)}``: the rest the edge warning of two poses measures their
    deviation from (``rest_pose`` of ``core.Interpolator``), in ``space``
    (:class:`bridge.world_space.WorldProportions`, the poses'): the shape a cloth's keys were
    simulated from, a character's keys are made on. That is the Basis of ``obj``'s relative shape keys
    (the reference key), its edges scaled by 1 − Shrinking (``frames.rest_length_factor``: the cloth's
    springs are that much shorter than the mesh's edges). A cloth's Rest Shape Key is not it: Blender
    4.2–5.0 read that key only behind a modifier not of their deform-only kind
    (``frames.cloth_rest_is_input``), where the Basis is no rest either (none is given there:
    ``frames.rest_length_factor``). Without it the poses' deviation is the least they can have from any
    rest they share, and poses 2–3 % off their rest but nearer each other are warned within issue 17's
    edge bound. ``{}`` (that least deviation, as without a rest, and nothing said) where the Basis
    is not the rest: absolute keys (*Relative* off: the Basis is the first pose Evaluation Time plays,
    not a rest), a cloth given another mesh than the Basis (:func:`cloth_input_is_basis`) or whose
    springs are not built from it (Dynamic Mesh, a Shrinking vertex group between two factors:
    ``frames.rest_length_factor``), or where the core would refuse the rest against the first pose
    ``first`` (n, 3, in ``space``) over ``triangles`` (m, 3): past 2 × or under half its size
    (``core.rest_pose_scale``), where it is not that pose's rest."""
    from .frames import rest_length_factor

    keys = obj.data.shape_keys
    factor = rest_length_factor(obj)
    if factor is None or not keys.use_relative or not cloth_input_is_basis(obj):
        return {}
    rest = space.to(mesh_data.shape_key_positions(keys.key_blocks[0], obj))
    return rest_option(rest, factor, first, triangles)


class InWorldProportions:
    """An interpolator of poses taken into the world's proportions, its poses back in the mesh's
    coordinates (:class:`bridge.world_space.WorldProportions`)."""

    def __init__(self, interpolator, space):
        self.interpolator, self.space = interpolator, space

    def pose(self, factor: float):
        return self.space.back(self.interpolator.pose(factor))


class KeyPairProperties:
    """Interpolation between two shape keys of the active object, the first defaulting to the
    Basis and the second to the active key."""

    def pair_interpolator(self, context, first: str, second: str, labels: tuple[str, str], n_poses: int = 1,
                          advice: str = "lower Count"):
        """Validate the keys named by properties ``first`` and ``second`` (writing the resolved
        names back) and the memory of ``n_poses`` output poses and their computation
        (:func:`check_memory`, ``advice`` how to make the output smaller), yield once, and return
        ``(first key, second key, core.Interpolator)``."""
        obj = context.active_object
        key_blocks = key_blocks_of(obj)
        start = resolve_key(obj, getattr(self, first), labels[0], key_blocks[0])
        end = resolve_key(obj, getattr(self, second), labels[1], default_pose_key(obj))
        require_distinct(start, end, *labels)
        setattr(self, first, start.name)
        setattr(self, second, end.name)
        triangles = surface_triangles(obj, self)
        options = self.core_options(context, len(obj.data.vertices))
        self.check_output(obj)
        check_memory(n_poses, len(obj.data.vertices), "The output", advice, work="pair")
        yield 0.0
        space = world_space.WorldProportions(obj)
        keys = in_world(obj, space, [mesh_data.shape_key_positions(key, obj) for key in (start, end)], [None, None],
                        triangles, INBETWEENED_IN_WORLD)
        interpolator = yield from self.compute(
            0.0, load_core().Interpolator, *keys, triangles, **options, **basis_rest(obj, space, keys[0], triangles),
            key_names=(f"shape key '{start.name}'", f"shape key '{end.name}'"),
            doing=f"preparing shape keys '{start.name}' and '{end.name}'")
        return start, end, InWorldProportions(interpolator, space)


class SHAPE_DIFFERENCES_OT_inbetween(KeyPair, PoseOutput, KeyPairProperties,
                                     InbetweenSettingsProperties, PoseWriter, GeneratorOperator,
                                     bpy.types.Operator):
    """Add evenly spaced in-between poses from shape differences between two keys, as shape
    keys or as a point cache on a new object"""

    bl_idname = "shape_differences.inbetween"
    bl_label = "In-between"
    memory_advice = "lower Count or decimate the mesh"

    def run(self, context):
        require_count(self.count, "in-betweens")
        key_a, key_b, interpolator = yield from self.pair_interpolator(
            context, "key_a", "key_b", ("From", "To"), n_poses=self.count + 2 * (self.output == 'CACHE'))
        factors = [i / (self.count + 1) for i in range(1, self.count + 1)]
        poses = []
        for i, factor in enumerate(factors, 1):
            poses.append((yield from self.compute((i - 1) / self.count, interpolator.pose, factor,
                                                   doing=f"the in-between at factor {factor:g}")))
        obj = context.active_object
        label = f"Inbetween {shorten(key_a.name, 16)}-{shorten(key_b.name, 16)} x{self.count}"
        if self.output == 'CACHE':  # the cache plays the whole motion, keys included
            poses = [mesh_data.shape_key_positions(key_a, obj), *poses, mesh_data.shape_key_positions(key_b, obj)]
        names, tails = zip(*(inbetween_name(key_a.name, key_b.name, f) for f in factors))
        self.summary = self.write_poses(context, obj, poses, names=names, tails=tails,
                                        frames=scene_frames(context, len(poses)), label=label, keyed=True)


class SHAPE_DIFFERENCES_OT_exaggerate(ExaggeratedPose, PoseOutput, KeyPairProperties,
                                      InbetweenSettingsProperties, PoseWriter, GeneratorOperator,
                                      bpy.types.Operator):
    """Add a pose pushed further from a reference pose (factor > 1) or toned down (factor < 1),
    through shape differences, as a shape key or as a point cache on a new object"""

    bl_idname = "shape_differences.exaggerate"
    bl_label = "Exaggerate"

    def run(self, context):
        reference, key, interpolator = yield from self.pair_interpolator(
            context, "reference", "key", ("Reference", "Key"), advice="decimate the mesh")
        pose = yield from self.compute(0.5, interpolator.pose, self.factor,
                                       doing=f"the pose at factor {self.factor:g}")
        tail = f" {format_factor(self.factor)} from {shorten(reference.name, 20)}"
        self.summary = self.write_poses(
            context, context.active_object, [pose], names=[f"Exaggerate {key.name}"], tails=[tail],
            frames=scene_frames(context, 1), label=f"Exaggerate {shorten(key.name, 16)}{tail}", keyed=True)


class SHAPE_DIFFERENCES_OT_reconstruct(PoseKey, PoseOutput, CoreSettingsProperties,
                                       PoseWriter, GeneratorOperator, bpy.types.Operator):
    """Add a pose rebuilt from its shape differences to the Basis at the current k_M, k_N and t
    (shows what a truncated basis keeps), as a shape key or as a point cache on a new object"""

    bl_idname = "shape_differences.reconstruct"
    bl_label = "Reconstruct"

    def run(self, context):
        obj = context.active_object
        key_blocks = key_blocks_of(obj)
        key = resolve_key(obj, self.key, "Key", default_pose_key(obj))
        if key == key_blocks[0]:
            raise InputError(f"'{key.name}' is the Basis, which the differences are measured "
                             "from: pick another shape key to reconstruct")
        self.key = key.name
        triangles = surface_triangles(obj, self)
        options = self.core_options(context, len(obj.data.vertices))
        if options["k_M"] is None:  # the full basis recovers areas exactly where the triangles allow it
            triangles = triangulation.area_recoverable_triangles(obj.data, triangles)
        self.check_output(obj)
        check_memory(1, len(obj.data.vertices), "The output", "decimate the mesh", work="reconstruct")
        yield 0.0
        core = load_core()
        base = mesh_data.shape_key_positions(key_blocks[0], obj)
        use_extrinsic = options.pop("use_extrinsic")
        reference = yield from self.compute(0.0, core.ReferenceShape, base, triangles,
                                            name=f"shape key '{key_blocks[0].name}'",
                                            offset=options.pop("offset"), use_extrinsic=use_extrinsic)
        differences = yield from self.compute(0.2, reference.shape_differences,
                                              mesh_data.shape_key_positions(key, obj), name=f"shape key '{key.name}'",
                                              **options)
        pose = yield from self.compute(0.5, core.reconstruct, base, triangles, differences)
        tail = f" (k {self.k_m or 'full'}/{self.k_n or 'full'})"
        self.summary = self.write_poses(
            context, obj, [pose], names=[f"Reconstruct {key.name}"], tails=[tail],
            frames=scene_frames(context, 1), label=f"Reconstruct {shorten(key.name, 16)}{tail}", keyed=True)
