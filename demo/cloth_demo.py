"""Demo: in-between a coarse cloth simulation with Shape Differences, headless.

A sheet falls onto a sphere (Cloth + Collision, baked). Every ``--step``-th frame is kept as a
key pose and the frames in between are rebuilt by ``shape_differences.inbetween_frames``; the
dropped frames of the real simulation are the ground truth, compared with the in-betweens and
with a plain linear blend of the same key poses. Saves ``demo_output/cloth_demo.blend`` (play
it: simulation, shape differences and linear blend side by side) and a Workbench picture.

    python demo/cloth_demo.py [--grid 24] [--frames 41] [--step 4] [--output demo_output]
"""

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import dev_extension  # noqa: E402  (before bpy: keeps the user's Blender configuration out)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

LABELS = ("Simulation", "Shape differences", "Linear blend")
COLORS = ((0.85, 0.55, 0.25, 1), (0.25, 0.6, 0.85, 1), (0.6, 0.6, 0.6, 1))
SPACING = 2.8


def build_cloth_scene(grid: int, frames: int):
    """A ``grid`` x ``grid`` vertex sheet falling on a sphere; the simulation is baked. Returns
    the cloth, the sphere and the seconds the bake took."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, segments=32, ring_count=16)
    sphere = bpy.context.active_object
    sphere.name = "Sphere"
    bpy.ops.object.shade_smooth()
    sphere.modifiers.new("Collision", 'COLLISION')
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=grid - 1, y_subdivisions=grid - 1, size=2.0,
                                    location=(0, 0, 0.9))
    cloth = bpy.context.active_object
    cloth.name = "Cloth"
    cloth.rotation_euler.z = 0.3
    bpy.ops.object.transform_apply(rotation=True)
    bpy.ops.object.shade_smooth()
    modifier = cloth.modifiers.new("Cloth", 'CLOTH')
    modifier.settings.quality = 5
    modifier.collision_settings.distance_min = 0.01
    modifier.point_cache.frame_start, modifier.point_cache.frame_end = 1, frames
    started = time.perf_counter()
    with bpy.context.temp_override(scene=scene):
        bpy.ops.ptcache.bake_all(bake=True)
    bake_seconds = time.perf_counter() - started
    scene.frame_set(1)
    return cloth, sphere, bake_seconds


def copy_without_cloth(obj, sphere, name: str, x: float):
    """A copy of the cloth mesh (with its shape keys) that has no Cloth modifier, and a sphere
    under it, moved ``x`` along the x axis."""
    copy = obj.copy()
    copy.data = obj.data.copy()
    copy.name = name
    copy.modifiers.clear()
    copy.location.x += x
    bpy.context.collection.objects.link(copy)
    sphere_copy = sphere.copy()
    sphere_copy.modifiers.clear()
    sphere_copy.location.x += x
    bpy.context.collection.objects.link(sphere_copy)
    return copy


def edge_lengths(positions: np.ndarray, edges: np.ndarray) -> np.ndarray:
    return np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)


def vertex_errors(poses: dict, truth: dict, size: float) -> dict:
    """Mean vertex distance to the truth per frame, in percent of the sheet size."""
    return {f: 100 * np.linalg.norm(poses[f] - truth[f], axis=1).mean() / size for f in truth}


def edge_error(poses: dict, truth: dict, edges: np.ndarray) -> float:
    """Mean relative edge-length error over all frames, in percent (stretch and shrink)."""
    return 100 * np.mean([np.abs(edge_lengths(poses[f], edges) / edge_lengths(truth[f], edges)
                                 - 1).mean() for f in truth])


def add_labels_camera_light(scene, width: float):
    for index, label in enumerate(LABELS):
        bpy.ops.object.text_add(location=(index * SPACING, -1.5, 0.0))
        text = bpy.context.active_object
        text.data.body, text.data.align_x, text.data.size = label, 'CENTER', 0.28
        text.rotation_euler.x = 1.1
    camera_data = bpy.data.cameras.new("Camera")
    camera_data.type, camera_data.ortho_scale = 'ORTHO', width + 0.6
    camera = bpy.data.objects.new("Camera", camera_data)
    scene.collection.objects.link(camera)
    camera.location, camera.rotation_euler = (SPACING, -7.0, 5.5), (np.radians(52), 0.0, 0.0)
    scene.camera = camera


def render(scene, path: Path, frame: int):
    scene.frame_set(frame)
    scene.render.engine = 'BLENDER_WORKBENCH'
    scene.display.shading.light = 'STUDIO'
    scene.display.shading.color_type = 'OBJECT'
    scene.display.shading.show_shadows = True
    scene.render.resolution_x, scene.render.resolution_y = 1200, 440
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGB'
    scene.render.image_settings.compression = 100
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--grid", type=int, default=24, help="vertices per side of the sheet")
    parser.add_argument("--frames", type=int, default=41)
    parser.add_argument("--step", type=int, default=4, help="keep every n-th frame")
    parser.add_argument("--output", type=Path, default=Path("demo_output"))
    parser.add_argument("--render-frame", type=int, default=None,
                        help="frame to render (default: where the linear blend is worst)")
    arguments = parser.parse_args()
    arguments.output.mkdir(parents=True, exist_ok=True)
    extension = dev_extension.enable()
    bridge = extension.bridge

    cloth, sphere, bake_seconds = build_cloth_scene(arguments.grid, arguments.frames)
    scene = bpy.context.scene
    per_frame = bake_seconds / (arguments.frames - 1)
    print(f"Baked a {len(cloth.data.vertices)}-vertex cloth over {arguments.frames} frames "
          f"in {bake_seconds:.1f} s ({per_frame:.3f} s per frame)")

    frames = list(range(1, arguments.frames + 1))
    truth_all = dict(bridge.frame_reading.frame_positions(bpy.context, cloth, frames))
    key_frames = frames[::arguments.step]
    count = arguments.step - 1

    # The operator's default output: a PC2 point cache played by a Mesh Cache modifier on a new
    # object; the baked cloth itself is left as it was.
    started = time.perf_counter()
    before = set(bpy.data.objects)
    bpy.ops.shape_differences.inbetween_frames(
        frame_start=1, frame_end=key_frames[-1], frame_step=arguments.step, count=count,
        output='CACHE', filepath=str((arguments.output / "cloth_inbetweens.pc2").resolve()))
    seconds = time.perf_counter() - started
    (ours_object,) = set(bpy.data.objects) - before
    made = (len(key_frames) - 1) * count
    print(f"shape_differences.inbetween_frames: {len(key_frames)} key poses, {count} in-betweens "
          f"per gap in {seconds:.1f} s (reading the keys and writing the cache included: "
          f"{seconds / made:.3f} s per in-between, {seconds / made / per_frame:.2f} x the bake's "
          f"time per frame), played by '{ours_object.name}' from {ours_object.modifiers[0].filepath}")

    # The in-betweens land on the dropped frames: compare with the simulation there.
    dropped_frames = [frame for frame in frames[: key_frames[-1]] if frame not in key_frames]
    played = dict(bridge.frame_reading.frame_positions(bpy.context, ours_object, dropped_frames))
    ours, linear, truth = {}, {}, {}
    for frame, next_frame in zip(key_frames, key_frames[1:]):
        for i in range(1, count + 1):
            dropped = frame + i
            factor = i / (count + 1)
            ours[dropped] = played[dropped]
            linear[dropped] = (1 - factor) * truth_all[frame] + factor * truth_all[next_frame]
            truth[dropped] = truth_all[dropped]
    edges = np.array([edge.vertices[:] for edge in cloth.data.edges])
    print(f"Error on the {len(truth)} dropped frames (vertex error in % of the sheet size; "
          "edge-length error in %):")
    print(f"  {'':18} {'mean':>7} {'worst frame':>12} {'edge length':>12}")
    for label, poses in (("shape differences", ours), ("linear blend", linear)):
        errors = vertex_errors(poses, truth, size=2.0)
        print(f"  {label:18} {np.mean(list(errors.values())):7.2f} "
              f"{max(errors.values()):12.2f} {edge_error(poses, truth, edges):12.2f}")
    linear_errors = vertex_errors(linear, truth, size=2.0)
    worst_linear_frame = max(linear_errors, key=linear_errors.get)

    # Playback: the cache object and a copy with a linear blend of the key poses.
    ours_object.name = "Cloth (shape differences)"
    ours_object.location.x += SPACING
    sphere_copy = sphere.copy()
    sphere_copy.modifiers.clear()
    sphere_copy.location.x += SPACING
    scene.collection.objects.link(sphere_copy)
    linear_object = copy_without_cloth(cloth, sphere, "Cloth (linear blend)", 2 * SPACING)
    linear_object.shape_key_clear()
    bridge.shape_keys.add_shape_keys(linear_object,
                                     [bridge.shape_keys.NewShapeKey(f"Frame {f}", truth_all[f]) for f in key_frames],
                                     keyframes=key_frames)
    for obj, color in zip((cloth, ours_object, linear_object), COLORS):
        obj.color = color
    add_labels_camera_light(scene, width=3 * SPACING)

    blend_path = (arguments.output / "cloth_demo.blend").resolve()
    bpy.ops.wm.save_as_mainfile(filepath=str(blend_path))
    render_frame = arguments.render_frame or worst_linear_frame
    picture = (arguments.output / "cloth_demo.png").resolve()
    started = time.perf_counter()
    render(scene, picture, render_frame)
    print(f"Saved {blend_path} and {picture} (frame {render_frame}, rendered in "
          f"{time.perf_counter() - started:.1f} s)")


if __name__ == "__main__":
    main()
