"""What every Shape Differences operator shares: running its work as a generator (synchronously
in ``execute``, from a modal timer with a progress bar and Esc to cancel in ``invoke``), turning
bad input into reports, and resolving the core settings from the scene or the operator.

An operator's work is a generator that validates first, computes while yielding its progress
(0..1) and writes to the object only in its last step, so cancelling or failing changes nothing.
"""

import re
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import wait as wait_for

import bpy
import numpy as np

from ..bridge import frame_reading, mesh_data, triangulation, world_space
from ..properties import BasisSettings, BasisSizes, CoreSettings


def load_core():
    """The core package, imported on first use so enabling the extension stays fast."""
    from .. import core
    return core


class InputError(Exception):
    """Bad selection or settings: the message says what is wrong and how to fix it."""


# The core numbers the mesh's triangles in the order it was given them, Blender's loop triangles
# (those of its offset surface too, "triangle 57 of the offset surface": not the mesh's).
TRIANGLE_REFERENCE = re.compile(r"\b([Tt]riangles?) (\d+)(?: and (\d+))?\b(?! of the offset surface)(?: \(([^()]*)\))?")


def name_faces(message: str, triangle_faces) -> str:
    """``message`` with each of the core's "triangle i" (or "triangles i and j") of the mesh followed
    by the face it is part of (``triangle_faces``: the face of every loop triangle, or None where every
    face is a triangle and the numbers are the faces'), which Blender shows (Indices overlay)."""
    if triangle_faces is None:
        return message

    def face(index: str) -> str:
        return str(triangle_faces[int(index)])

    def named(match):
        if any(index is not None and int(index) >= len(triangle_faces) for index in match.group(2, 3)):
            return match.group(0)  # not one of the mesh's
        word, first, second, aside = match.groups()
        text = f"{word} {first}" + (f" and {second}" if second else "")
        faces = f"of face {face(first)}" if second is None else f"of faces {face(first)} and {face(second)}"
        return f"{text} ({faces}" + (f"; {aside})" if aside else ")")

    return TRIANGLE_REFERENCE.sub(named, message)


# The core's remedy for a pose with a NaN or infinite coordinate (core.validation.check_vertices) is to
# remove that frame; a shape key named so is removed (by its name), and a mesh has no frame to remove.
NON_FINITE_KEY = re.compile(r"(shape key '(.*?)'(?: of '.*?')?: vertex \d+ has a non-finite coordinate .*?) "
                            r"or remove that frame\.")
NON_FINITE_MESH = re.compile(r"(the mesh of '.*?': vertex \d+ has a non-finite coordinate .*?) or remove that frame\.")


def name_remedies(message: str) -> str:
    """``message`` with the core's "remove that frame" said of a shape key as "remove shape key 'X'",
    and left out for a mesh (fixing it is the remedy)."""
    return NON_FINITE_MESH.sub(r"\1.", NON_FINITE_KEY.sub(r"\1 or remove shape key '\2'.", message))


def offset_option(offset: float, where: str = "") -> float | None:
    """The core's ``offset`` for an Offset t setting (``where`` says which one, if not the
    operator's): None (automatic) for 0, else the distance. A negative one (typed past the soft
    minimum) is refused in the setting's terms; the core's message is for scripts (its ``offset``
    argument, None for automatic)."""
    if not offset >= 0:
        raise InputError(f"Offset t{where} = {offset:g} must be positive, or 0 for the automatic distance (half "
                         "the mean edge length)")
    return offset or None


#: What the world's proportions are to the operators that work in them (:func:`check_world_scale`).
REBUILT_IN_WORLD = "the poses are rebuilt in the world"
INBETWEENED_IN_WORLD = "the poses are in-betweened as the world shows them"
MEASURED_IN_WORLD = "the poses are measured as the world shows them"


def check_world_scale(obj, where: str, matrix=None, poses=(), triangles=None, *, invertible: bool = True,
                      frame: float | None = None, read: bool = False) -> None:
    """Refuse ``obj`` where its world matrix flattens it, naming its scale there (the object's own
    or a parent's) as the cause rather than its mesh. ``matrix``: that world matrix (4, 4) or its
    linear part (3, 3), ``obj``'s at the current frame by default; ``where``: what the operator does
    in the world (:data:`REBUILT_IN_WORLD`, …); ``frame``: the (sub-)frame that matrix is shown at,
    named where given: an in-between's (a scale keyframed through 0), or, ``read``, a frame whose
    pose was read (a scale keyframed to 0 there). Refused where the matrix cannot be inverted to
    working precision (its smallest singular value at most machine epsilon × its largest: a scale of
    0 along an axis, or next to it), when ``invertible`` (the operator takes its results back into
    the mesh); and where the matrix's smallest singular value is below 1e-5 × its largest (√ of
    the core's degenerate ratio) and, in one of ``poses`` (pairs of positions (n, 3): in the mesh's
    coordinates and as the world shows them), a triangle of ``triangles`` (int (m, 3)) the mesh
    has with an area has none in the world (:func:`core.mesh_topology.zero_area_triangles`): the
    core would refuse it as a degenerate face and advise dissolving faces the mesh does not have."""
    linear = np.array(obj.matrix_world if matrix is None else matrix, dtype=np.float64)[:3, :3]
    sigma = np.linalg.svd(linear, compute_uv=False)
    scale = ", ".join(f"{value:.3g}" for value in np.linalg.norm(linear, axis=0))
    at = "" if frame is None else f" at frame {frame:g}"
    flattened = f"'{obj.name}' is flattened in the world{at} (its scale there is ({scale}))"
    like = "scales of a like size along every axis"
    if invertible and not sigma[-1] > np.finfo(np.float64).eps * sigma[0]:
        keyed = ("" if frame is None else " there, or a frame range and Step that leave that frame out" if read else
                 " there (a scale keyframed from one side of 0 to the other passes 0 between its keys), or "
                 "in-betweens that miss that frame (another Step, Count or Speed)")
        raise InputError(f"{flattened}: {where} and cannot be taken back into its mesh. Give it (and its parents) "
                         + ("a scale other than 0 along every axis" if sigma[-1] == 0 else like) + keyed)
    from ..core.mesh_topology import DEGENERATE_TRIANGLE_RATIO, zero_area_triangles

    # A linear map multiplies a triangle's area / longest edge² by at least its singular values'
    # spread: where that is above √ of the ratio the core calls degenerate, a triangle the world
    # flattens is a sliver of the mesh itself (area / edge² under 1e-5), whose own refusal ("… has
    # zero area … Degenerate Dissolve") is the one to give; nor is any pass over the mesh made then.
    if not sigma[-1] < np.sqrt(DEGENERATE_TRIANGLE_RATIO) * sigma[0]:
        return
    for mesh_positions, world_positions in poses:
        flat = zero_area_triangles(world_positions, triangles)  # the one pass where nothing is flat
        if flat.size:
            flat = np.setdiff1d(flat, flat[zero_area_triangles(mesh_positions, triangles[flat])])
        if flat.size:
            raise InputError(f"{flattened}: {where}, and there {flat.size} of its triangles have no area, which "
                             f"they have in its mesh. Give it (and its parents) {like}: the mesh itself is fine")


def in_world(obj, space, poses, times, triangles, where: str, *, invertible: bool = True) -> list:
    """``poses`` ((n, 3) each, in ``obj``'s mesh coordinates, shown at ``times``) as ``space``
    (:class:`bridge.world_space.WorldProportions`, :class:`bridge.world_space.WorldFrames`) takes them into the world,
    :func:`check_world_scale` refusing a world matrix there that flattens ``obj``, naming the frame
    where each pose has its own (:class:`bridge.world_space.WorldFrames`: a scale keyframed to 0 at a key)."""
    per_frame = isinstance(space, world_space.WorldFrames)
    world = []
    for pose, at in zip(poses, times):
        moved = space.to(pose, at)
        linear = space.linear(at)
        if linear is not None:
            check_world_scale(obj, where, linear, [(pose, moved)], triangles, invertible=invertible,
                              frame=at if per_frame else None, read=True)
        world.append(moved)
    return world


def check_shown_in_world(obj, space, times, where: str) -> None:
    """Refuse ``obj`` where ``space`` (:class:`bridge.world_space.WorldFrames`, its matrices at ``times`` read)
    would take poses back into its mesh at one of ``times`` (frames; a fraction is a sub-frame)
    through a world matrix that cannot be inverted (:func:`check_world_scale`, naming that frame):
    a scale keyframed from one side of 0 to the other passes 0 between two keys, where an
    in-between may fall. ``where``: what the operator does in the world. Nothing to check in the
    world's proportions (:class:`bridge.world_space.WorldProportions`), the same at every time and checked with
    the keys (:func:`in_world`)."""
    if isinstance(space, world_space.WorldFrames):
        for time in times:
            check_world_scale(obj, where, space.linear(time), frame=time)


#: Where the scene's settings are, for a setting taken from there (:func:`offset_option`,
#: :func:`check_basis_size`).
SCENE_SETTING = " (the scene's, in the sidebar's Shape Diff tab)"

#: What 0 means for each basis size, where it may be 0 (:func:`check_basis_size`).
BASIS_ZERO = {"k_M": "0 for the full basis", "k_N": "0 for the target not truncated"}


def check_basis_size(label: str, k: int, where: str = "", zero: str | None = None) -> None:
    """Refuse a negative basis size ``k`` (typed past the soft minimum) in the setting's terms:
    its ``label``, ``where`` it is set if not on the operator, and what it may be — a positive
    number of eigenfunctions, or ``zero`` (what 0 means there; None where a size is needed). The
    core's message is for scripts (its arguments, None for the full basis)."""
    if k < 0:
        allowed = f"{zero}, or a positive number of eigenfunctions" if zero else "a positive number of eigenfunctions"
        raise InputError(f"{label}{where} = {k} must be {allowed} (typically 50–300)")


#: What a run that ran out of memory says to make smaller, where its operator names nothing of its
#: own (:attr:`GeneratorOperator.memory_advice`).
MEMORY_ADVICE = "decimate the mesh or split it into parts"


def ran_out_of_memory(error: MemoryError, advice: str = MEMORY_ADVICE) -> str:
    """The report of a run that ran out of memory past the checks made before any work
    (:func:`check_memory`: another program took it meanwhile, or the system does not say how much
    there is): what ran out (the core's or NumPy's words, "CHOLMOD could not hold the factor of a
    matrix of … unknowns", "Unable to allocate 1.2 GiB for an array …") and what to do: ``advice``
    (the operator's own, what makes its job smaller), close other programs, or run it where there
    is more memory."""
    said = " ".join(str(error).split())
    return (f"Ran out of memory{f' ({said})' if said else ''}: nothing was changed. To run it, {advice}; "
            "close other programs to free memory; or run it on a machine with more memory")


def reported_error(error: BaseException, triangle_faces=None, memory_advice: str = MEMORY_ADVICE) -> str | None:
    """The message to show for an expected failure, or None for a bug that should propagate.
    ``memory_advice``: what makes the job smaller, for a :class:`MemoryError` (:func:`ran_out_of_memory`)."""
    if isinstance(error, (InputError, frame_reading.FrameReadError)):
        return str(error)
    if isinstance(error, MemoryError):
        return ran_out_of_memory(error, memory_advice)
    if isinstance(error, ImportError) and error.name and error.name.split(".")[0] in (
            "scipy", "threadpoolctl"):
        return (f"The Python package '{error.name}' is missing. Install the Shape Differences "
                "zip built for your platform (it bundles SciPy and threadpoolctl), then restart Blender.")
    core = load_core()
    if isinstance(error, core.ShapeDifferenceError):
        return name_faces(name_remedies(str(error)), triangle_faces)
    return None


# Seconds between progress lines printed on the console in background mode.
CONSOLE_PROGRESS_INTERVAL = 1.0
# Longest a timer tick waits for a core computation running in the worker thread: Esc and the
# rest of Blender's UI stay responsive while one core call takes seconds.
WORKER_POLL_SECONDS = 0.05
_worker = None


def shutdown_worker():
    """Let the worker thread end (after a call still running) when the extension is disabled."""
    global _worker
    if _worker is not None:
        _worker.shutdown(wait=False, cancel_futures=True)
        _worker = None


def worker():
    """The one thread that runs core computations of modal operators (never bpy calls)."""
    global _worker
    if _worker is None:
        _worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="shape_differences")
    return _worker


def edit_mode_problem(obj) -> str | None:
    """Why the mesh of ``obj`` cannot be read or written now, or None: in Edit Mode, its own or
    that of another object sharing the mesh (a linked duplicate), Blender holds the mesh's
    vertices in its edit mesh and the mesh itself has none until Edit Mode is left."""
    if obj.mode != 'OBJECT':
        return f"'{obj.name}' is in {obj.mode.replace('_', ' ').title()} Mode: switch to Object Mode first"
    if obj.type == 'MESH' and obj.data.is_editmode:
        editors = [other.name for other in bpy.data.objects if other.data == obj.data and other.mode == 'EDIT']
        by = f" through '{editors[0]}', which shares it" if editors else ""
        return f"The mesh of '{obj.name}' is in Edit Mode{by}: switch to Object Mode first"
    return None


def instance_hint(obj) -> str:
    """How to reach the meshes ``obj`` shows as a collection instance (an Empty drawing a collection,
    as linking or appending one makes: its meshes are not objects of the scene to select), else ""."""
    if obj is None or obj.instance_type != 'COLLECTION' or obj.instance_collection is None:
        return ""
    return (f" ('{obj.name}' is an instance of the collection '{obj.instance_collection.name}': make its "
            "objects real with Object › Apply › Make Instances Real, then select one of its meshes)")


def report(operator, kind: set[str], message: str) -> None:
    """``operator.report(kind, message)`` with what UTF-8 cannot hold escaped as Python prints it
    (``caf\\udce9``): a file name whose bytes are no text (a Latin-1 folder on a UTF-8 system)
    comes to Python with such characters, and Blender cannot take them into a report: it drops
    the message ("Python: (null)") and fails the operator, also after its work is written.
    A warning is also kept in the operator's ``_warned`` (where it has one: :class:`GeneratorOperator`),
    for the line that ends its run (:func:`look_first`)."""
    if 'WARNING' in kind and isinstance(getattr(operator, "_warned", None), list):
        operator._warned.append(message)
    operator.report(kind, message.encode("utf-8", "backslashreplace").decode("utf-8"))


# How many of the other gaps a summary names.
SUMMARY_PLACES = 3


def shown(window: str, headless: str) -> str:
    """Where a run's reports are, said for where it runs: ``window`` in Blender with its UI (the Info
    editor, the system console), ``headless`` under ``blender -b``, which has neither: its reports
    and the console's lines go to the same log (reports on stdout, the console's lines on stderr)."""
    return headless if bpy.app.background else window


def summarized(messages: list[str], label: str, about: dict | None = None) -> list[str]:
    """The warning reports of the ``messages`` an operator (``label``) collected: messages that say
    the same problem for other gaps or in-betweens, differing only in their numbers (frames,
    factors, counts) and in how many in-betweens of a gap have it
    (``core.sequence_warnings.message_shape``), are reported once, by the one whose in-between
    keeps the most flipped or collapsed triangles, else the one farthest past what it allows (its
    ``excess``; the first of them on a tie), with how many more
    there are and the gaps of the first few others, and those others are printed on the system
    console in full (a retime of 40 gaps, each with flipped triangles, reports one warning, not 40:
    the gap to look at). ``about``: per message, the core's warning it came from, whose ``defects``,
    ``excess``, ``gap`` (its keys' names) and ``factors`` are used; a message without one counts as
    keeping none, past nothing, and names no place."""
    from ..core.sequence_warnings import factor_list, message_shape

    about = about or {}
    groups: dict[str, list[str]] = {}
    for message in messages:
        groups.setdefault(message_shape(message), []).append(message)
    out = []
    for alike in groups.values():
        if len(alike) == 1:
            out.append(alike[0])
            continue
        worst = max(range(len(alike)), key=lambda i: (*severity(about.get(alike[i])), -i))
        others = alike[:worst] + alike[worst + 1:]
        first, stop = (alike[worst][:-1], ".") if alike[worst].endswith(".") else (alike[worst], "")
        places: dict[tuple[str, str], list[float]] = {}  # each gap of the others, with their lone in-betweens' factors
        for message in others:
            warning = about.get(message)
            gap, factors = getattr(warning, "gap", None), getattr(warning, "factors", ())
            if gap is not None:  # a warning about several in-betweens lists their factors itself
                places.setdefault(gap, []).extend(factors if len(factors) == 1 else ())
        where = [f"between {gap[0]} and {gap[1]}" + (f" (factor{'s' if len(factors) > 1 else ''} "
                                                      f"{factor_list(factors)})" if factors else "")
                 for gap, factors in places.items()]
        where = "".join(f"; {place}" for place in where[:SUMMARY_PLACES]) + \
            ("; …" if len(where) > SUMMARY_PLACES else "")
        out.append(f"{first} (and {len(others)} more like it{where}; each in full "
                   f"{shown('in the system console', 'on stderr')}){stop}")
        for message in others:
            print(f"{label}: warning: {message}", file=sys.stderr, flush=True)
    return out


def severity(warning) -> tuple[int, float]:
    """How much a core warning (None or another object: nothing) asks to be looked at, as
    :func:`summarized` and :func:`look_first` rank it: the flipped or collapsed triangles it keeps,
    then how far past its allowance it is (its ``excess``)."""
    return getattr(warning, "defects", 0), getattr(warning, "excess", 0.0)


# How much of a warning's opening a run's last line quotes, where the warning names no gap.
LOOK_FIRST_CHARACTERS = 90


def look_first(warned: list[str], about: dict | None = None, headless: bool | None = None) -> str:
    """The last report of a run that gave the warning reports ``warned`` (in order), at level
    WARNING: Blender's status bar shows only an operator's last report, so it says how many there
    are, where they all are (:func:`shown`), and the one to look at first: the core's warning whose in-between keeps
    the most flipped or collapsed triangles (``about``: per message, the core's warning it came
    from; on a tie the one farthest past its allowance, then the first, as :func:`summarized`), said by its gap and kind, else the first warning's opening words. Where they are: the
    Info editor, or, ``headless`` (``blender -b``; by default ``bpy.app.background``), the console,
    where Blender prints a script's operator reports in order, this one last. Where no warning keeps
    flipped or collapsed triangles, the one to look at first is the core's warning farthest past what
    it allows (its ``excess``: a gap's fit 6.7 % off the interpolated metric where 2.1 % is allowed,
    3.2, before one 0.8 % off where 0.7 % is, 1.1), else the first."""
    about = about or {}
    core = [warning for warning in about.values() if getattr(warning, "gap", None) is not None]
    # of warnings alike in triangles kept, the one farthest past its allowance, then the first: the
    # one summarized reports in full
    worst = max(core, key=severity, default=None)
    if worst is not None and worst.defects > 0:
        first = (f"between {worst.gap[0]} and {worst.gap[1]}, {worst.defects} flipped or collapsed "
                 f"triangle(s) kept [{worst.kind}]")
    else:
        # the message of the warning farthest past its allowance, where one measures against one
        farthest = max(about, key=lambda message: severity(about[message])[1], default=None)
        text = farthest if farthest is not None and severity(about[farthest])[1] > 0.0 else warned[0]
        text = text.removeprefix("Shape-difference interpolation: ")
        cut = min((i for i in (text.find(": "), text.find("; ")) if i > 0), default=len(text))
        first = text[:cut] if cut <= LOOK_FIRST_CHARACTERS else text[:LOOK_FIRST_CHARACTERS].rsplit(" ", 1)[0] + " …"
    count = len(warned)
    where = "printed above" if (bpy.app.background if headless is None else headless) else "in the Info editor"
    return f"{count} warning{'s' if count > 1 else ''}, each {where}; look first at: {first}"


def refused_in_poll(operator_class, message: str) -> bool:
    """Say ``message``, why ``operator_class`` cannot run now, as its poll message (Blender shows it
    on the greyed-out button and puts it in the ``RuntimeError`` a script's call raises), and return
    False for its ``poll``. Headless (``blender -b``) it is printed too, as one line
    ``<label>: refused: <message>``: Blender prints no report for a failed poll, so a batch's log would
    name the cause only on the last line of the traceback."""
    operator_class.poll_message_set(message)
    if bpy.app.background:
        print(f"{getattr(operator_class, 'bl_label', operator_class.__name__)}: refused: {message}",
              file=sys.stderr, flush=True)
    return False


class GeneratorOperator:
    """Mixin for operators whose work is the generator ``run(context)``; the core calls it makes
    name the poses they hand over (``key_names``: shape keys, frames) for the core's messages."""

    bl_options = {'REGISTER', 'UNDO'}
    #: What makes the job smaller where it runs out of memory (:func:`ran_out_of_memory`).
    memory_advice = MEMORY_ADVICE

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None or obj.type != 'MESH':
            return refused_in_poll(cls, "Select a mesh object: the active object must be a mesh" + instance_hint(obj))
        editing = edit_mode_problem(obj)
        if editing:
            return refused_in_poll(cls, editing)
        return True

    def run(self, context):
        """Validate, compute (yielding progress in 0..1), then write. Set ``self.summary``."""
        raise NotImplementedError

    def compute(self, progress: float, function, *args, doing: str = "", **kwargs):
        """``yield from`` this to run one core call ``function(*args, **kwargs)`` (pure NumPy, no
        bpy) and get its result. From the UI it runs in a worker thread while this yields
        ``progress`` every few hundredths of a second, so Esc cancels at once however long the
        call takes (a cancelled call finishes in the background and its result is dropped);
        in ``execute`` it simply runs, headless (``blender -b``) with a heartbeat on the console
        (``<label>: working on <doing>, T s`` whenever no line came for ``HEARTBEAT_SECONDS``;
        ``doing`` by default ``the step from N%``): preparing the keys of a 100k mesh is one
        call of many seconds. Warnings the call raises are collected like the job's own while a
        timer tick waits for it, which is nearly all the time it runs."""
        if not getattr(self, "_modal", False):
            yield progress  # lets execute() print progress on the console
            if not (bpy.app.background and hasattr(self, "_console_began")):
                return function(*args, **kwargs)
            # The call runs in this thread and prints nothing, the heartbeat's thread only while
            # it runs (joined when it ends), so the two never print at once.
            from ..core.heartbeat import Heartbeat
            with Heartbeat(getattr(self, "bl_label", type(self).__name__), self._console_began,
                           last=self._console_last) as heartbeat:
                heartbeat.doing = doing or f"the step from {100 * progress:.0f}%"
                result = function(*args, **kwargs)
            self._console_last = heartbeat.last
            return result
        future = worker().submit(function, *args, **kwargs)
        try:
            while not wait_for([future], timeout=WORKER_POLL_SECONDS).done:
                yield progress
        except GeneratorExit:
            future.cancel()
            raise
        return future.result()

    # -- driving the generator -------------------------------------------------------------

    def _start(self, context, modal: bool = False):
        self._modal = modal
        self._job = self.run(context)
        self._warnings: list[str] = []
        self._about: dict[str, object] = {}  # per message, the core's warning it came from (summarized)
        self._warned: list[str] = []  # the warning reports made (report), for the run's last line
        self.summary = ""
        self.triangle_faces = None
        self._ran_out = False  # the job ran out of memory (said on the console, headless)
        self._undo: list = []  # what takes back each write made so far (undo_on_failure), in order

    def undo_on_failure(self, undo) -> None:
        """Have ``undo()`` (no arguments) take back a write the job just made (shape keys added, a
        new object, a file, attributes) should the job fail after it: a job writes in its last
        step, where memory may still run out (a :class:`MemoryError` after the first keys are
        added), and an operator that does not finish leaves no undo step of its own, so the
        user's file would keep half the output. Undone last first (:meth:`_take_back`)."""
        self._undo.append(undo)

    def _take_back(self) -> None:
        """Undo the job's writes (:meth:`undo_on_failure`), last first; one that fails to be
        undone is said on the console and the others are still undone."""
        undo, self._undo = self._undo, []
        for step in reversed(undo):
            try:
                step()
            except Exception as error:  # the others still go
                print(f"Shape Differences: could not take back a write of a failed run: {error!r}", file=sys.stderr)

    def _step(self) -> tuple[str | None, float]:
        """Advance the job by one step: (final status or None while running, progress)."""
        caught = []
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    return None, next(self._job)
                except StopIteration:
                    self._undo = []
                    return 'FINISHED', 1.0
                except Exception as error:
                    self._take_back()  # whatever the failure, the file is left as it was
                    if isinstance(error, MemoryError):
                        self._ran_out = True
                        # the in-betweens' work in the background stops too, as Esc stops it: its memory
                        # goes with it (core.gap_processes.stop)
                        from ..core.gap_processes import stop as stop_background
                        stop_background()
                    message = reported_error(error, self.triangle_faces, self.memory_advice)
                    if message is None:
                        raise
                    report(self, {'ERROR'}, message)
                    return 'CANCELLED', 1.0
        finally:
            # After the recording ends: showing a foreign warning inside it would record it again.
            self._collect_warnings(caught)

    def _collect_warnings(self, caught):
        core_warning = load_core().ShapeDifferenceWarning
        for warning in caught:
            if not issubclass(warning.category, core_warning):
                warnings.showwarning(warning.message, warning.category, warning.filename,
                                     warning.lineno)
                continue
            message = name_faces(str(warning.message), self.triangle_faces)
            if message not in self._warnings:
                self._warnings.append(message)
                self._about[message] = warning.message

    def _finish(self, status: str) -> set[str]:
        for message in summarized(self._warnings, getattr(self, "bl_label", type(self).__name__), self._about):
            report(self, {'WARNING'}, message)
        if status == 'FINISHED' and self.summary:
            report(self, {'INFO'}, self.summary)
            if self._warned:  # the status bar shows the last report: the warnings, not the summary
                report(self, {'WARNING'}, look_first(self._warned, self._about))
        return {status}

    def execute(self, context):
        """Run the whole job now; in background mode print its progress on the console."""
        console = bpy.app.background
        label = getattr(self, "bl_label", type(self).__name__)
        last_print = -np.inf  # the first step's progress at once: a long run does not start silently
        self._start(context)
        # the heartbeat's seconds count from here, its silence from the last line (compute)
        self._console_began = self._console_last = time.monotonic()
        while True:
            try:
                status, progress = self._step()
            except Exception as error:
                if console:  # one line naming the cause before Blender's traceback, for a farm's log
                    print(f"{label}: {load_core().errors.unexpected_failure(error)}", file=sys.stderr, flush=True)
                raise
            if status:
                if console:  # without a UI nothing cancels a run: it ends done, or refused (the error report says why)
                    ended = ('done' if status == 'FINISHED' else 'ran out of memory, nothing changed'
                             if getattr(self, "_ran_out", False) else 'refused')
                    print(f"{label}: {ended}", file=sys.stderr, flush=True)
                return self._finish(status)
            if console and time.monotonic() - last_print >= CONSOLE_PROGRESS_INTERVAL:
                last_print = self._console_last = time.monotonic()
                print(f"{label}: {100 * progress:.0f}%", file=sys.stderr, flush=True)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        return self._start_modal(context)

    def _start_modal(self, context) -> set[str]:
        self._start(context, modal=True)
        status, _progress = self._step()  # validation runs right away
        if status:
            return self._finish(status)
        window_manager = context.window_manager
        window_manager.progress_begin(0, 100)
        self._timer = window_manager.event_timer_add(0.001, window=context.window)
        window_manager.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        """One timer tick runs one step of the job; Esc closes the job (nothing is written
        before its last step). The timer and the progress cursor go whatever happens, also when
        a step raises an unexpected error."""
        status = None
        try:
            if event.type == 'ESC':
                # the in-betweens' work in the background stops too: the gaps a second process holds,
                # the calls begun ahead (core.gap_processes.stop); a core call under way ends in the
                # worker thread, its result dropped
                from ..core.gap_processes import stop as stop_background
                stop_background()
                self._job.close()  # runs the job's clean-up; nothing has been written yet
                report(self, {'WARNING'}, "Cancelled: nothing was changed")
                status = 'CANCELLED'
            elif event.type == 'TIMER':
                status, progress = self._step()
                context.window_manager.progress_update(int(100 * progress))
        except BaseException:
            status = 'CANCELLED'
            self._job.close()
            raise
        finally:
            if status is not None:
                window_manager = context.window_manager
                window_manager.event_timer_remove(self._timer)
                window_manager.progress_end()
        if status is None:
            return {'RUNNING_MODAL'}  # block other input while the object is being worked on
        return self._finish(status)


# -- settings shared with the core ----------------------------------------------------------

#: The core settings an operator can have, by property name: each operator has those its mixin
#: declares (:class:`BasisSizeProperties`, :class:`InbetweenSettingsProperties`,
#: :class:`CoreSettingsProperties`).
CORE_SETTINGS = ("k_m", "k_n", "offset", "use_extrinsic")


class BasisSizeProperties(BasisSizes):
    """Basis sizes of an operator that takes no other core setting (*Transfer Poses*: intrinsic
    differences, no offset surface): each one not set is taken from the scene settings."""

    def core_options(self, context, vertex_count: int, target_count: int | None = None) -> dict:
        """Keyword arguments for the core facade, from this operator or the scene settings;
        ``target_count``: the vertices of the mesh k_N is the basis of, where it is another than
        the base's (a transfer's source), else the base's ``vertex_count``.

        Resolved values are written back to the operator so the Redo panel shows them.
        """
        settings = context.scene.shape_differences
        declared = [name for name in CORE_SETTINGS if name in self.properties.bl_rna.properties]
        where = {name: "" if self.properties.is_property_set(name) else SCENE_SETTING for name in declared}
        for name in declared:
            if not self.properties.is_property_set(name):
                setattr(self, name, getattr(settings, name))
        for label, name in (("k_M", "k_m"), ("k_N", "k_n")):
            check_basis_size(label, getattr(self, name), where[name], BASIS_ZERO[label])
        # Both bases live on meshes with the base's vertices (the offset surfaces have more), or
        # k_N on the other mesh of a transfer.
        for label, k, count in (("k_M", self.k_m, vertex_count), ("k_N", self.k_n, target_count or vertex_count)):
            if k >= count:
                raise InputError(
                    f"{label} = {k} is too large for a mesh with {count} vertices: "
                    f"use at most {count - 1}, or 0 for the full basis")
        if self.k_n and not self.k_m:
            raise InputError(f"k_N = {self.k_n} needs k_M (the base pose's basis size): set k_M, or k_N to 0")
        check_basis_order(self.k_m, self.k_n)
        options = dict(k_M=self.k_m or None, k_N=self.k_n or None)
        if "use_extrinsic" in declared:
            options["use_extrinsic"] = self.use_extrinsic
        if "offset" in declared:
            options["offset"] = offset_option(self.offset, where["offset"])
        return options


class InbetweenSettingsProperties(BasisSettings, BasisSizeProperties):
    """Core settings of an in-between operator (basis sizes, Extrinsic; no offset, which the
    in-betweens do not use): each one not set is taken from the scene settings."""


class CoreSettingsProperties(CoreSettings, InbetweenSettingsProperties):
    """Core settings of an operator with an offset distance (*Reconstruct*): each one not set is
    taken from the scene settings."""


def check_basis_order(k_m: int, k_n: int) -> None:
    """Refuse a target basis k_N (0: none) smaller than the base's k_M, as the core does
    (:func:`core.validation.check_basis_sizes`), before any work."""
    if k_n and k_n < k_m:
        raise InputError(f"k_N = {k_n} must be at least k_M = {k_m} (or 0)")


def playback_range(scene) -> tuple[int, int]:
    """The frames playback covers: the preview range where it is on (the timeline's clock
    button), else the scene's range — the default range of Blender's own *Bake Action*."""
    if scene.use_preview_range:
        return scene.frame_preview_start, scene.frame_preview_end
    return scene.frame_start, scene.frame_end


# -- shape key lookup -------------------------------------------------------------------------

def surface_triangles(obj, operator=None):
    """The loop triangles of ``obj``'s mesh, int64 ``(m, 3)``; a mesh without faces is an error.
    ``operator`` (a :class:`GeneratorOperator`): where the mesh has faces of more than three
    corners, it keeps the face of every triangle so that core messages name faces too."""
    triangles = triangulation.mesh_triangles(obj.data)
    if len(triangles) == 0:
        # faces its modifiers make (Geometry Nodes instances realized on a point) are not the mesh's
        # own: their vertices are no fixed set the poses and the results can be written on
        makers = [modifier.name for modifier in obj.modifiers if modifier.show_viewport]
        raise InputError(f"'{obj.name}' has no faces" + (
            f" of its own (those shown are made by its modifier{'s' if len(makers) > 1 else ''} "
            f"{', '.join(repr(name) for name in makers)}): shape differences need a surface mesh whose vertices "
            "the poses move. Export the object as Alembic and import it (a mesh played by a Mesh Sequence Cache), "
            "or convert a copy to a mesh (Object › Convert › Mesh) for a single pose" if makers else
            ": shape differences need a surface mesh"))
    if operator is not None:
        operator.triangle_faces = triangle_faces(obj, triangles)
    return triangles


def triangle_faces(obj, triangles):
    """The face of each of ``triangles`` (``obj``'s loop triangles, :func:`surface_triangles`), or
    None where every face is one triangle (:func:`name_faces`)."""
    return triangulation.loop_triangle_polygons(obj.data) if len(triangles) > len(obj.data.polygons) else None


def frame_name(frame) -> str:
    """Frame ``frame`` as messages name a pose taken there ("frame 25"): the name the operators
    hand the core with such poses (``key_names``, ``sample_names``)."""
    return f"frame {frame}"


def finite_pose(positions, what: str):
    """``positions`` read from Blender, refused by the core's check (``core.validation.check_vertices``:
    a NaN or infinite coordinate, as a simulation that exploded or a broken cache file leaves, or one
    too large) with ``what`` naming the pose as the user knows it ("frame 12 of 'Cloth'", "shape key
    'Smile' of 'Face'"): the core names only what it was given ("target vertices", "base vertices")."""
    from ..core.validation import check_vertices

    check_vertices(positions, name=what)
    return positions


def key_pose(key_block, obj):
    """The pose shape key ``key_block`` of ``obj`` shows at value 1 (:func:`bridge.mesh_data.shape_key_positions`),
    checked by :func:`finite_pose`."""
    return finite_pose(mesh_data.shape_key_positions(key_block, obj), f"shape key '{key_block.name}' of '{obj.name}'")


def mesh_pose(obj):
    """The positions of ``obj``'s mesh (:func:`bridge.mesh_data.vertex_positions`), checked by :func:`finite_pose`."""
    return finite_pose(mesh_data.vertex_positions(obj.data), f"the mesh of '{obj.name}'")


def key_blocks_of(obj, needed: int = 2):
    """The shape keys of ``obj``, requiring at least ``needed`` of them."""
    key = obj.data.shape_keys
    count = len(key.key_blocks) if key else 0
    if count < needed:
        raise InputError(
            f"'{obj.name}' has {count} shape key{'s' if count != 1 else ''}, needs at least "
            f"{needed} (a Basis and a pose): add keys in Properties › Object Data › Shape Keys, or "
            "capture an animation with 'Frames to Shape Keys'")
    return key.key_blocks


def find_key(obj, name: str, property_name: str):
    """The shape key called ``name``; the error lists the keys there are."""
    key_blocks = key_blocks_of(obj)
    key_block = key_blocks.get(name)
    if key_block is None:
        names = ", ".join(f"'{kb.name}'" for kb in key_blocks)
        raise InputError(f"'{obj.name}' has no shape key '{name}' (for {property_name}); "
                         f"pick one of {names}")
    return key_block


def default_pose_key(obj):
    """The key a user most likely means: the active shape key unless it is the Basis, else the
    last key."""
    key_blocks = key_blocks_of(obj)
    active = obj.active_shape_key
    return active if active is not None and active != key_blocks[0] else key_blocks[-1]


def resolve_key(obj, name: str, property_name: str, default):
    """``find_key`` for a given name, ``default`` (a key) when the name is empty."""
    return find_key(obj, name, property_name) if name else default


def require_count(count: int, what: str):
    if count < 1:
        raise InputError(f"Count is {count}: ask for at least 1 of the {what}")


def check_memory(n_poses: int, n_vertices: int, what: str, advice: str, *, work: str | None = "sequence",
                 batch: int = 0) -> None:
    """Refuse, before any work, a job whose output of ``n_poses`` poses of ``n_vertices`` vertices
    (``what``, made smaller as ``advice`` says), with the ``batch`` in-betweens of its largest gap
    made at once beside it (``core.validation.INBETWEEN_BYTES_PER_VERTEX`` each, as the command's
    retime counts them), would take over half the memory available
    (``core.validation.check_output_memory``), or whose computation needs more than there is
    (``check_working_memory``): ``work`` is "sequence" (in-betweens of frames), "pair" (two shape
    keys), "reconstruct", or None (poses read, nothing computed). Blender with the artist's unsaved
    work would otherwise run until the system kills it (core is imported when an operator first runs)."""
    from ..core import validation

    if work is not None:
        per_vertex = {"sequence": validation.WORKING_BYTES_PER_VERTEX,
                      "pair": validation.PAIR_WORKING_BYTES_PER_VERTEX,
                      "reconstruct": validation.RECONSTRUCT_WORKING_BYTES_PER_VERTEX}[work]
        job = "Rebuilding a pose of this mesh" if work == "reconstruct" else "In-betweening this mesh"
        validation.check_working_memory(n_vertices, job, "decimate it or split it into parts, or run it on a machine "
                                        "with more memory" + (" (python -m core retime on a farm node)"
                                                              if work == "sequence" else ""),
                                        bytes_per_vertex=per_vertex)
    validation.check_output_memory(n_poses, n_vertices, what, advice,
                                   working=int(batch) * int(n_vertices) * validation.INBETWEEN_BYTES_PER_VERTEX)


def require_distinct(first, second, first_name: str, second_name: str):
    if first == second:
        raise InputError(f"{first_name} and {second_name} are both '{first.name}': "
                         "pick two different shape keys")
