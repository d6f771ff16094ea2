"""Operators on the evaluated animation of the active mesh (cloth, armature, any modifiers):
capture frames, in-between every n-th frame, retime."""

import math
import time
from contextlib import closing, contextmanager

import bpy
import numpy as np
from bpy.props import IntProperty

from ..bridge import copied_motion, frame_checks, frame_reading, modifier_kinds, world_space
from ..properties import (AnimationOutput, CaptureStep, InbetweensPerGap, KeyStep, PoseOutput,
                          Speed)
from .base import (INBETWEENED_IN_WORLD, GeneratorOperator, InbetweenSettingsProperties, InputError,
                   check_memory, check_shown_in_world, finite_pose, frame_name, in_world, load_core, playback_range,
                   report, require_count, surface_triangles)
from .motion_sources import (dynamic_paint_start, frames_depend_on_earlier, missing_zone_bake, modifiers_set_aside,
                             motion_set_aside, object_motion, objects_moving, render_only_motion, simulation_zone_start,
                             unbaked_simulations, unfit_mesh_cache, viewport_only_motion)
from .output import PoseWriter
from .poses import format_factor, inbetween_name, rest_option


def frame_key_name(frame: int) -> str:
    return f"Frame {frame}"


def simulation_start(scene, movers: list) -> int | None:
    """The first frame of the unbaked simulations of ``movers``, an object and the objects that move
    it (a cloth proxy driving it through a Surface Deform: :func:`objects_moving`), of their
    Geometry Nodes simulation zones (:func:`simulation_zone_start`; baked or not, which the Python API
    does not tell) and of their Dynamic Paint canvases (:func:`dynamic_paint_start`; baked or not, as
    :func:`frames_depend_on_earlier` takes them): reading frames starts there, so that a simulation
    that is not baked is computed from its start, one frame at a time."""
    starts = [mover.modifiers[name].point_cache.frame_start for mover in movers
              for name in unbaked_simulations(mover)]
    starts += [start for mover in movers for modifier in mover.modifiers if modifier.show_viewport
               for start in (simulation_zone_start(scene, modifier), dynamic_paint_start(modifier))
               if start is not None]
    return min(starts) if starts else None


def simulation_first_frame(scene, obj, start: int, end: int) -> list[int]:
    """``[frame]``: the first frame of the cloth and soft body simulations moving ``obj``
    (:func:`objects_moving`), where a range ``start``–``end`` does not begin there; else ``[]``. The mesh
    is at its rest there (the simulation starts from it), which a range cut from inside the motion
    does not begin at; a range that begins before it reads the mesh the simulation is given, not yet
    simulated (Blender holds a simulation at its input before its first frame), and the rest is the
    mesh at that frame, inside the range (none where the range ends before it or at it: nothing in it
    is simulated, that frame showing the mesh the simulation is given, as every frame before it).
    ``[]`` also where reading it would have more frames evaluated than the range's:
    where ``scene``'s frames are read one after the other (:func:`frames_depend_on_earlier`: an unbaked
    simulation anywhere in it) from the range's start or an unbaked simulation's of ``obj``
    (:func:`simulation_start`), after that frame (each frame from there would be evaluated, and
    simulated where not baked, for a measure of the warnings)."""
    movers = objects_moving(obj)
    first = _first_simulated(movers)
    if first is None or first == start:
        return []
    if first > start:  # inside the range: read with it, or between its frames (one frame more at most)
        return [first] if first < end else []
    visited = simulation_start(scene, movers)
    if frames_depend_on_earlier(scene) and first < (start if visited is None else min(start, visited)):
        return []
    return [first]


def _first_simulated(movers: list) -> int | None:
    """The first frame of the cloth and soft body simulations of ``movers`` (:func:`objects_moving`), or None."""
    return min((modifier.point_cache.frame_start for _, modifier in modifier_kinds.simulations(movers)),
               default=None)


def cloth_rest_is_input(obj, modifier) -> bool:
    """Whether the cloth ``modifier`` of ``obj`` builds its springs from the mesh it is given at its first
    frame (what the frames show there, its edges times 1 − Shrinking). Not with *Dynamic Mesh* (the springs
    follow that mesh at every frame), nor with a *Rest Shape Key* set behind any enabled modifier outside
    ``bridge.modifier_kinds.DEFORM_ONLY_MODIFIERS`` (a Subdivision Surface, a Weld, Geometry Nodes, even a
    UV Project): Blender may build the springs from the key there (the modifier stack adds the key as a layer of the mesh before
    the first such modifier and carries it through; those that rebuild the mesh through BMesh, an Edge Split
    or a Triangulate, drop it, and the rest is then the first frame after all: no rest, cautious). Behind
    deform-only modifiers or none, Blender 4.2–5.0 read no Rest Shape Key (the cloth modifier's own copy of
    the key runs only where it is given no mesh, which never happens: ``MOD_cloth.cc``, ``deform_verts``),
    so the cloth's rest is that first frame whatever the key (docs/inbetween-measurements.md, *The cloth's
    Rest Shape Key*)."""
    settings = modifier.settings
    if settings.use_dynamic_mesh:
        return False
    if settings.rest_shape_key is None:
        return True
    before = modifier_kinds.enabled_before(obj, modifier)
    return all(m.type in modifier_kinds.DEFORM_ONLY_MODIFIERS for m in before)


def rest_length_factor(obj) -> float | None:
    """The factor the cloth and soft body simulations moving ``obj`` (:func:`objects_moving`) set their
    springs' rest lengths to over their first frame's edges: 1 − Shrinking for cloth (``shrink_min``:
    at 0.1 frame 1's edges read 1 / 0.9 = 1.111 × every later frame's, at −0.2 0.833 ×), 1 where nothing
    changes them. None where it differs over the mesh or between the simulations (a Shrinking vertex
    group between two factors), where Blender does not say by how much (a soft body's Shrink / Blow up
    ``spring_length`` or its ``plastic`` deformation) or where a cloth's springs are not built from its
    first frame (:func:`cloth_rest_is_input`: Dynamic Mesh, a Rest Shape Key Blender reads). The one
    source of the rest's scale for a sequence's rest (:class:`SimulationRest`) and two poses'
    (``poses.basis_rest``)."""
    factors = set()
    for mover, modifier in modifier_kinds.simulations(objects_moving(obj)):
        settings = modifier.settings
        if modifier.type != 'CLOTH':
            if settings.spring_length or settings.plastic:
                return None
            factors.add(1.0)
        elif (settings.vertex_group_shrink and settings.shrink_max != settings.shrink_min) or \
                not cloth_rest_is_input(mover, modifier):
            return None
        else:
            factors.add(1.0 - settings.shrink_min)
    return factors.pop() if len(factors) == 1 else (1.0 if not factors else None)


class SimulationRest:
    """The rest a sequence's warnings measure the edges from (``rest_pose`` of
    :class:`core.SequenceInterpolator`) where a range ``start``–``end`` of ``obj`` does not start at the
    first frame of a cloth or soft body simulation inside it: that frame (:func:`simulation_first_frame`),
    read with the range's frames (:attr:`frames`: the frame to read, or none), set aside before the
    range's space is chosen where the range does not read it itself (:meth:`set_aside`: it is for the
    warnings alone, so the space and the in-betweens are the range's as without it), then taken to that
    space (:meth:`options`). A range that starts before the simulation begins with the mesh as the
    simulation is given it, not at its rest lengths where Shrinking is set: the simulation's first frame
    is the rest there too. A range that starts at the simulation's first frame is given its first key as
    the rest: the sequence then reads its keys' deviations as from a rest whatever start
    :func:`core.retime.motion_ends` chooses (``start="keys"`` alone says the keys are cut from a motion,
    and a key the cloth bounces back from is read only from a rest:
    :func:`core.sequence_caught_stretch.caught_stretch`); the deviations are those from the first key, as
    without it, the warnings naming it the rest pose. Else the first key stands for the rest. A cloth that Shrinking shrinks or grows
    is at its rest lengths times :func:`rest_length_factor` there, not at its edges (frame 1 of Shrinking
    0.1 read as the rest makes every key 11 % off it, and the warnings allow that much more misfit): its
    edges are scaled so, and so are the first key's where the range starts at the simulation's first
    frame. Where the factor is not one number or the springs are not built from that frame
    (:func:`rest_length_factor`: Dynamic Mesh, a Rest Shape Key behind a modifier not of Blender's
    deform-only kind), no frame is read and none is given."""

    def __init__(self, scene, obj, start: int, end: int):
        self.start, self.frames, self._read = start, simulation_first_frame(scene, obj, start, end), []
        self._factor = rest_length_factor(obj)
        if self._factor is None:
            self.frames = []
        # a range from the simulation's first frame: its first key is the rest (at other lengths where Shrinking
        # is set), given as such so that the sequence knows it whatever start the motion's ends choose
        self._from_start = self._factor is not None and _first_simulated(objects_moving(obj)) == start

    def set_aside(self, read: dict, matrices: dict, own_frames: list) -> None:
        """Take the rest frame's positions and world matrix out of ``read`` and ``matrices`` ({frame: …}
        of the frames read) where it is not one of the range's ``own_frames`` (those it read for
        itself: a range that starts before the simulation may key its first frame), and keep the range's
        first frame's positions (its matrix too where that frame is the rest)."""
        kept = set(own_frames)
        self._read = [((read[frame], matrices[frame]) if frame in kept else (read.pop(frame), matrices.pop(frame)))
                      + (read[self.start],) for frame in self.frames]
        if self._from_start:
            self._read = [(read[self.start], matrices[self.start], read[self.start])]

    def options(self, space, matrices: dict, triangles) -> dict:
        """``{"rest_pose": positions (n, 3)}`` in ``space`` (that of the range's frames, whose world
        matrices are ``matrices``): the rest as the world shows it at its frame, in the first key's
        coordinates, then in the range's space, scaled about its centroid by :func:`rest_length_factor`;
        ``{}`` where there is no rest frame, where the world flattens the mesh there, or where the core
        would refuse it against the first key (``core.rest_pose_scale``: a cloth that shrinks or grows
        to under half or over twice its size other than by Shrinking): measured from the first key, as
        without it. ``triangles`` (m, 3): the mesh's."""
        for positions, matrix, first in self._read:
            shown = world_space.shown_under(positions, matrix, matrices[self.start])
            if shown is None:
                continue
            rest, first = space.to(shown, self.start), space.to(first, self.start)
            option = rest_option(rest, self._factor, first, triangles)  # Shrinking's rest lengths
            if option:
                return option
        return {}


class FrameRangeProperties:
    """Frame range properties; start and end default to the playback range when not set (the
    preview range where it is on, else the scene's)."""

    frame_start: IntProperty(name="Start", description="First frame (default: the start of the preview "
                                                       "range where it is on, else of the scene)")
    frame_end: IntProperty(name="End", description="Last frame (default: the end of the preview range "
                                                   "where it is on, else of the scene)")

    minimum_frames = 1

    def frame_range(self, context) -> tuple[int, int]:
        """Start and end frame; resolved values are written back for the Redo panel. The step is
        checked here too: every operator reading frames asks for its range first."""
        for name, frame in zip(("frame_start", "frame_end"), playback_range(context.scene)):
            if not self.properties.is_property_set(name):
                setattr(self, name, frame)
        if self.frame_step < 1:
            raise InputError(f"Step is {self.frame_step}: take every frame (Step 1) or every n-th (Step n)")
        if self.frame_start > self.frame_end:
            raise InputError(f"The frame range starts at {self.frame_start}, after its end at {self.frame_end}: "
                             "swap Start and End")
        from ..core.retime import MAX_FRAME

        beyond = next((frame for frame in (self.frame_start, self.frame_end) if abs(frame) > MAX_FRAME), None)
        if beyond is not None:  # the scene would show the nearest frame Blender has, under this one's name
            raise InputError(f"Frame {beyond:,} is beyond Blender's frames ({-MAX_FRAME:,} to {MAX_FRAME:,}): "
                             "pick a frame range within them")
        return self.frame_start, self.frame_end

    def frames(self, context) -> list[int]:
        """Every ``frame_step``-th frame of the range (at least ``minimum_frames`` of them)."""
        start, end = self.frame_range(context)
        frames = list(range(start, end + 1, self.frame_step))
        if len(frames) < self.minimum_frames:
            from ..core.retime import step_remedy

            raise InputError(
                f"Frames {start} to {end} with step {self.frame_step} give "
                f"{len(frames)} frame{'s' if len(frames) != 1 else ''}, at least {self.minimum_frames} are "
                f"needed: use {step_remedy(end - start + 1, self.frame_step, self.minimum_frames)}")
        return frames

    def read_keys(self, context, obj, keys: list[int], progress_share: float, also=(), matrices: dict | None = None,
                  stay: bool = False):
        """Yield progress while reading the evaluated mesh at the key frames ``keys`` and the frames
        ``also``; returns the keys' positions and {frame: positions} of every frame read.
        ``matrices``: a dict that gets {frame: ``obj``'s world matrix} of every frame read; ``stay``:
        as for :meth:`read_frames`."""
        frames = sorted(set(keys) | set(also))
        read_matrices = [] if matrices is not None else None
        read = dict(zip(frames, (yield from self.read_frames(context, obj, frames, progress_share, read_matrices,
                                                             stay))))
        if matrices is not None:
            matrices.update(zip(frames, read_matrices))
        return [read[f] for f in keys], read

    @staticmethod
    @contextmanager
    def frame_set_back(context):
        """Run the block, then set the scene back to the frame (and sub-frame) it is at now where it was
        left at another, also when the block fails or the run is cancelled: around reading with
        ``stay`` (:meth:`read_frames`) and writing shape keys on the object read."""
        scene = context.scene
        frame, subframe = scene.frame_current, scene.frame_subframe
        try:
            yield
        finally:
            if (scene.frame_current, scene.frame_subframe) != (frame, subframe):
                scene.frame_set(frame, subframe=subframe)

    def read_frames(self, context, obj, frames: list[int], progress_share: float, matrices: list | None = None,
                    stay: bool = False):
        """Yield progress while reading the evaluated mesh at ``frames``; returns the positions.
        ``matrices``: a list that gets ``obj``'s world matrix at each of ``frames``. ``stay``: the scene
        may be left at the last frame read (:func:`bridge.frame_reading.frame_positions`), for a run that writes shape
        keys on ``obj`` next and sets the scene back after (inside :meth:`frame_set_back`): Blender then
        evaluates the new keys and the return to the scene's frame at once, where a return first and the
        keys after cost a cloth one more build at its start frame."""
        read, shown = {}, {}
        movers = objects_moving(obj)
        unfit = unfit_mesh_cache(obj, movers)
        if unfit:  # an error, as for a file that is gone: every frame would read the rest mesh
            raise frame_reading.CacheFileUnfit(unfit)
        lost = missing_zone_bake(obj, movers)
        if lost:  # before any frame: reading would simulate the zone again
            raise frame_reading.BakeFilesMissing(lost)
        aside = modifiers_set_aside(context, obj)
        # what the unbaked caches hold before ("0 frames in memory"): it grows where frames are simulated
        unbaked = {(mover, modifier): modifier.point_cache.info
                   for mover, modifier in modifier_kinds.simulations(movers)
                   if not modifier.point_cache.is_baked}
        began = time.monotonic()
        reader = frame_reading.frame_positions(context, obj, frames,
                                               first_visit=simulation_start(context.scene, movers),
                                               every_frame=frames_depend_on_earlier(context.scene), set_aside=aside,
                                               stay=stay)
        with closing(reader) as frame_reader:
            for frame, positions in frame_reader:  # in the order visited (bridge.frame_reading.frame_positions)
                read[frame] = positions
                if matrices is not None:
                    shown[frame] = obj.matrix_world.copy()
                yield progress_share * len(read) / len(frames)
        poses = [read[frame] for frame in frames]
        if matrices is not None:
            matrices.extend(shown[frame] for frame in frames)
        # named by frame and object (the core names only its argument); a NaN captured into a key
        # would hide its vertex wherever the key plays
        for frame, positions in zip(frames, poses):
            finite_pose(positions, f"frame {frame} of '{obj.name}'")
        # an error, as for a cache of another vertex count: the frames are not this mesh's poses
        foreign = frame_checks.frames_of_another_mesh(obj, frames, poses, movers)
        if foreign:
            raise frame_reading.CacheFileUnfit(foreign)
        lost = frame_checks.missing_bake(obj, frames, poses, movers)
        if lost:  # an error, not a warning: a batch or farm job must fail rather than write a still mesh
            raise frame_reading.BakeFilesMissing(lost)
        unread = frame_checks.cache_reads_no_positions(obj, frames, poses, movers)
        if unread:  # the same: the cache plays the mesh at rest
            raise frame_reading.CacheFileUnfit(unread)
        still = frame_checks.still_frames(obj, frames, poses)
        if still:  # the motion may be in what was set aside (an animated Displace after a Subdivision)
            still = motion_set_aside(context, obj, frames, aside) or still
        if still and "rigid_body" in object_motion(obj):  # a simulation that moves no vertex of the mesh
            still = (f"The {len(frames)} frames read from '{obj.name}' ({frames[0]}–{frames[-1]}) are all the same "
                     "pose: its rigid body simulation moves it as a whole (its place in the world, not the "
                     "vertices of its mesh), so there is no deformation to read or in-between")
        for warning in (render_only_motion(obj, movers), viewport_only_motion(obj, movers),
                        frame_checks.frames_outside_simulation(obj, frames, movers),
                        frame_checks.frames_outside_cache(context.scene, obj, frames, movers),
                        frame_checks.frames_held_by_cache(obj, frames, poses, movers), still):
            if warning:
                report(self, {'WARNING'}, warning)
        simulated = [(mover, modifier) for (mover, modifier), held in unbaked.items()
                     if modifier.point_cache.info != held]
        if simulated:  # a farm task or batch simulates them again, which at 100k vertices takes hours
            named = ", ".join(f"'{modifier.name}' of '{mover.name}'" for mover, modifier in simulated)
            report(self, {'WARNING'}, f"{named} {'is' if len(simulated) == 1 else 'are'} not baked, and "
                                      f"frames {frames[0]}–{frames[-1]} were simulated for this run where its "
                                      f"cache held none (reading took {time.monotonic() - began:.1f} s): bake it "
                                      "(Physics › Cache › Bake) before sending the file to a farm or batch, so "
                                      "that tasks read the frames instead")
        return poses


class SHAPE_DIFFERENCES_OT_frames_to_shape_keys(CaptureStep, PoseOutput, FrameRangeProperties,
                                                PoseWriter, GeneratorOperator, bpy.types.Operator):
    """Capture the evaluated mesh (after cloth, armature and other modifiers) at every n-th
    frame, as one shape key per frame or as a point cache on a new object"""

    bl_idname = "shape_differences.frames_to_shape_keys"
    bl_label = "Frames to Shape Keys"
    memory_advice = "raise Step or narrow the frame range"

    def run(self, context):
        with self.frame_set_back(context):
            yield from self.capture(context)

    def capture(self, context):
        obj = context.active_object
        if not len(obj.data.vertices):
            raise InputError(f"The mesh of '{obj.name}' has no vertices: there is nothing to capture")
        frames = self.frames(context)
        self.check_captured_output(obj)
        check_memory(len(frames), len(obj.data.vertices), "The output", "raise Step or narrow the frame range",
                     work=None)
        poses = yield from self.read_frames(context, obj, frames, 1.0, stay=self.output == 'SHAPE_KEYS')
        self.summary = self.write_poses(
            context, obj, poses, names=[frame_key_name(frame) for frame in frames],
            frames=[float(frame) for frame in frames],
            label=f"Frames {frames[0]}-{frames[-1]}"
                  + (f" step {self.frame_step}" if self.frame_step > 1 else ""))


class SHAPE_DIFFERENCES_OT_inbetween_frames(KeyStep, InbetweensPerGap, AnimationOutput,
                                            InbetweenSettingsProperties, FrameRangeProperties,
                                            PoseWriter, GeneratorOperator, bpy.types.Operator):
    """Take every n-th evaluated frame as a key pose and add in-betweens for each gap: as a point
    cache on a new object (the active object stays as it was), or as shape keys whose values are
    keyframed so playback shows the denser motion"""

    bl_idname = "shape_differences.inbetween_frames"
    bl_label = "In-between Frames"
    memory_advice = ("lower In-betweens per gap (made at once for each gap), raise Step or narrow the frame range, "
                     "or on a farm run python -m core retime in parts (--chunk I/N)")

    minimum_frames = 2

    def run(self, context):
        with self.frame_set_back(context):
            yield from self.inbetween(context)

    def inbetween(self, context):
        obj = context.active_object
        require_count(self.count, "in-betweens per gap")
        frames = self.frames(context)
        triangles = surface_triangles(obj, self)
        options = self.core_options(context, len(obj.data.vertices))
        self.check_captured_output(obj, keyframed=True)
        end = self.frame_range(context)[1]
        # the keys, the in-betweens of each gap and, for a range that is not whole steps, those of
        # the shorter last gap (at most as many) and the last frame
        gaps = len(frames) - 1 + (end > frames[-1])
        check_memory(len(frames) + (end > frames[-1]) + gaps * self.count, len(obj.data.vertices),
                     "The output", "lower In-betweens per gap or the frame range", batch=self.count)
        # a range that is not whole steps ends with a shorter gap, keyed by its own sequence (core.retime)
        retime = load_core_retime()
        tail = (frames[0] + retime.short_gap_keys(frames[-1] - frames[0], end - frames[0])).tolist()
        # the last frame keys the sequence too, at its time (the gap before sees it so)
        keyed = frames + ([end] if tail else [])
        # how the motion leaves the first key and reaches the last: told by the frames in the middle
        # of the first and last gaps of the sequence keyed (core.retime.motion_ends)
        middles = [ends[3] for ends in (retime.start_samples(keyed), retime.end_samples(keyed, tail))
                   if ends and ends[3] is not None]
        # the in-betweens' second process started now, where the sequence may share its gaps with it: its
        # start overlaps the reading of the frames rather than the first gaps (core.gap_processes)
        start_gap_worker(len(obj.data.vertices), len(keyed) - 1, options["k_M"])
        # a range starting inside a cloth or soft body simulation, or before it: its first frame read too, the
        # rest the warnings measure the edges from
        rest = SimulationRest(context.scene, obj, frames[0], end)
        matrices = {}
        _poses, read = yield from self.read_keys(context, obj, frames, 0.2, also=tail + middles + rest.frames,
                                                 matrices=matrices, stay=self.output == 'SHAPE_KEYS')
        rest.set_aside(read, matrices, frames + tail + middles)
        # an object scaled differently at different frames: interpolated in the world, where the simulation ran
        space = world_space.frames_space(context, obj, matrices)
        scaled = dict(zip(read, in_world(obj, space, read.values(), read, triangles, INBETWEENED_IN_WORLD)))
        # chosen in that space: an object scaled up from rest leaves its first key moving in its own coordinates
        options.update(retime.motion_ends(scaled, keyed, tail))
        options.update(rest.options(space, matrices, triangles))
        sequence = yield from self.compute(0.2, load_core().SequenceInterpolator, [scaled[f] for f in keyed],
                                           triangles, **options, key_times=keyed,
                                           doing=f"preparing the {len(keyed)} keys",
                                           key_names=[frame_name(f) for f in keyed])
        names, tails, all_poses, timeline = [], [], [], []
        factors = [i / (self.count + 1) for i in range(1, self.count + 1)]
        spans = [(gap, frame, next_frame, factors) for gap, (frame, next_frame) in enumerate(zip(frames, frames[1:]))]
        ends = True  # the last frame is written
        if tail:  # in-betweens as many frames apart as in the whole gaps
            spacing, short = self.frame_step / (self.count + 1), end - frames[-1]
            spans.append((None, frames[-1], end, [i * spacing / short for i in range(1, self.count + 1)
                                                  if i * spacing < short * (1 - 1e-9)]))
            # a point cache plays evenly spaced frames: the last frame only if it is one of them
            ends = self.output == 'SHAPE_KEYS' or abs(short / spacing - round(short / spacing)) < 1e-9
        # each in-between's time, and the object's matrix there where its scale is keyframed: read
        # in one pass over the frames, before the gaps' poses go back through them
        spans = [(gap, frame, after, gap_factors, [frame + factor * (after - frame) for factor in gap_factors])
                 for gap, frame, after, gap_factors in spans]
        inbetween_times = [time for *_, times in spans for time in times]
        with closing(space.reading(inbetween_times)) as reading:
            for _ in reading:
                yield 0.2
        check_shown_in_world(obj, space, inbetween_times, INBETWEENED_IN_WORLD)
        for gap, frame, next_frame, gap_factors, times in spans:
            names.append(frame_key_name(frame)), tails.append(""), all_poses.append(read[frame])
            timeline.append(frame)
            progress = 0.2 + 0.8 * len(timeline) / ((len(spans) + 1) * (self.count + 1))
            if gap is None and gap_factors:
                sequence = yield from self.compute(progress, retime.short_gap_sequence, scaled, triangles, tail,
                                                   frames[0], **options, key_names=[frame_name(f) for f in tail],
                                                   doing=f"preparing the keys after frame {frame:g}")
                gap = len(sequence) - 1  # its last gap is the short one
            if gap_factors:  # all in-betweens of a gap in one call: the core shares the work between them
                # kept as float32, what shape keys and point caches store
                doing = f"the in-betweens of frames {frame:g}-{next_frame:g}"
                # nothing begun ahead of the sequence's last gap asked (the shorter last gap has its own)
                ahead = gap + 1 < len(frames) - 1
                all_poses.extend(space.back((yield from self.compute(progress, sequence.poses, gap, gap_factors,
                                                                     ahead=ahead, doing=doing)), times)
                                 .astype(np.float32))
            for factor in gap_factors:
                name, tail_name = inbetween_name(frame_key_name(frame), frame_key_name(next_frame), factor)
                names.append(name), tails.append(tail_name)
            timeline.extend(times)
        last = spans[-1][2]
        if ends:
            names.append(frame_key_name(last)), tails.append(""), all_poses.append(read[last])
            timeline.append(last)
        self.summary = self.write_poses(
            context, obj, all_poses, names=names, tails=tails, frames=timeline, keyframe=True,
            label=f"Inbetween step {self.frame_step} x{self.count}")
        if self.output == 'SHAPE_KEYS':
            self.summary += f" (keyframed from frame {frames[0]} to {last})"


class KeySamples:
    """The source samples of a retime as ``core.retime`` indexes them: only those its plan reads
    (``RetimePlan.samples_read``) are there."""

    def __init__(self, n_samples: int, keys: dict):
        self.n_samples, self.keys = n_samples, keys

    def __len__(self):
        return self.n_samples

    def __getitem__(self, index):
        return self.keys[int(index)]


class SHAPE_DIFFERENCES_OT_retime(KeyStep, Speed, AnimationOutput, InbetweenSettingsProperties,
                                  FrameRangeProperties, PoseWriter, GeneratorOperator,
                                  bpy.types.Operator):
    """Retime the evaluated animation: key every n-th frame and play the motion at a new speed
    (0.5 = twice as slow), with in-betweens from shape differences; the kept frames are exactly
    the source's. Writes a point cache on a new object (or keyframed shape keys)"""

    bl_idname = "shape_differences.retime"
    bl_label = "Retime"
    memory_advice = ("raise the speed or retime a shorter range, or on a farm run python -m core retime in parts "
                     "(--chunk I/N)")

    def run(self, context):
        with self.frame_set_back(context):
            yield from self.retime(context)

    def retime(self, context):
        obj = context.active_object
        retime = load_core_retime()
        start, end = self.frame_range(context)
        # Blender keeps the speed in single precision (0.3 arrives as 0.30000001192): its shortest
        # decimal, or 24 frames at 0.3 give 80 samples instead of 81 and the keys land off the frames
        speed = float(str(np.float32(self.speed)))
        if not speed > 0:  # typed past the soft minimum; the core's message is for scripts (its argument)
            raise InputError(f"Speed = {speed:g} must be positive: 0.5 plays the motion twice as slow, 2 twice as fast")
        plan = retime.plan_retime(end - start + 1, self.frame_step, speed)
        last = start + plan.n_out - 1
        if last > retime.MAX_FRAME:  # frames past it play nowhere: the scene's End cannot reach them
            slowest = (end - start) / (retime.MAX_FRAME - start)
            raise InputError(f"At speed {speed:g} the retimed motion runs to frame {last:,}, past Blender's last "
                             f"frame {retime.MAX_FRAME:,}, where nothing plays: use a speed of "
                             f"{math.ceil(slowest * 1e4) / 1e4:g} or more, or retime frames that start earlier")
        if self.output != 'SHAPE_KEYS' and speed * copied_motion.NLA_MAX_SCALE < 1.0 and "keyframed" in object_motion(obj):
            raise InputError(f"At speed {speed:g} the keyframed transform of '{obj.name}' would play "
                             f"{1.0 / speed:g} times slower on the new object, and Blender's NLA slows an action "
                             f"down {copied_motion.NLA_MAX_SCALE:g} times at most: use a speed of {1.0 / copied_motion.NLA_MAX_SCALE:g} "
                             "or more")
        check_memory(plan.n_out, len(obj.data.vertices), f"Retime at speed {format_factor(speed)}",
                     "raise the speed or retime a shorter range", batch=plan.batch(range(plan.n_gaps)))
        key_frames = [start + int(key) for key in plan.keys]
        triangles = surface_triangles(obj, self)
        options = self.core_options(context, len(obj.data.vertices))
        self.check_captured_output(obj, keyframed=True)
        # as for In-between Frames: the second process started before the frames are read
        start_gap_worker(len(obj.data.vertices), plan.n_gaps, options["k_M"])
        # the keys and the other samples the retime reads (core.retime.RetimePlan.samples_read: the shorter
        # last gap's keys, the middles of the first and last gaps); a range starting inside a cloth or soft
        # body simulation, or before it: its first frame too, the rest the warnings measure the edges from
        rest = SimulationRest(context.scene, obj, start, end)
        matrices = {}
        samples_read = [start + sample for sample in plan.samples_read]
        _poses, read = yield from self.read_keys(context, obj, key_frames, 0.1, also=samples_read + rest.frames,
                                                 matrices=matrices, stay=self.output == 'SHAPE_KEYS')
        rest.set_aside(read, matrices, key_frames + samples_read)
        out_frames = [float(start + k) for k in range(plan.n_out)]
        # each pose is shown under the object's matrix of a frame: a new object plays the source's
        # keyframed transform retimed, at the pose's source time; shape keys play under the source's
        # own transform, at the output frame
        shown_at = out_frames if self.output == 'SHAPE_KEYS' else (start + plan.times).tolist()
        # an object scaled differently at different frames: interpolated in the world, where the simulation
        # ran; the matrices of the frames shown read in one pass
        space = world_space.frames_space(context, obj, matrices)
        with closing(space.reading(shown_at)) as reading:
            for _ in reading:
                yield 0.1
        shown = samples_read
        samples = KeySamples(plan.n_source, dict(zip(plan.samples_read, in_world(
            obj, space, [read[frame] for frame in shown], shown, triangles, INBETWEENED_IN_WORLD))))
        check_shown_in_world(obj, space, shown_at, INBETWEENED_IN_WORLD)
        options.update(rest.options(space, matrices, triangles))
        poses_out = retime.iter_retime(samples, triangles, plan, **options,
                                       sample_names=lambda sample: frame_name(start + sample))
        retimed = []
        for index in range(plan.n_out):
            _index, pose = yield from self.compute(0.1 + 0.9 * index / plan.n_out, next, poses_out,
                                                   doing=f"output frame {index + 1}/{plan.n_out}")
            # kept as float32, what shape keys and point caches store
            retimed.append(space.back(pose[None], shown_at[index:index + 1])[0].astype(np.float32))
        shown_speed = format_factor(speed)
        self.summary = self.write_poses(
            context, obj, retimed, names=[f"Retime {shown_speed}x"] * plan.n_out,
            tails=[f" frame {frame:g}" for frame in out_frames], frames=out_frames, keyframe=True,
            label=f"Retime {shown_speed}x step {self.frame_step}", speed=speed)
        if self.frame_step > 1 and speed < 1.0:  # slow motion from every n-th frame only
            self.summary += (f"; frames between every {self.frame_step}th are rebuilt, not read: Step 1 keeps "
                             "every frame of the source")
        shown = playback_range(context.scene)[1]
        if out_frames[-1] > shown:  # the scene's range is the user's to change
            which = "preview range" if context.scene.use_preview_range else "scene"
            report(self, {'WARNING'}, f"The retimed motion runs to frame {out_frames[-1]:g}, past the end of "
                                      f"playback at frame {shown}: set the {which}'s End to {out_frames[-1]:g} "
                                      "to play all of it")


def load_core_retime():
    from ..core import retime
    return retime


def start_gap_worker(vertices: int, gaps: int, k_M: int | None) -> None:
    """Start the in-betweens' second process (:func:`core.gap_processes.start_worker`) where a sequence
    of ``vertices`` vertices, ``gaps`` key gaps and basis size ``k_M`` (None: full) may share its gaps
    with it; nothing elsewhere (small meshes, one core, processes off)."""
    from ..core.gap_processes import start_worker

    start_worker(vertices, gaps, k_M)
