"""Retiming an animation from every ``step``-th frame: slow motion, the original timing with the
dropped frames rebuilt, or faster, with in-betweens from :class:`core.SequenceInterpolator`.

Times are in source samples (frames): sample ``j`` of an animation of ``F`` samples is at time
``j``. The key poses are samples ``0, step, 2·step, …`` and the last sample (a shorter last gap
when ``F − 1`` is not a multiple of ``step``). Output sample ``k`` shows source time
``k · speed`` for ``k = 0 … ⌊(F − 1) / speed⌋``: ``speed = 0.5`` over 25 frames gives 49. An
output sample at a key's time is that key's positions exactly; any other is the in-between of its
gap at the factor of its time within the gap.

A :class:`core.SequenceInterpolator` takes its keys evenly spaced in time (its splines' velocities
at a key come from the neighbouring keys), so a shorter last gap of ``r`` samples read as one of
its gaps gets the wrong timing, and lends the gap before it a wrong end velocity: a sheet moving
as a steady screw, 18 samples keyed every 4th, came out 2.5 % of its size off in both, where the
linear blend is exact. The sequence of all the keys is given their times (``key_times``), which
makes both gaps exact for steady motion; the short gap's in-betweens come from a second sequence
keyed every ``r`` samples up to the last sample (:attr:`RetimePlan.tail`), which knows the motion
just before it (on four cloths its in-betweens were as close to the source as the first
sequence's in the median and never more than 1.34 × the blend's error, against 2.23 ×). Numbers in
docs/inbetween-measurements.md, *Retiming a range that is not whole steps*.

Chunks: the in-betweens of a gap are asked together (:meth:`core.SequenceInterpolator.poses`
shares the work between them), so the result for a gap depends only on the keys, the gap and the
plan; every call builds the interpolator from all the keys, so computing gaps ``a:b`` in one process and ``b:c`` in another
gives exactly (bit for bit) the samples of computing ``a:c`` at once. :meth:`RetimePlan.chunk`
splits the gaps evenly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import MeshError
from .validation import (INBETWEEN_BYTES_PER_VERTEX, check_count, check_output_memory, check_positive, check_triangles,
                         check_vertices, describe)

# An output time this close to a whole sample (relative) is that sample: k · speed in floating
# point misses integers by a few ulps (3 · 0.1 = 0.30000000000000004).
WHOLE_SAMPLE_TOLERANCE = 1e-9
#: Blender's last frame (MAXFRAME); its first (MINAFRAME) is the negative. A scene set to a frame
#: beyond them shows the nearest of the two.
MAX_FRAME = 1_048_574
#: How many frames Blender has, from its first to its last (:data:`MAX_FRAME`).
BLENDER_FRAMES = 2 * MAX_FRAME + 1
#: Most output samples a retime plans: Blender's last frame. A longer retime plays nowhere, and
#: its plan alone (four arrays per output sample) would fill the memory (speed 1e-7 over 96
#: samples: 950 million samples, the process killed by the system).
MAX_OUTPUT_SAMPLES = MAX_FRAME


@dataclass(frozen=True)
class RetimePlan:
    """Which source samples are keys and, for each output sample, its gap and factor.

    ``keys``: int ``(K,)`` source samples used as key poses. ``times``: float ``(n_out,)`` source
    time of each output sample. ``gaps``: int ``(n_out,)`` the gap (key ``g`` → ``g + 1``) each
    output sample lies in (the last key belongs to the last gap). ``factors``: float ``(n_out,)``
    position within the gap (0 at key ``g``, 1 at key ``g + 1``). ``exact_keys``: int
    ``(n_out,)`` the key an output sample shows exactly, −1 for in-betweens. ``tail``: int, the
    source samples keying the shorter last gap's own sequence (``r`` apart, ending on the last two
    keys), empty when every gap is ``step`` long (see the module docstring).
    """

    n_source: int
    step: int
    speed: float
    keys: np.ndarray
    times: np.ndarray
    gaps: np.ndarray
    factors: np.ndarray
    exact_keys: np.ndarray
    tail: np.ndarray

    @property
    def n_gaps(self) -> int:
        return len(self.keys) - 1

    @property
    def samples_read(self) -> list[int]:
        """The source samples the in-betweens need (the keys, the tail's and the middles of the
        first and last gaps, :attr:`start_samples` and :attr:`end_samples`), in order."""
        middles = {ends[3] for ends in (self.start_samples, self.end_samples) if ends and ends[3] is not None}
        return sorted(set(self.keys.tolist()) | set(self.tail.tolist()) | middles)

    @property
    def start_samples(self) -> tuple | None:
        """:func:`start_samples` of this plan's keys."""
        return start_samples(self.keys)

    @property
    def end_samples(self) -> tuple[int, int, int, int] | None:
        """:func:`end_samples` of this plan's keys and tail."""
        return end_samples(self.keys, self.tail)

    @property
    def n_out(self) -> int:
        return len(self.times)

    def chunk(self, index: int, count: int) -> range:
        """The gaps of chunk ``index`` (0-based) of ``count`` near-equal contiguous chunks: chunk
        ``i`` starts at gap ``n_gaps · i // count``. Only its own two bounds are computed (in Python
        integers), whatever the count: a list of every chunk's bounds grows with the count."""
        if not (isinstance(count, (int, np.integer)) and count >= 1 and 0 <= index < count):
            raise ValueError(f"chunk {index} of {count}: need 0 <= index < count and count >= 1.")
        index, count = int(index), int(count)
        return range(self.n_gaps * index // count, self.n_gaps * (index + 1) // count)

    def batch(self, gaps: range) -> int:
        """The most in-betweens (output samples that are no keys) of one gap in ``gaps``: what
        :func:`iter_retime` asks of a sequence at once."""
        outputs = self.outputs(gaps)
        asked = self.gaps[outputs.start:outputs.stop][self.exact_keys[outputs.start:outputs.stop] < 0]
        return int(np.bincount(asked).max()) if asked.size else 0

    def outputs(self, gaps: range) -> range:
        """The output samples that lie in ``gaps`` (a contiguous range, possibly empty)."""
        start = int(np.searchsorted(self.gaps, gaps.start, side="left"))
        stop = int(np.searchsorted(self.gaps, gaps.stop, side="left"))
        return range(start, stop)


def step_remedy(n_frames: int, step: int, keys: int = 2) -> str:
    """What makes ``n_frames`` frames taken every ``step``-th give ``keys`` (≥ 2) of them, where they
    give fewer: a step the frames span ``keys − 1`` times, or more frames where Blender has that many
    (:data:`BLENDER_FRAMES`; a step past them leaves only the smaller step)."""
    gaps = keys - 1
    remedies = ([f"a step of at most {(n_frames - 1) // gaps}"] if n_frames - 1 >= gaps else []) + \
               ([f"at least {step * gaps + 1} frames"] if step * gaps + 1 <= BLENDER_FRAMES else [])
    return " or ".join(remedies) or f"at least {keys} frames and a smaller step"


def plan_retime(n_source: int, step: int, speed: float) -> RetimePlan:
    """Plan the retime of ``n_source`` samples keyed every ``step``-th, played at ``speed``: at
    least two output samples (a speed of at most ``n_source − 1``) and at most
    :data:`MAX_OUTPUT_SAMPLES`, and at most as many keys, else :class:`MeshError`."""
    step_given = step
    try:  # whole numbers and a real number: NaN, text, booleans, complex, arrays are refused in these terms
        step = check_count(step, "step")
    except MeshError:
        step = None
    if step is None or step < 1:
        raise MeshError(f"The frame step must be a whole number of at least 1; got {describe(step_given)}.")
    try:
        speed = check_positive(speed, "speed")
    except MeshError:
        raise MeshError(f"The speed must be a positive number; got {describe(speed)}.") from None
    n_source = check_count(n_source, "The number of frames", minimum=None)
    if n_source < 2 or n_source - 1 < step:
        raise MeshError(
            f"{n_source} frame{'s' if n_source != 1 else ''} with step {step} give fewer than two key "
            f"poses: use {step_remedy(n_source, step)}."
        )
    last = n_source - 1
    span = last / speed * (1 + WHOLE_SAMPLE_TOLERANCE)  # n_out − 1 before the floor; may overflow to inf
    if span >= MAX_OUTPUT_SAMPLES:
        count = f"{math.floor(span) + 1:,}" if span < 1e15 else f"{span:.3g}"
        raise MeshError(f"Speed {speed:g} over {n_source} frames gives {count} output frames, more than "
                        f"{MAX_OUTPUT_SAMPLES:,} (the last frame Blender plays): raise the speed (0.5 = twice "
                        "as slow) or retime a shorter range.")
    n_out = math.floor(span) + 1
    if n_out < 2:  # a speed above F − 1 (Blender's largest, 3.4e38, too) shows only the first key
        raise MeshError(f"Speed {speed:g} over {n_source} frames gives one output frame (the first), and a "
                        f"retime needs at least two: use a speed of at most {last} (the range played in two "
                        "frames) or retime a longer range.")
    if last // step + 1 > MAX_OUTPUT_SAMPLES:  # checked before the keys are listed (2^31 of them: 16 GB)
        raise MeshError(f"{n_source:,} frames with step {step} give {last // step + 1:,} key poses, more than "
                        f"{MAX_OUTPUT_SAMPLES:,} (the last frame Blender plays): use a larger step or retime a "
                        "shorter range.")
    keys = np.arange(0, n_source, step)
    tail = short_gap_keys(int(keys[-1]), last)
    if keys[-1] != last:
        keys = np.append(keys, last)
    times = np.arange(n_out) * speed
    whole = np.round(times)
    snap = np.abs(times - whole) <= WHOLE_SAMPLE_TOLERANCE * np.maximum(1.0, whole)
    times = np.minimum(np.where(snap, whole, times), last)
    gaps = np.clip(np.searchsorted(keys, times, side="right") - 1, 0, len(keys) - 2)
    starts, ends = keys[gaps], keys[gaps + 1]
    factors = (times - starts) / (ends - starts)
    exact = np.full(n_out, -1)
    exact[factors == 0.0] = gaps[factors == 0.0]
    exact[factors == 1.0] = gaps[factors == 1.0] + 1
    return RetimePlan(n_source, step, speed, keys, times, gaps, factors, exact, tail)


def short_gap_keys(last_key: int, last: int) -> np.ndarray:
    """The samples (int) keying a last gap shorter than the step, from sample ``last_key`` (the
    last whole-step key, ≥ 0) to ``last``: the sequence of its own, ``r = last − last_key`` apart —
    up to two keys before ``last_key`` (those ≥ 0), ``last_key`` and ``last``; empty when ``last
    == last_key`` (see the module docstring)."""
    short = last - last_key
    if short <= 0:
        return np.zeros(0, dtype=np.int64)
    return np.array([last_key - j * short for j in (2, 1) if last_key - j * short >= 0] + [last_key, last], dtype=np.int64)


def end_samples(keys, tail) -> tuple[int, int, int, int] | None:
    """The samples (or frames) telling how the motion reaches the last key
    (:func:`core.motion_ends.end_of_motion`), for a sequence keyed on ``keys`` whose shorter last
    gap, if any, is keyed by its own sequence on ``tail`` (:func:`short_gap_keys`): the last three
    keys of the sequence that makes the last gap (the tail's, evenly spaced, where it has them)
    and the sample in the middle of that gap; None with fewer than three keys or a last gap
    shorter than two samples."""
    keys = tail if len(tail) >= 3 else keys
    if len(keys) < 3 or keys[-1] - keys[-2] < 2:
        return None
    before, start, end = (int(k) for k in keys[-3:])
    return before, start, end, start + (end - start) // 2


def start_samples(keys) -> tuple | None:
    """The samples (or frames) telling how the motion leaves the first key
    (:func:`core.motion_ends.start_of_motion`), for a sequence keyed on ``keys``: the first three
    keys and the sample in the middle of the first gap (None where the keys are one sample apart);
    None with fewer than three keys."""
    if len(keys) < 3:
        return None
    first, second, third = (int(k) for k in keys[:3])
    return first, second, third, first + (second - first) // 2 if second - first >= 2 else None


def motion_ends(samples, keys, tail, chosen=()) -> dict:
    """``start`` and ``end`` of the :class:`core.SequenceInterpolator` keyed on ``keys`` (and of
    the shorter last gap's, keyed on ``tail``), chosen from the source: ``samples[i]`` the positions
    at sample (or frame) ``i`` of :func:`start_samples` and :func:`end_samples` (an array or a
    dict), in the space the sequence interpolates. ``start`` from the middle of the first gap
    (:func:`core.motion_ends.start_of_motion`; ``"keys"`` where the keys are the source, one
    sample apart), ``end`` from the middle of the last (:func:`core.motion_ends.end_of_motion`);
    neither where the keys do not tell, nor those named in ``chosen`` (the caller's). MeshError where
    a middle sample is no pose of the keys' mesh (a non-finite coordinate would make both choices'
    distances NaN, and the comparison choose silently)."""
    from .motion_ends import end_of_motion, start_of_motion

    def middle_pose(sample, key):
        return check_vertices(samples[sample], len(samples[key]), name=f"sample {sample}")

    options = {}
    starts = start_samples(keys)
    if "start" not in chosen and starts is not None:
        first, second, third, middle = starts
        options["start"] = "keys" if middle is None else start_of_motion(
            [samples[first], samples[second], samples[third]], middle_pose(middle, first),
            (middle - first) / (second - first), (second - first, third - second))
    ends = end_samples(keys, tail)
    if "end" not in chosen and ends is not None:
        before, start, end, middle = ends
        options["end"] = end_of_motion([samples[before], samples[start], samples[end]], middle_pose(middle, start),
                                       (middle - start) / (end - start), (start - before, end - start))
    return options


def _check_samples(samples) -> None:
    """MeshError unless ``samples`` can be counted and indexed (a list of poses, an array, a memory
    map); each sample read is checked as a pose where it is read (:func:`_key_pose`)."""
    if not hasattr(samples, "__len__") or not hasattr(samples, "__getitem__") or isinstance(samples, (str, bytes)):
        raise MeshError(f"samples must be a sequence of poses (n, 3) or an array (samples, n, 3); got {describe(samples)}.")


def _key_pose(sample, name: str, n_vertices: int | None = None) -> np.ndarray:
    """A source ``sample`` as float64 ``(n, 3)``, checked (:func:`core.validation.check_vertices`:
    real numbers, shape, finite, ``n_vertices`` vertices where given; ``name`` in its messages),
    made read-only where the conversion made an array of its own (float32 samples, a memory map's
    rows), so the sequence keeps it as its key instead of a copy; the caller's own float64 arrays (a
    list of frames) are left as they are, writable."""
    pose = check_vertices(sample, n_vertices, name=name)
    if pose is not sample and pose.base is None:
        pose.flags.writeable = False
    return pose


def short_gap_sequence(samples, triangles, tail, first=None, **interpolator_options):
    """The :class:`core.SequenceInterpolator` of a short last gap keyed on samples ``tail``
    (:func:`short_gap_keys`; ``samples[i]``: sample ``i``'s positions, checked by the caller where
    it names them: :func:`iter_retime` its keys and the tail's other samples, the *In-between
    Frames* operator its frames; the sequence checks its keys again, as every one does), starting
    inside the motion; its last gap is the short gap. ``first``: the sample the whole sequence
    starts at, whose edges its warnings measure deviations from where no ``rest_pose`` is given: the
    tail's are measured from it too, not from the tail's first key, a shape deep in the motion
    (:mod:`core.sequence_edge_misfit`), where it is within :data:`core.rest_pose_scale.REST_SCALE_LIMIT`
    of the tail's first key's size (else from that key)."""
    from .rest_pose_scale import rest_scale, scale_taken
    from .sequence_inbetweens import SequenceInterpolator

    # the whole sequence's first sample stands for the rest only where it is a rest of the tail's keys
    # (a mesh grown past twice its size since, a shape key's grow, is measured from the tail's first key)
    rest = {} if (first is None or interpolator_options.get("rest_pose") is not None or not scale_taken(
        rest_scale(samples[first], samples[tail[0]], triangles))) else {"rest_pose": samples[first]}
    return SequenceInterpolator([samples[key] for key in tail], triangles,
                                **{**interpolator_options, **rest, "start": "keys"})


def iter_retime(samples, triangles, plan: RetimePlan, gaps: range | None = None, *, sample_names=None,
                **interpolator_options):
    """Yield ``(output index, positions float64 (n, 3))`` for the output samples in ``gaps``
    (default: all), in order.

    ``sample_names``: a function of a source sample's index giving its name in warnings (such as
    its frame); by default the keys are ``"key pose i"`` (the i-th of :attr:`RetimePlan.keys`).

    ``samples``: the source, float ``(n_source, n, 3)`` (a memory map is fine: only
    :attr:`RetimePlan.samples_read` are read).
    ``interpolator_options``: ``k_M``, ``k_N``, ``offset``, ``use_extrinsic``, ``smooth``, ``start``,
    ``end``, ``rest_pose`` of :class:`core.SequenceInterpolator`; ``start`` by default from the middle of the first gap
    (:func:`core.motion_ends.start_of_motion`), ``end`` from the middle of the last gap
    (:func:`core.motion_ends.end_of_motion`); the shorter last gap's sequence starts inside the
    motion (``start="keys"``) and ends as the whole one.
    """
    from .sequence_inbetweens import SequenceInterpolator

    _check_samples(samples)
    if len(samples) != plan.n_source:
        raise MeshError(f"The plan is for {plan.n_source} samples; got {len(samples)}.")
    gaps = range(plan.n_gaps) if gaps is None else gaps
    if not isinstance(gaps, range) or gaps.step != 1 or gaps.start < 0 or gaps.stop > plan.n_gaps or gaps.start > gaps.stop:
        raise MeshError(f"gaps {describe(gaps)} is not a contiguous range within the {plan.n_gaps} gaps.")
    key_names = [f"key pose {i}" if sample_names is None else sample_names(int(key))
                 for i, key in enumerate(plan.keys)]
    first = _key_pose(samples[plan.keys[0]], key_names[0])
    # every key of the first key's vertex count, and the faces of a mesh of them, before the motion's
    # ends are read from the samples (:func:`motion_ends`): keys of two counts reached it as NumPy's
    # "operands could not be broadcast", empty keys as its "Mean of empty slice" warning
    key_poses = [first] + [_key_pose(samples[key], name, len(first))
                           for key, name in zip(plan.keys[1:], key_names[1:])]
    check_triangles(triangles, len(first))
    # the short last gap's tail: its keys named as the plan's, as the main sequence's warnings name
    # them (its last gap is the plan's last, "between key pose K − 2 and key pose K − 1"; the samples
    # before it are no keys of the plan); those that are no keys checked here, once, before the end
    # of the motion is read from them
    position = {int(key): i for i, key in enumerate(plan.keys)}
    tail_names = [sample_names(int(s)) if sample_names is not None else
                  f"key pose {position[int(s)]}" if int(s) in position else f"sample {int(s)}" for s in plan.tail]
    checked = {int(key): pose for key, pose in zip(plan.keys, key_poses)}
    for s, name in zip(plan.tail, tail_names):
        if int(s) not in checked:
            checked[int(s)] = _key_pose(samples[s], name, len(first))
    read = {s: checked[s] if s in checked else samples[s] for s in plan.samples_read}  # middles: motion_ends checks them
    interpolator_options = {**interpolator_options, **motion_ends(read, plan.keys, plan.tail, interpolator_options)}
    names = None if sample_names is None else key_names
    sequence = SequenceInterpolator(key_poses, triangles, **interpolator_options, key_times=plan.keys, key_names=names)
    tail = None
    if len(plan.tail) and gaps.stop == plan.n_gaps:
        tail = short_gap_sequence(checked, triangles, plan.tail, int(plan.keys[0]), **interpolator_options,
                                  key_names=tail_names)
    # the in-betweens' output indices of each gap, in order (outputs are sorted by gap)
    rows_of: dict[int, list[int]] = {}
    for index in plan.outputs(gaps):
        if plan.exact_keys[index] < 0:
            rows_of.setdefault(int(plan.gaps[index]), []).append(int(index))
    # the sequence's gaps asked, in order, with their factors: the later ones may be computed in a
    # second process meanwhile (core.gap_processes)
    sequence.will_ask((gap, [float(plan.factors[i]) for i in rows]) for gap, rows in rows_of.items()
                      if not (tail is not None and gap == plan.n_gaps - 1))
    batch: dict[int, np.ndarray] = {}  # output index → pose, for the in-betweens of one gap asked together
    for index in plan.outputs(gaps):
        key = plan.exact_keys[index]
        if key >= 0:
            yield index, key_poses[key].copy()
            continue
        gap = int(plan.gaps[index])
        if index not in batch:
            rows = rows_of[gap]
            factors = [float(plan.factors[i]) for i in rows]
            short = tail is not None and gap == plan.n_gaps - 1
            # the sequence's last gap asked (the shorter last gap is the tail's): nothing begun ahead of it
            ahead = gap + 1 < gaps.stop - (tail is not None)
            batch = dict(zip(rows, tail.poses(len(tail) - 1, factors) if short else
                             sequence.poses(gap, factors, ahead=ahead)))
        yield index, batch[index]


def retime(samples, triangles, *, step: int, speed: float, gaps: range | None = None,
           **interpolator_options) -> np.ndarray:
    """The retimed samples float32 ``(n_out, n, 3)`` (only those in ``gaps`` if given) of
    ``samples`` float ``(n_source, n, 3)`` keyed every ``step``-th, at ``speed``; see the module
    docstring."""
    _check_samples(samples)  # before len(): a clear refusal of what has none
    plan = plan_retime(len(samples), step, speed)
    # the output (and the in-betweens of its largest gap while they are made) within half the memory
    # available, before any work, as the command's and the operators'; the vertex count read from the
    # first key before iter_retime checks it (once, by its name): a pose of another shape than (n, 3)
    # (a flat (3n,) one, none) counts none here and is refused there by its shape
    try:
        shape = np.shape(samples[int(plan.keys[0])])
    except (TypeError, ValueError):  # no pose, a ragged one
        shape = ()
    n_points = int(shape[0]) if len(shape) == 2 and shape[1] == 3 else 0
    asked = range(plan.n_gaps) if gaps is None else gaps if isinstance(gaps, range) else range(0)  # else refused
    outputs = plan.outputs(asked)  # by iter_retime
    check_output_memory(len(outputs), n_points, "The output of this retime",
                        "retime it in parts (gaps=plan.chunk(i, count)) or raise the speed",
                        working=plan.batch(asked) * n_points * INBETWEEN_BYTES_PER_VERTEX)
    poses = np.empty((len(outputs), n_points, 3), dtype=np.float32)  # filled in place: no float64 list beside it
    for index, pose in iter_retime(samples, triangles, plan, gaps, **interpolator_options):
        poses[index - outputs.start] = pose
    return poses
