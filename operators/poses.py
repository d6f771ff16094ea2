"""Operators on the shape keys of the active mesh: in-between, exaggerate, reconstruct."""

import bpy
from bpy.props import FloatProperty, IntProperty, StringProperty

from .. import bridge
from .base import (CoreSettingsProperties, GeneratorOperator, InputError, default_pose_key,
                   key_blocks_of, load_core, require_distinct, resolve_key, surface_triangles)


def inbetween_name(name_a: str, name_b: str, factor: float) -> str:
    return f"Inbetween {name_a}-{name_b} {factor:.2f}"


class KeyPairProperties:
    """Interpolation between two shape keys of the active object, the first defaulting to the
    Basis and the second to the active key."""

    def pair_interpolator(self, context, first: str, second: str, labels: tuple[str, str]):
        """Validate the keys named by properties ``first`` and ``second`` (writing the resolved
        names back), yield once, and return ``(first key, second key, core.Interpolator)``."""
        obj = context.active_object
        key_blocks = key_blocks_of(obj)
        start = resolve_key(obj, getattr(self, first), labels[0], key_blocks[0])
        end = resolve_key(obj, getattr(self, second), labels[1], default_pose_key(obj))
        require_distinct(start, end, *labels)
        setattr(self, first, start.name)
        setattr(self, second, end.name)
        triangles = surface_triangles(obj)
        options = self.core_options(context, len(obj.data.vertices))
        yield 0.0
        interpolator = load_core().Interpolator(
            bridge.shape_key_positions(start), bridge.shape_key_positions(end), triangles,
            **options)
        return start, end, interpolator


def added_summary(names: list[str]) -> str:
    shown = names if len(names) <= 4 else [names[0], "...", names[-1]]
    return f"Added {len(names)} shape key{'s' if len(names) != 1 else ''}: " + ", ".join(shown)


class SHAPE_DIFFERENCES_OT_inbetween(KeyPairProperties, CoreSettingsProperties, GeneratorOperator,
                                     bpy.types.Operator):
    """Add evenly spaced in-between shape keys from shape differences between two keys"""

    bl_idname = "shape_differences.inbetween"
    bl_label = "In-between"

    key_a: StringProperty(name="From", description="First shape key (empty: the Basis)")
    key_b: StringProperty(
        name="To", description="Second shape key (empty: the active key, or the last one)")
    count: IntProperty(name="Count", min=1, soft_max=50, default=3,
                       description="Number of in-between keys, evenly spaced between the two")

    def run(self, context):
        key_a, key_b, interpolator = yield from self.pair_interpolator(
            context, "key_a", "key_b", ("From", "To"))
        new_keys = []
        for i in range(1, self.count + 1):
            yield 0.5 * i / self.count
            factor = i / (self.count + 1)
            new_keys.append(bridge.NewShapeKey(
                inbetween_name(key_a.name, key_b.name, factor), interpolator.pose(factor)))
        self.summary = added_summary(bridge.add_shape_keys(context.active_object, new_keys))


class SHAPE_DIFFERENCES_OT_exaggerate(KeyPairProperties, CoreSettingsProperties,
                                      GeneratorOperator, bpy.types.Operator):
    """Add a shape key that pushes a pose further from a reference pose (factor > 1) or tones it
    down (factor < 1), through shape differences"""

    bl_idname = "shape_differences.exaggerate"
    bl_label = "Exaggerate"

    key: StringProperty(name="Key", description="Pose to exaggerate (empty: the active key)")
    reference: StringProperty(name="Reference",
                              description="Pose the change is measured from (empty: the Basis)")
    factor: FloatProperty(name="Factor", default=1.5, soft_min=0.0, soft_max=3.0,
                          description="1 = the key itself, above 1 exaggerates, below 1 tones down")

    def run(self, context):
        _reference, key, interpolator = yield from self.pair_interpolator(
            context, "reference", "key", ("Reference", "Key"))
        yield 0.5
        pose = bridge.NewShapeKey(f"Exaggerate {key.name} {self.factor:.2f}",
                                  interpolator.pose(self.factor))
        self.summary = added_summary(bridge.add_shape_keys(context.active_object, [pose]))


class SHAPE_DIFFERENCES_OT_reconstruct(CoreSettingsProperties, GeneratorOperator,
                                       bpy.types.Operator):
    """Add a shape key with a pose rebuilt from its shape differences to the Basis at the current
    k_M, k_N and t: shows what a truncated basis keeps"""

    bl_idname = "shape_differences.reconstruct"
    bl_label = "Reconstruct"

    key: StringProperty(name="Key", description="Pose to rebuild (empty: the active key)")

    def run(self, context):
        obj = context.active_object
        key_blocks = key_blocks_of(obj)
        key = resolve_key(obj, self.key, "Key", default_pose_key(obj))
        if key == key_blocks[0]:
            raise InputError(f"'{key.name}' is the Basis, which the differences are measured "
                             "from: pick another shape key to reconstruct")
        self.key = key.name
        triangles = surface_triangles(obj)
        options = self.core_options(context, len(obj.data.vertices))
        yield 0.0
        core = load_core()
        base = bridge.shape_key_positions(key_blocks[0])
        differences = core.shape_differences(base, bridge.shape_key_positions(key), triangles,
                                             **options)
        yield 0.5
        truncation = f"k {self.k_m or 'full'}/{self.k_n or 'full'}"
        pose = bridge.NewShapeKey(f"Reconstruct {key.name} ({truncation})",
                                  core.reconstruct(base, triangles, differences))
        self.summary = added_summary(bridge.add_shape_keys(obj, [pose]))
