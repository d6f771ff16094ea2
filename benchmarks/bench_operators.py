"""What the artist pays: the *In-between Frames* and *Retime* operators run in Blender (the PyPI
``bpy`` module) on a cloth baked in the same process, against Blender's bake of that cloth.

Each scene of ``benchmarks/cloth_scenes.py`` named is built and baked anew (its first ``--frames``
frames; the bake timed by CPU time, per simulated frame), then each operator is run with every
output asked for, and its CPU time split into

- read: the key frames read from the cloth (``FrameRangeProperties.read_frames``: frame changes,
  the evaluated mesh, the checks of what was read);
- core: the core calls the operator makes (``GeneratorOperator.compute``);
- write: the shape keys or the point cache file and its object (``PoseWriter.write_poses``);
- update: the view layer updates ``bpy.ops`` runs before and after an operator (Blender evaluating
  what the operator changed, as a redraw of the UI would; shape keys written on the cloth are
  evaluated inside the operator instead, with the scene's return to its frame: in ``other``);
- undo: an undo step pushed after the operator (``ed.undo_push``), as Blender pushes one after
  an operator declaring 'UNDO' run from the UI;
- other: the rest of the operator (settings, triangles, world matrices, the scene set back to its
  frame after writing shape keys, ...).

Before the runs, Blender's own cost of setting the scene to a baked frame and to the cloth's start
frame (where it builds the cloth anew) is printed: what reading and writing cost at least.

Times are per in-between written (the poses that are not keys) and × the bake's time per frame;
``core alone`` is ``core.SequenceInterpolator`` on the same keys (its ``poses`` per gap), without
Blender. A digest of the written positions (shape keys' coordinates, the cache file's bytes)
is printed to compare runs bitwise.

    python -m benchmarks.bench_operators --scenes flag_soft_20k sheet_cube_50k [--frames 33]
                                         [--steps 4 8] [--outputs CACHE SHAPE_KEYS] [--speed 0.5]
                                         [--repeat 1] [--profile OUT.prof]

Run it with one BLAS thread (``OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1``): the times are CPU times
of the whole process (Blender's own threads included).
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import hashlib
import importlib
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

import dev_extension  # noqa: E402  (sets BLENDER_USER_RESOURCES before bpy is imported)
from benchmarks import cloth_scenes  # noqa: E402

PARTS = ("read", "core", "write", "update", "undo", "other")


class Clock:
    """CPU seconds spent inside the wrapped methods, by part."""

    def __init__(self):
        self.spent = dict.fromkeys(PARTS, 0.0)
        self.depth = 0

    @contextmanager
    def part(self, name):
        if self.depth:  # a part inside another counts as the outer one
            yield
            return
        self.depth += 1
        start = time.process_time()
        try:
            yield
        finally:
            self.spent[name] += time.process_time() - start
            self.depth -= 1

    def generator(self, name, method):
        """``method`` (a generator method) with the time spent in each of its steps counted."""
        clock = self

        def wrapped(*args, **kwargs):
            job = method(*args, **kwargs)
            value = None
            while True:
                try:
                    with clock.part(name):
                        item = job.send(value)
                except StopIteration as stop:
                    return stop.value
                value = yield item

        return wrapped

    def function(self, name, method):
        clock = self

        def wrapped(*args, **kwargs):
            with clock.part(name):
                return method(*args, **kwargs)

        return wrapped


def instrument(extension, clock: Clock):
    """Wrap the operators' reading, core calls and writing so that ``clock`` counts them."""
    frames = sys.modules[extension.__name__ + ".operators.frames"]
    base = sys.modules[extension.__name__ + ".operators.base"]
    output = sys.modules[extension.__name__ + ".operators.output"]
    frames.FrameRangeProperties.read_frames = clock.generator("read", frames.FrameRangeProperties.read_frames)
    compute = base.GeneratorOperator.compute

    def timed_compute(self, progress, function, *args, **kwargs):
        return (yield from compute(self, progress, clock.function("core", function), *args, **kwargs))

    base.GeneratorOperator.compute = timed_compute
    retime = importlib.import_module(extension.__name__ + ".core.retime")
    retime.motion_ends = clock.function("core", retime.motion_ends)  # called outside compute
    from bpy.ops import _BPyOpsSubModOp

    _BPyOpsSubModOp._view_layer_update = staticmethod(clock.function("update", _BPyOpsSubModOp._view_layer_update))
    output.PoseWriter.write_poses = clock.function("write", output.PoseWriter.write_poses)


def written_positions(bpy, extension, before_objects, obj, before_keys) -> tuple[list, np.ndarray]:
    """The poses the run wrote: (names, float32 (k, n, 3))."""
    new = [o for o in bpy.data.objects if o.name not in before_objects]
    if new:
        point_cache = sys.modules[extension.__name__ + ".core.point_cache"]
        path = bpy.path.abspath(new[0].modifiers["Mesh Cache"].filepath)
        return [new[0].name], np.asarray(point_cache.read_pc2(path).positions, dtype=np.float32)
    key = obj.data.shape_keys
    key_blocks = [kb for kb in key.key_blocks if kb.name not in before_keys and kb != key.reference_key]
    poses = []
    for kb in key_blocks:
        buffer = np.empty(len(kb.data) * 3, dtype=np.float32)
        kb.data.foreach_get("co", buffer)
        poses.append(buffer.reshape(-1, 3))
    return [kb.name for kb in key_blocks], np.array(poses)


def undo_back(bpy, obj, before_objects, before_keys):
    """Remove what a run added (the new object, or the new shape keys and their animation)."""
    for other in [o for o in bpy.data.objects if o.name not in before_objects]:
        mesh = other.data
        bpy.data.objects.remove(other)
        bpy.data.meshes.remove(mesh)
    key = obj.data.shape_keys
    if key is not None:
        if key.animation_data is not None and key.animation_data.action is not None:
            bpy.data.actions.remove(key.animation_data.action)
        obj.shape_key_clear()


def run_operator(bpy, extension, obj, clock, name, kwargs, with_undo: bool, profile):
    operator = getattr(bpy.ops.shape_differences, name)
    before_objects = set(bpy.data.objects.keys())
    before_keys = set(obj.data.shape_keys.key_blocks.keys()) if obj.data.shape_keys else set()
    clock.spent = dict.fromkeys(PARTS, 0.0)
    if profile is not None:
        profile.enable()
    start = time.process_time()
    operator(**kwargs)
    if with_undo:  # the step Blender pushes after an operator declaring 'UNDO' run from the UI
        with clock.part("undo"):
            bpy.ops.ed.undo_push(message=name)
    total = time.process_time() - start
    if profile is not None:
        profile.disable()
    names, poses = written_positions(bpy, extension, before_objects, obj, before_keys)
    digest = hashlib.sha256(poses.tobytes()).hexdigest()[:16]
    parts = dict(clock.spent)
    parts["other"] = total - sum(parts.values())
    undo_back(bpy, obj, before_objects, before_keys)
    return total, parts, len(poses), digest


def blender_frame_costs(scene, obj, repeat: int = 3) -> tuple[float, float]:
    """CPU seconds (least of ``repeat``) of setting the scene to a baked frame of ``obj``'s cloth and to
    its start frame, where Blender builds the cloth anew: what reading frames and writing on the
    cloth cost at least. The scene is left at the start frame."""
    first = next(m for m in obj.modifiers if m.type == "CLOTH").point_cache.frame_start
    costs = {first + 4: [], first: []}
    for _ in range(repeat):
        for frame, spent in costs.items():
            before = time.process_time()
            scene.frame_set(frame)
            spent.append(time.process_time() - before)
    return min(costs[first + 4]), min(costs[first])


def core_alone(core, frames: np.ndarray, triangles, step: int, count: int) -> float:
    """CPU seconds of ``core.SequenceInterpolator`` on the keys every ``step`` frames and all its
    in-betweens (``count`` per gap), as the operator asks for them."""
    keys = list(frames[::step])
    factors = [i / (count + 1) for i in range(1, count + 1)]
    start = time.process_time()
    sequence = core.SequenceInterpolator(keys, triangles)
    for gap in range(len(keys) - 1):
        sequence.poses(gap, factors)
    return time.process_time() - start


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", required=True, choices=sorted(cloth_scenes.SCENES))
    parser.add_argument("--frames", type=int, default=33, help="frames baked (from frame 1)")
    parser.add_argument("--steps", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--outputs", nargs="+", default=["CACHE", "SHAPE_KEYS"])
    parser.add_argument("--speed", type=float, default=0.5, help="Retime's speed (0: no retime)")
    parser.add_argument("--retime-step", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--no-undo", action="store_true", help="push no undo step after each run")
    parser.add_argument("--no-core", action="store_true", help="skip the core alone")
    parser.add_argument("--profile", help="write a cProfile of the operator runs here")
    args = parser.parse_args(argv)

    import bpy

    extension = dev_extension.enable()
    core = importlib.import_module(extension.__name__ + ".core")
    clock = Clock()
    instrument(extension, clock)
    profile = cProfile.Profile() if args.profile else None
    folder = Path(tempfile.mkdtemp(prefix="bench-operators-"))
    for name in args.scenes:
        spec = dataclasses.replace(cloth_scenes.SCENES[name], frames=args.frames)
        obj = cloth_scenes.build(spec)
        n = len(obj.data.vertices)
        bake = cloth_scenes.bake_all(time.process_time) / (spec.frames - 1)
        scene = bpy.context.scene
        if not args.no_undo:
            bpy.ops.ed.undo_push(message="baked")
        print(f"\n{name}: {n} vertices, {spec.frames} frames baked, {bake * 1e3:.0f} ms CPU per frame", flush=True)
        baked, start = blender_frame_costs(scene, obj)
        print(f"Blender's own: a baked frame set {baked * 1e3:.1f} ms, the cloth's start frame set {start * 1e3:.0f} ms "
              "(Blender builds the cloth there; as much again for each build after a change of its mesh)", flush=True)
        runs = [("inbetween_frames", output, dict(frame_start=1, frame_end=spec.frames, frame_step=step,
                                                   count=step - 1, output=output), step)
                for step in args.steps for output in args.outputs]
        if args.speed:
            runs += [("retime", output, dict(frame_start=1, frame_end=spec.frames, frame_step=args.retime_step,
                                             speed=args.speed, output=output), args.retime_step)
                     for output in args.outputs]
        for repeat in range(args.repeat + 1):  # the first round warms up (imports, caches), not shown
            for operator, output, kwargs, step in (runs if repeat else runs[:1]):
                if output == "CACHE":
                    kwargs = dict(kwargs, filepath=str(folder / f"{name}_{operator}_{step}_{repeat}.pc2"))
                scene.frame_set(1)
                total, parts, n_poses, digest = run_operator(bpy, extension, obj, clock, operator, kwargs,
                                                             not args.no_undo, profile)
                if not repeat:
                    continue
                n_keys = len(range(1, spec.frames + 1, step))
                inbetweens = n_poses - n_keys
                per = {part: 1e3 * seconds / inbetweens for part, seconds in parts.items()}
                label = f"{operator} step {step}" + (f" speed {args.speed:g}" if operator == "retime" else "")
                print(f"{label:30s} {output:10s} n={n} poses={n_poses:3d} inbetweens={inbetweens:3d} "
                      f"ms/inbetween {1e3 * total / inbetweens:7.1f} = "
                      + " ".join(f"{part} {per[part]:6.1f}" for part in PARTS)
                      + f"  x bake {total / inbetweens / bake:.3f}  digest {digest}", flush=True)
        if not args.no_core:
            read = dict(extension.bridge.frame_reading.frame_positions(bpy.context, obj,
                                                                       list(range(1, spec.frames + 1))))
            frames = np.array([read[frame] for frame in range(1, spec.frames + 1)])
            triangles = extension.bridge.triangulation.mesh_triangles(obj.data)
            for step in args.steps:
                seconds = core_alone(core, frames, triangles, step, step - 1)
                inbetweens = (len(range(0, spec.frames, step)) - 1) * (step - 1)
                print(f"{'core alone step ' + str(step):30s} {'':10s} n={n} inbetweens={inbetweens:3d} "
                      f"ms/inbetween {1e3 * seconds / inbetweens:7.1f}  x bake {seconds / inbetweens / bake:.3f}",
                      flush=True)
    if profile is not None:
        profile.dump_stats(args.profile)


if __name__ == "__main__":
    main()
