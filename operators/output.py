"""Where an operator's poses go: shape keys on the active object, or a PC2 point cache played by
a Mesh Cache modifier on a new object. Any operator that writes poses uses this mixin:

    class MY_OT_thing(PoseOutput, PoseWriter, GeneratorOperator, bpy.types.Operator):
        def run(self, context):
            source = context.active_object
            self.check_output(source)              # validation step: refuses what would harm
            ...                                    # compute poses, yielding progress
            self.summary = self.write_poses(context, source, poses, names=names,
                                            frames=frames, label="Thing 1.50")

``PoseOutput`` / ``AnimationOutput`` (in :mod:`..properties`) declare the ``output`` and
``filepath`` properties; ``PoseWriter`` writes. Cache output never modifies the source object.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import bpy
import numpy as np

from ..bridge import cache_object, modifier_kinds, naming, scene_timing, shape_keys
from .base import InputError, report
from .handler_guard import skipped_out_of_memory
from .motion_sources import (modifiers_set_aside, modifiers_under_frames, modifiers_under_keys, moves_vertices,
                             object_motion, _plays_nla, refuse_emptying_caches, sharing_mesh, zone_frames_dropped)

CACHE_FOLDER = "caches"


def require_local(obj, data, what: str, advice: str = "Make") -> None:
    """Raise :class:`InputError` if ``data`` (``obj`` itself or its mesh) is linked from a library
    or a library override (its shape keys too, for a mesh): ``what`` (e.g. "shape keys added to it
    are") would not be saved with the file — gone when it is opened again, with no warning."""
    owned = [data] + ([data.shape_keys] if getattr(data, "shape_keys", None) is not None else [])
    linked = next((item for item in owned if item.library is not None or item.override_library is not None), None)
    if linked is None:
        return
    library = linked.library or linked.override_library.reference.library
    origin = f"linked from '{library.filepath}'" if library is not None else "a library override"
    subject = f"'{obj.name}'" if data == obj else f"The mesh of '{obj.name}'"
    raise InputError(
        f"{subject} is {origin}: {what} not saved with this file (gone when it is opened again). "
        f"{advice} it local first (Object › Relations › Make Local › Selected Objects and Data)")


def cache_files_in_use() -> set[str]:
    """The files (real paths) the Mesh Cache modifiers of every object in the file play, linked
    objects' resolved against their library."""
    used = set()
    for obj in bpy.data.objects:
        for modifier in obj.modifiers:
            if modifier.type == 'MESH_CACHE' and modifier.filepath:
                used.add(os.path.realpath(bpy.path.abspath(modifier.filepath, library=obj.library)))
    return used


def numbered_files(path: Path):
    """``path``, then ``name.001.pc2``, ``name.002.pc2``, …, leaving out those a Mesh Cache modifier
    in the file plays (a .blend copied without its caches: the old object's path, empty on disk,
    would otherwise be taken and the old object play the new poses)."""
    used = cache_files_in_use()
    candidate, number = path, 0
    while True:
        if os.path.realpath(candidate) not in used:
            yield candidate
        number += 1
        candidate = path.with_name(f"{path.stem}.{number:03d}{path.suffix}")


def unique_file(path: Path) -> Path:
    """The first of :func:`numbered_files` that no file has."""
    return next(candidate for candidate in numbered_files(path) if not candidate.exists())


def holds_poses(path: Path, poses, start: float, sampling: float) -> bool:
    """Whether the file ``path`` is a PC2 of ``poses`` at ``start`` / ``sampling``: the same run
    made again (a farm task retried, a batch run twice on the saved shot), whose file no object of
    this .blend plays. Coordinates agree to 1e-6 of the poses' size: the same computation on
    another machine may round the last bit of a float32 otherwise (NumPy and OpenBLAS pick their
    kernels by memory alignment)."""
    from ..core.errors import MeshError
    from ..core.point_cache import read_pc2

    try:
        cache = read_pc2(path)
    except (MeshError, OSError):  # not a point cache (or unreadable): another file
        return False
    # compared pose by pose, as float32 (what the file holds), without a copy of them all
    shape = (len(poses), *np.shape(poses[0])) if len(poses) else (0,)
    if cache.positions.shape != shape or cache.start != np.float32(start) or cache.sampling != np.float32(sampling):
        return False
    size = max((float(np.abs(np.asarray(pose, dtype=np.float32)).max()) for pose in poses), default=0.0)
    return all(np.abs(cache.positions[i] - np.asarray(pose, dtype=np.float32)).max() <= 1e-6 * size
               for i, pose in enumerate(poses))


def write_new_cache(path: Path, poses, start: float, sampling: float) -> tuple[Path, bool]:
    """Write the PC2 of ``poses`` to ``path``, or to the first free name of :func:`numbered_files`
    (an existing file is never overwritten), and return the file and whether this call wrote it.
    A file there that holds these poses already (:func:`holds_poses`) is the file, not written
    again: a retried farm task or a batch run again plays the first run's file instead of leaving
    it beside a copy. The name is taken only once the
    file is whole, and only if no file has it then (``exclusive``): two Blender processes writing
    one name at once (two shots in one folder with the same default cache name) keep a file each
    (before, the later replaced the earlier, and one shot played the other's cache)."""
    from ..core.point_cache import write_pc2

    for candidate in numbered_files(path):
        if candidate.exists():
            if holds_poses(candidate, poses, start, sampling):
                return candidate, False
            continue
        try:
            return write_pc2(candidate, poses, start=start, sampling=sampling, exclusive=True), True
        except FileExistsError:  # another process took the name meanwhile
            continue


def in_session_folder(path: str) -> bool:
    """Whether ``path`` lies in Blender's temporary folder of this session, which Blender deletes
    when it quits."""
    folder = bpy.app.tempdir
    return bool(folder) and os.path.realpath(path).startswith(os.path.realpath(folder).rstrip(os.sep) + os.sep)


#: The cache file the last run of each operator (by idname) wrote, None for shape keys: Python
#: state, which undo leaves as it is (:meth:`PoseWriter.drop_undone_cache`).
_LAST_CACHE: dict[str, str | None] = {}

#: Mesh Cache modifiers pointed at copies by :func:`keep_session_caches`: {(object, modifier):
#: their path before}, restored after a save that was a copy (:func:`restore_after_copy`).
_MOVED_FOR_SAVE: dict[tuple[str, str], str] = {}


@skipped_out_of_memory("while copying caches from Blender's temporary folder beside the .blend being saved",
                       "skipped: the saved .blend may play caches from that folder, which Blender deletes when it "
                       "quits; save again once memory is free")
def keep_session_caches(filepath, *_):
    """Before a save to ``filepath``: a cache written while the .blend had never been saved went
    to Blender's temporary folder (:meth:`PoseWriter.cache_path`), which Blender deletes when it
    quits; it is copied into ``caches/`` beside the .blend being saved and its Mesh Cache modifier
    pointed there (relative), so the saved file keeps it."""
    _MOVED_FOR_SAVE.clear()
    if not filepath:
        return
    folder = Path(filepath).parent / CACHE_FOLDER
    for obj in bpy.data.objects:
        if obj.library is not None:
            continue
        for modifier in obj.modifiers:
            source = bpy.path.abspath(modifier.filepath) if modifier.type == 'MESH_CACHE' and modifier.filepath else ""
            if not source or not in_session_folder(source) or not os.path.isfile(source):
                continue
            try:
                folder.mkdir(parents=True, exist_ok=True)
                target = unique_file(folder / Path(source).name)
                shutil.copy2(source, target)
            except OSError as error:
                print(f"Shape Differences: could not copy the cache '{source}' beside '{filepath}': {error}")
                continue
            _MOVED_FOR_SAVE[(obj.name, modifier.name)] = modifier.filepath
            modifier.filepath = f"//{CACHE_FOLDER}/{target.name}"


@skipped_out_of_memory("while pointing the Mesh Cache modifiers back after Save Copy",
                       "skipped: they may still play the copies beside the saved copy (see each Mesh Cache's File Path)")
def restore_after_copy(filepath, *_):
    """After a save: where it was a copy (*Save Copy*: this session's .blend is another or none),
    the session's modifiers point back to the caches they played (the copy keeps its own)."""
    if os.path.realpath(bpy.data.filepath or "") != os.path.realpath(filepath or ""):
        for (name, modifier_name), path in _MOVED_FOR_SAVE.items():
            obj = bpy.data.objects.get(name)
            modifier = obj.modifiers.get(modifier_name) if obj is not None else None
            if modifier is not None:
                modifier.filepath = path
    _MOVED_FOR_SAVE.clear()


def register_handlers():
    for handlers, handler in ((bpy.app.handlers.save_pre, keep_session_caches),
                              (bpy.app.handlers.save_post, restore_after_copy)):
        if handler not in handlers:
            handlers.append(handler)


def unregister_handlers():
    for handlers, handler in ((bpy.app.handlers.save_pre, keep_session_caches),
                              (bpy.app.handlers.save_post, restore_after_copy)):
        if handler in handlers:
            handlers.remove(handler)


class PoseWriter:
    """Writes poses according to the operator's ``output`` and ``filepath`` properties."""

    def check_output(self, source, *, keyframed: bool = False) -> None:
        """Refuse what the writing step would fail on or harm (call it in the validation step,
        before any work): shape keys on a mesh linked from a library (or overridden: they would not
        be saved), or that would empty an unbaked simulation's cache (the object's, another's
        sharing its mesh, or one reacting to it as a collider or force field:
        :func:`~.motion_sources.refuse_emptying_caches`),
        keyframed shape keys on absolute ones (``keyframed``: Blender plays those by their
        Evaluation Time, never by the values keyed) or on keys whose NLA strip is being edited (tweak
        mode), a cache file relative to a .blend that was never saved, a Windows path on Linux or
        macOS, a ``~user`` of no user (``core.point_cache.foreign_path``)."""
        if self.output != 'SHAPE_KEYS':
            if self.filepath.startswith("//") and not bpy.data.filepath:
                raise InputError(f"The Cache File '{self.filepath}' is relative to the .blend, "
                                 "which is not saved yet: save the .blend first, or give an "
                                 "absolute path")
            from ..core.point_cache import foreign_path, unwritable

            foreign = self.filepath and foreign_path(
                self.filepath, "the .blend's folder" if bpy.data.filepath else "the current folder")
            if foreign:
                raise InputError(f"The Cache File {foreign}")
            path, _ = self.cache_path(source.name, warn=False)  # a path the system refuses: before any work
            reason = unwritable(path)
            if reason:
                raise InputError(f"Cannot write the cache file '{path}': {reason}. Pick another Cache File")
            return
        require_local(source, source.data, "shape keys added to it are",
                      "Choose Output › Point Cache (a new object), or make")
        key = source.data.shape_keys
        if keyframed and key is not None and not key.use_relative:
            raise InputError(f"The shape keys of '{source.name}' are absolute (Shape Keys › Relative is "
                             "off): Blender plays them by Evaluation Time and ignores the key values this "
                             "would keyframe, so the new keys would never play. Choose Output › Point "
                             "Cache (a new object), or turn Relative on")
        if keyframed and key is not None and key.animation_data is not None and key.animation_data.use_tweak_mode:
            # Blender files keyframes inserted in tweak mode in the edited strip's action, at its own time
            raise InputError(f"An NLA strip of the shape keys of '{source.name}' is being edited (tweak mode): the "
                             "new keys' keyframes would go into that strip's action and play through its timing, "
                             "scale and repeats rather than at the frames written. Leave tweak mode (Tab in the NLA "
                             "editor) and run again, or choose Output › Point Cache (a new object)")
        refuse_emptying_caches(bpy.context.scene, source, "shape keys added to",
                               "choose Output › Point Cache (a new object; this one stays as it is)", shapes=True)

    def check_captured_output(self, source, *, keyframed: bool = False) -> None:
        """``check_output`` for poses captured from the evaluated mesh: shape keys added to
        ``source`` are deformed again by what moved it, so say so (the work still runs) once they
        are written (:meth:`write_poses`), after any refusal of the run."""
        self.check_output(source, keyframed=keyframed)
        self.deformed_again = None
        if self.output != 'SHAPE_KEYS':
            return
        # generators change no vertex, and what is set aside while the frames are read (a Displace
        # after a Triangulate, :func:`~.motion_sources.modifiers_set_aside`) is not in the poses: it
        # deforms the new keys once, as it deformed the frames
        aside = modifiers_set_aside(bpy.context, source)
        movers = [f"'{m.name}'" for m in source.modifiers if m.show_viewport and moves_vertices(m) and m not in aside]
        key = source.data.shape_keys
        # relative keys add to the new ones; absolute keys show one key (or two blended) at a time
        if key is not None and key.use_relative:
            animation = key.animation_data
            # an action, NLA strips (an action pushed down: no active one left) or drivers play the values
            if animation is not None and (animation.action is not None or _plays_nla(animation)
                                          or len(animation.drivers)):
                movers.append("its animated shape keys")
            else:  # a key left at a value is in every captured pose, and adds its change once more
                held = [f"'{kb.name}' at {kb.value:g}" for kb in key.key_blocks[1:] if kb.value and not kb.mute]
                if held:
                    movers.append(f"its shape key{'s' if len(held) > 1 else ''} {', '.join(held)}")
        if movers:
            self.deformed_again = (f"The new shape keys are deformed again by {', '.join(movers)} "
                                   f"of '{source.name}': disable those to play them as captured, "
                                   "or use Output › Point Cache (a new object)")

    def given_path(self) -> str:
        """The Cache File as given, a plain relative path (``caches/x.pc2``) taken relative to the
        saved .blend (``//caches/x.pc2``) rather than to the folder Blender was started from, which
        differs from run to run, and a leading ``~`` (``~/caches/x.pc2`` in a script) the home
        folder, as in a shell and in ``python -m core``, rather than a folder named ``~``."""
        given = os.path.expanduser(self.filepath) if self.filepath.startswith("~") else self.filepath
        if given and not given.startswith("//") and not os.path.isabs(given) and bpy.data.filepath:
            return "//" + given
        return given

    def cache_path(self, object_name: str, warn: bool = True, check_free: bool = True) -> tuple[Path, str]:
        """The PC2 file to write (never an existing one, nor one a Mesh Cache in the file plays;
        ``check_free=False``: the name asked for, before that check) and the path to store in the
        modifier (:meth:`stored_path`). Raises :class:`InputError` for a path the system cannot use
        (a name too long, a folder that cannot be read) and for a device or special file
        (``/dev/null``, a named pipe: neither a cache to write nor a name to add ``.pc2`` to)."""
        base_name = bpy.path.clean_name(object_name) + ".pc2"
        given = self.given_path()
        try:
            if given:
                path = Path(os.path.abspath(bpy.path.abspath(given)))
                if given.endswith(("/", "\\")) or path.is_dir():
                    path = path / base_name
                elif path.exists() and not path.is_file():  # a device (/dev/null), a named pipe, a socket
                    raise InputError(f"The Cache File '{self.filepath}' is a device or special file, not a "
                                     "file or folder: pick a .pc2 file or a folder to write the cache in")
                elif path.suffix.lower() != ".pc2":
                    path = path.with_name(path.name + ".pc2")
            elif bpy.data.filepath:
                path = Path(bpy.path.abspath(f"//{CACHE_FOLDER}")) / base_name
            else:
                path = Path(bpy.app.tempdir or os.path.realpath(".")) / base_name
                if warn:
                    report(self, {'WARNING'}, "The .blend is not saved, so the cache went to Blender's temporary "
                                              f"folder ({path.parent}), deleted when Blender quits: saving the .blend "
                                              f"copies it into {CACHE_FOLDER}/ beside it")
            if check_free:
                path = unique_file(path)
        except OSError as error:
            raise InputError(f"Cannot use the Cache File '{self.filepath or path}': {error.strerror or error}. "
                             "Pick another Cache File") from None
        return path, self.stored_path(path)

    def stored_path(self, path: Path) -> str:
        """The path of the cache file ``path`` for the Mesh Cache modifier: relative to the .blend
        when the user gave a relative Cache File or none."""
        given = self.given_path()
        relative = bpy.data.filepath and (not given or given.startswith("//"))
        return bpy.path.relpath(str(path)) if relative else str(path)

    def write_poses(self, context, source, poses, *, names: list[str], frames: list[float],
                    label: str, tails: list[str] | None = None, keyframe: bool = False,
                    speed: float = 1.0, keyed: bool = False) -> str:
        """Write ``poses`` (float ``(n, 3)`` each) and return the summary for the report.

        Shape keys: one key per pose named ``names[i] + tails[i]`` (the tail, e.g. a factor, is
        never cut), keyframed at ``frames`` if ``keyframe``. Point cache: a PC2 of the poses at
        ``frames`` (evenly spaced) on a new object called "<source> <label>", which moves as
        ``source`` does as a whole; ``speed``: the poses play ``source``'s time
        ``frames[0] + (frame − frames[0]) · speed`` (a retime), its keyframed transform too.
        ``keyed``: the poses are of ``source``'s shape keys (before its modifiers), and the new
        object is deformed by copies of ``source``'s modifiers as the keys are
        (:func:`~.motion_sources.modifiers_under_keys`); else they are what its modifiers made, and only the
        generators after its motion are copied (:func:`~.motion_sources.trailing_generators`).
        """
        if self.output == 'SHAPE_KEYS':
            tails = tails or [""] * len(names)
            new_keys = [shape_keys.NewShapeKey(name, pose, tail)
                        for name, pose, tail in zip(names, poses, tails)]
            times = [scene_timing.scene_time(context.scene, frame) for frame in frames]
            had_basis = source.data.shape_keys is not None
            had_action = bool(had_basis and source.data.shape_keys.animation_data
                              and source.data.shape_keys.animation_data.action)
            # named so that no F-curve there animates another key (bridge.shape_keys.unique_key_name): their
            # keyframes go into new F-curves of their own, or those of keys removed since, emptied (kept to be
            # given back on failure)
            dead = shape_keys.dead_key_curves(source.data.shape_keys) if keyframe and had_action else {}
            added = shape_keys.add_shape_keys(source, new_keys, keyframes=times if keyframe else None)
            undo = getattr(self, "undo_on_failure", None)  # a failure after this (GeneratorOperator) takes them back
            if undo is not None:
                undo(lambda: remove_added_keys(source, added, had_basis, had_action, dead))
            if getattr(self, "deformed_again", None):  # captured poses (check_captured_output)
                report(self, {'WARNING'}, self.deformed_again)
            dropped = zone_frames_dropped(context.scene, source, "shape keys added to",
                                          "use Output › Point Cache (a new object; this one stays as it is)")
            if dropped:
                report(self, {'WARNING'}, dropped)
            # the keyed values are the mesh's: its other objects play the new keys as well, unless
            # their own simulation or cache replaces what the keys show
            others = [other for other in (sharing_mesh(source) if keyframe else [])
                      if not any(modifier.show_viewport and modifier.type in modifier_kinds.POSE_REPLACING_MODIFIERS
                                 for modifier in other.modifiers)]
            if others:
                named = ", ".join(f"'{other.name}'" for other in others)
                report(self, {'WARNING'}, f"{named} {'shares' if len(others) == 1 else 'share'} the mesh of "
                                          f"'{source.name}' and now {'plays' if len(others) == 1 else 'play'} the "
                                          "new keyframed shape keys too: give "
                                          f"'{source.name}' its own mesh first (Object › Relations › Make Single "
                                          "User › Object & Data), or use Output › Point Cache (a new object)")
            motion = object_motion(source) if speed != 1.0 else {}
            if motion:
                # a new object retimes a keyframed transform, not a simulation's
                advice = (f"bake it to keyframes ({BAKE_RIGID_BODY}) and " if "rigid_body" in motion else "")
                report(self, {'WARNING'}, f"'{source.name}' is moved as a whole by "
                                          f"{', '.join(motion.values())}, at its own speed while the new "
                                          f"shape keys play at {speed:g}x: {advice}use Output › Point Cache "
                                          "(a new object) to retime its keyframed transform too")
            self.drop_undone_cache(None)
            return added_summary(added)
        return self.write_cache_object(context, source, poses, frames, label, speed, keyed)

    def drop_undone_cache(self, played: Path | None, written: bool = False) -> None:
        """Remember the cache file this run plays (``played``; None: shape keys) where it is the
        operator's own — ``written`` by this run, or by the run it repeats — and, where the run
        repeats the last one from the Redo panel (Adjust Last Operation), delete the file that one
        wrote: Blender undid it first, so nothing plays the file any more, and each change of a
        setting there would leave one more on disk. Called once the new poses are written, since a
        repeat that fails brings the undone run back; a file a Mesh Cache in the file plays stays
        (Repeat Last runs again without undoing), and so does an earlier run's file a run played
        again without writing it (:func:`write_new_cache`: another .blend in the folder, a version
        saved before, may play it)."""
        previous = _LAST_CACHE.get(self.bl_idname) if self.is_repeat() else None
        own = played is not None and (written or previous == str(played))
        _LAST_CACHE[self.bl_idname] = str(played) if own else None
        if (previous and previous != str(played) and os.path.isfile(previous)
                and os.path.realpath(previous) not in cache_files_in_use()):
            try:
                os.remove(previous)
            except OSError as error:  # left on disk: the new poses are written all the same
                print(f"Shape Differences: could not delete the undone cache '{previous}': {error}")

    def write_cache_object(self, context, source, poses, frames: list[float], label: str,
                           speed: float = 1.0, keyed: bool = False) -> str:
        sampling = float(frames[1] - frames[0]) if len(frames) > 1 else 1.0
        if len(frames) > 1 and not np.allclose(np.diff(frames), sampling, rtol=1e-6):
            raise ValueError("A point cache needs evenly spaced frames")  # a bug, not user input
        # the Mesh Cache and the object's animation play the scene's time, not its frame number
        start = scene_timing.scene_time(context.scene, frames[0])
        sampling = scene_timing.scene_time(context.scene, sampling)
        name = naming.unique_name(source.name, f" {label}", bpy.data.objects.keys())
        path, _ = self.cache_path(name, check_free=False)
        try:
            path, written = write_new_cache(path, poses, start, sampling)
        except OSError as error:
            from ..core.point_cache import unwritable

            reason = unwritable(path) or error.strerror or str(error)
            raise InputError(f"Cannot write the cache file '{path}': {reason}. Pick another Cache File") from None
        stored_path = self.stored_path(path)
        modifiers, left_out = modifiers_under_keys(source) if keyed else modifiers_under_frames(source)
        try:
            obj = cache_object.add_cache_object(context, source, name, stored_path, start, sampling,
                                                modifiers=modifiers, speed=speed,
                                                source_end=start + sampling * (len(frames) - 1) * speed,
                                                deformed_by_parent=keyed)
        except BaseException:
            if written:
                path.unlink(missing_ok=True)
            raise
        undo = getattr(self, "undo_on_failure", None)  # a failure after this (GeneratorOperator) takes it back
        if undo is not None:
            undo(lambda: remove_cache_object(obj, path if written else None))
        if left_out:
            advice = ("use Output › Shape Keys to see them under it" if keyed else "copy them to it by hand if it "
                      "should render them (Particle Properties › Copy Active to Selected Objects)")
            report(self, {'WARNING'},
                   f"'{obj.name}' plays the poses without {', '.join(repr(m.name) for m in left_out)} "
                   f"of '{source.name}' (a simulation, a cache or a particle system is not copied): {advice}")
        # taken over (bridge.copied_motion.copy_object_motion): the keyframed transform at any speed, the
        # parent and constraints at the scene's own
        motion = object_motion(source)
        if "rigid_body" in motion:  # the simulation moves the source alone: the new object stays put
            report(self, {'WARNING'}, f"'{obj.name}' stands still where '{source.name}' is moved as a whole by its "
                                      f"rigid body simulation (the poses are in its own coordinates): bake that "
                                      f"motion to keyframes ({BAKE_RIGID_BODY}) and run again, so that the new "
                                      "object takes it over")
        missing = [words for kind, words in motion.items() if kind in ("nla", "drivers")]
        if missing:
            report(self, {'WARNING'}, f"'{obj.name}' is not moved by {' and '.join(missing)} of '{source.name}': "
                                      "add those to it by hand if it should follow them")
        own_speed = [words for kind, words in motion.items() if kind in ("constraints", "parent")]
        if speed != 1.0 and own_speed:
            verb = "moves" if own_speed == [motion.get("parent")] else "move"  # "its constraints" is plural
            report(self, {'WARNING'}, f"'{obj.name}' plays the motion at {speed:g}x, but "
                                      f"{' and '.join(own_speed)} {verb} it at the scene's own speed")
        self.drop_undone_cache(path, written)
        span = (f"frame {frames[0]:g}" if len(frames) == 1
                else f"frames {frames[0]:g}-{frames[-1]:g}")
        return (f"Added '{obj.name}' playing {len(frames)} pose{'s' if len(frames) != 1 else ''} "
                f"({span}) from {path}" + ("" if written else " (an earlier run's file, which holds these poses)"))


def remove_added_keys(obj, names: list[str], had_basis: bool, had_action: bool,
                      dead: dict[str, list[dict]] | None = None) -> None:
    """Take back the shape keys ``names`` added to ``obj`` (:meth:`PoseWriter.write_poses`), the
    Basis made for them (not ``had_basis``) and their keyframes: the action made for them (not
    ``had_action``), else their F-curves in the keys' own action, which are new, or were those of keys
    removed before the run (``dead``: :func:`bridge.shape_keys.dead_key_curves`, taken before the keys
    were added), which get their keyframes back."""
    dead = dead or {}
    key = obj.data.shape_keys
    animation = key.animation_data if key is not None else None
    if animation is not None and animation.action is not None:
        if had_action:
            for name in names:
                fcurve = shape_keys.shape_key_value_fcurve(key, name)
                if fcurve is not None and fcurve.data_path in dead:
                    shape_keys.set_keyframes(fcurve, dead[fcurve.data_path])
                elif fcurve is not None:
                    _remove_fcurve(animation, fcurve)
        else:  # the action alone: drivers of the keys stay
            action = animation.action
            animation.action = None
            if action.users == 0:
                bpy.data.actions.remove(action)
    shape_keys.remove_shape_keys(obj, names, remove_basis=not had_basis)


def _remove_fcurve(animation, fcurve) -> None:
    """Remove ``fcurve`` from ``animation``'s action (legacy and slotted actions, as
    :func:`bridge.shape_keys.key_fcurves` finds it)."""
    if hasattr(animation, "action_slot"):  # Blender 4.4+: the slot's channel bag holds it
        from bpy_extras import anim_utils

        anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot).fcurves.remove(fcurve)
    else:
        animation.action.fcurves.remove(fcurve)


def remove_cache_object(obj, path: Path | None) -> None:
    """Take back a new object playing a point cache (:meth:`PoseWriter.write_cache_object`), its
    mesh, and ``path``, the file this run wrote for it (None: an earlier run's, which stays)."""
    mesh = obj.data
    bpy.data.objects.remove(obj)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)
    if path is not None:
        path.unlink(missing_ok=True)


#: Where a user turns a rigid body's motion into keyframes, which a new object takes over.
BAKE_RIGID_BODY = "Object › Rigid Body › Bake To Keyframes"


def added_summary(names: list[str]) -> str:
    shown = names if len(names) <= 4 else [names[0], "...", names[-1]]
    return f"Added {len(names)} shape key{'s' if len(names) != 1 else ''}: " + ", ".join(shown)
