"""Headless commands on point caches, without Blender (studio batches and farms).

    python -m core retime in.pc2 --topology mesh.obj --step 4 --speed 0.5 -o out.pc2
    python -m core retime in.pc2 --topology mesh.obj --step 4 --speed 0.5 --chunk 2/8 -o part2.pc2
    python -m core merge part1.pc2 part2.pc2 ... -o out.pc2
    python -m core merge --numbered 'parts/chunk#.pc2' --count 8 -o out.pc2 \
        --retime in.pc2 --topology mesh.obj --step 4 --speed 0.5
    python -m core info in.pc2

``retime`` reads a PC2 or MDD cache (exported by any package) and the mesh's faces from an OBJ
with the same vertices in the same order, keys every ``--step``-th sample and writes a PC2 that
plays the motion at ``--speed`` (see :mod:`core.retime`). ``--chunk I/N`` (1-based) or
``--gaps A:B`` computes only the output samples of some key gaps; ``merge`` concatenates the
chunk files into exactly (bit for bit) the file one process writes; given the retime's input
and settings (``--retime``), it refuses chunks of any other retime, such as another job's written
into a shared chunk folder. Progress goes to stderr; warnings print one line each
(``retime: warning [pose]: …`` with the warning's kind, :data:`core.errors.KINDS`; exit status 0) and a line of how many of each kind there were at the end
(``retime: 3 warning(s): 3 pose; most flipped or collapsed triangles kept: 121, between …``),
errors one line and exit with status 2.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import signal
import sys
import threading
import time
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .errors import ShapeDifferenceError, ShapeDifferenceWarning, unexpected_failure, warn
from .gap_processes import start_worker
from .heartbeat import HEARTBEAT_SECONDS, Heartbeat
from .heartbeat import line as _line
from .heartbeat import whole
from .obj_file import read_obj
from .point_cache import (check_disk_space, check_pc2_name, check_pc2_timing, foreign_path, merge_pc2, pc2_size,
                          read_pc2_header, read_point_cache, refuse_overwriting, unwritable, write_pc2)
from .retime import MAX_OUTPUT_SAMPLES, iter_retime, plan_retime
from .validation import INBETWEEN_BYTES_PER_VERTEX, check_output_memory, check_working_memory


def _too_many_chunks(count: int) -> str | None:
    """Why ``count`` chunks of a retime (``retime --chunk I/N``'s N, ``merge --count``) are more than
    any retime is split into, or None: a retime has at most :data:`core.retime.MAX_OUTPUT_SAMPLES`
    key gaps (Blender's frames), so the chunks past them are empty, and a merge would look for each
    one's file (a count in the trillions would list that many names before looking for the first)."""
    if count <= MAX_OUTPUT_SAMPLES:
        return None
    return (f"{count:,} chunks are more than any retime has key gaps (at most {MAX_OUTPUT_SAMPLES:,}, one per "
            "frame Blender plays): give the number of chunks the retime was split into")


def _chunk(text: str) -> tuple[int, int]:
    try:
        index, count = (int(part) for part in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--chunk wants I/N (e.g. 2/8); got {text!r}") from None
    if not 1 <= index <= count:
        raise argparse.ArgumentTypeError(f"--chunk {text}: need 1 <= I <= N")
    too_many = _too_many_chunks(count)
    if too_many:
        raise argparse.ArgumentTypeError(f"--chunk {text}: {too_many}")
    return index - 1, count


def _gap_range(text: str) -> tuple[int, int]:
    try:
        start, stop = (int(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--gaps wants A:B (e.g. 0:6); got {text!r}") from None
    return start, stop


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m core", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)

    retime = commands.add_parser("retime", help="retime a PC2/MDD cache from every step-th sample")
    retime.add_argument("cache", help="input PC2 or MDD file")
    _add_retime_settings(retime, required=True)
    part = retime.add_mutually_exclusive_group()
    part.add_argument("--chunk", type=_chunk, help="compute chunk I of N (1-based) of the key gaps")
    part.add_argument("--gaps", type=_gap_range, help="compute key gaps A to B (0-based, B excluded)")
    retime.add_argument("-o", "--output", required=True, help="output PC2 file")
    retime.add_argument("--merged-output", metavar="PC2",
                        help="with --chunk/--gaps: the file the chunks will be merged into, checked as -o is "
                             "before any work (a farm job's output: a path the merge cannot write fails "
                             "every chunk at once, not after all of them)")
    retime.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")

    merge = commands.add_parser("merge", help="concatenate retimed chunks (in order) into one PC2")
    merge.add_argument("parts", nargs="*", help="chunk PC2 files in chunk order")
    merge.add_argument("--numbered", metavar="PATTERN",
                       help="chunk files named by PATTERN with '#' in its file name (not its folders) "
                            "replaced by 1..COUNT (for farm jobs)")
    merge.add_argument("--count", type=int, help="number of numbered chunk files")
    merge.add_argument("-o", "--output", required=True, help="output PC2 file")
    merge.add_argument("--retime", metavar="CACHE",
                       help="the input cache of the retime whose chunks these are, with that retime's "
                            "--topology, --step, --speed and other settings: chunks of any other retime "
                            "(another job's, in a shared chunk folder) are refused")
    _add_retime_settings(merge, required=False)

    info = commands.add_parser("info", help="print a cache's header")
    info.add_argument("cache", help="PC2 or MDD file")
    return parser


def _add_retime_settings(parser: argparse.ArgumentParser, required: bool) -> list[argparse.Action]:
    """The options that say what a retime computes besides its input cache: ``retime`` takes them,
    and ``merge --retime`` the same, to know which retime its chunks must be of. Returns them."""
    add = parser.add_argument
    return [
        add("--topology", required=required, help="OBJ file with the mesh's faces (same vertex order)"),
        add("--step", type=int, required=required, help="key every step-th sample"),
        add("--speed", type=float, default=1.0,
            help="0.5 = twice as slow, 1 = original timing (dropped samples rebuilt), 2 = twice as fast"),
        add("--k-m", type=int, default=0, help="base basis size (0 = full basis)"),
        add("--k-n", type=int, default=0, help="target basis size (0 = not truncated)"),
        add("--offset", type=float, default=0.0,
            help="no effect: in-betweens use no offset surface (the rotations come from the "
                 "keys); accepted so that older job scripts run"),
        add("--intrinsic", action="store_true", help="intrinsic shape differences only"),
        add("--linear", action="store_true", help="linear instead of cubic interpolation between keys"),
        add("--start", type=float,
            help="frame of the output's first sample (default: the input PC2's start; 0 for MDD)"),
    ]


def _numbered(pattern: str, count: int | None) -> list[str]:
    """The files ``pattern`` names with the ``#`` of its file name replaced by 1 … ``count``
    (a ``#`` in a folder, such as ``shot#12/``, stays)."""
    folder, name = os.path.split(pattern)
    if "#" not in name or not count or count < 1:
        raise ShapeDifferenceError("--numbered needs a PATTERN whose file name has a '#' (such as "
                                   "chunks/chunk#.pc2) and --count N >= 1")
    too_many = _too_many_chunks(count)
    if too_many:  # before the names are listed
        raise ShapeDifferenceError(f"--count {count}: {too_many}.")
    return [os.path.join(folder, name.replace("#", str(i))) for i in range(1, count + 1)]


def _even_times(times: np.ndarray) -> bool:
    """Whether an MDD's frame ``times`` (seconds) are finite, increasing and evenly spaced (to 1e-3
    of a step): frames at one time, or going back in time, are retimed in the file's order as if
    they were not."""
    if not np.isfinite(times).all():
        return False
    if times.size < 2:
        return True
    steps = np.diff(times)
    return bool(steps.min() > 0 and np.ptp(steps) <= 1e-3 * np.mean(steps))


class _SamplesRead:
    """The input samples a retime reads (:attr:`core.retime.RetimePlan.samples_read`), copied from
    the file once and indexed by sample as the cache's positions are: the in-betweens and the chunk's stamp
    (:func:`_job_fingerprint`) are then of the same data even where the file is written over in
    place while the task runs (a simulation cached again under its name: the memory map would show
    the new bytes to the stamp, or stop the process with SIGBUS where the new file is shorter)."""

    def __init__(self, cache, read):
        self._count = cache.n_samples
        self._samples = {int(sample): np.array(cache.positions[sample]) for sample in read}

    def __len__(self) -> int:
        return self._count

    def __getitem__(self, sample) -> np.ndarray:
        return self._samples[int(sample)]


def _job_fingerprint(cache, samples, samples_read, triangles, args) -> str:
    """What makes two chunks parts of one retime (:func:`core.point_cache.check_stamps`): the
    input's header and the samples the retime reads (``samples[i]``: sample ``i``'s positions), the
    faces, and every setting that changes the output (not file names: workers may see a share under
    other paths)."""
    digest = hashlib.sha256(json.dumps([
        cache.n_points, cache.n_samples, cache.start, cache.sampling, args.step, args.speed, args.start,
        args.k_m, args.k_n, args.intrinsic, args.linear]).encode())
    if cache.times is not None:
        digest.update(np.ascontiguousarray(cache.times, dtype="<f8").tobytes())
    for sample in samples_read:
        digest.update(np.ascontiguousarray(samples[sample], dtype="<f4").tobytes())
    digest.update(np.ascontiguousarray(triangles, dtype="<i8").tobytes())
    return digest.hexdigest()


def _merged_job(args) -> str | None:
    """The fingerprint of the retime ``merge --retime`` names (the one its chunks' stamps must
    carry), computed from the input cache's contents and the settings as ``retime`` computes it,
    or None without ``--retime``."""
    if args.retime is None:
        # A setting away from its default names a retime, which only --retime checks the chunks against:
        # without it the setting would be ignored, so it is refused.
        given = [setting.option_strings[0] for setting in _add_retime_settings(argparse.ArgumentParser(), False)
                 if getattr(args, setting.dest) != setting.default]
        if given:
            raise ShapeDifferenceError(
                f"{given[0]} goes with --retime CACHE (the input of the retime whose chunks are merged): "
                "--retime turns on the check that the chunks are of the retime these settings describe; "
                "without it they have no effect")
        return None
    if args.topology is None or args.step is None:
        raise ShapeDifferenceError("--retime CACHE needs the retime's --topology and --step (and its --speed "
                                   "and other settings) to know which retime the chunks must be of")
    cache = read_point_cache(args.retime)
    _, triangles = read_obj(args.topology)
    plan = plan_retime(cache.n_samples, args.step, args.speed)
    return _job_fingerprint(cache, cache.positions, np.asarray(plan.samples_read, dtype=int), triangles, args)


def _check_output(path: str, inputs: dict, what: str = "") -> None:
    """Refuse, before any work, an output ``path`` no PC2 can be written to
    (:func:`core.point_cache.check_pc2_name`, :func:`~core.point_cache.unwritable`), one of the
    files ``inputs`` ({path: what it is}) the job reads, and one not named ``.pc2``: the Cache File
    of the operators gets ``.pc2`` added, but the name a command is given is the one the next step
    of a script or job reads, so it is not changed. ``what``: the option the path came from, when
    not ``-o``, for the messages."""
    try:
        check_pc2_name(path)
        refuse_overwriting(path, inputs)
        if Path(path).suffix.lower() != ".pc2":
            raise ShapeDifferenceError(f"'{path}' is not named .pc2, and the output is a PC2 file: name it "
                                       f"'{path}.pc2' (or another name ending in .pc2).")
        reason = unwritable(path)
        if reason:
            raise ShapeDifferenceError(f"Cannot write '{path}': {reason}. Give another output file.")
    except ShapeDifferenceError as error:
        if not what:
            raise
        raise ShapeDifferenceError(f"{what}: {error}") from None


def _check_parts_exist(parts: list[str]) -> None:
    """Name the first of the chunk files ``parts`` (in chunk order) that does not exist, and the
    retime task that writes it."""
    missing = [index for index, part in enumerate(parts, 1) if not os.path.lexists(part)]
    if missing:
        index, count = missing[0], len(parts)
        others = f" ({len(missing)} of the {count} are missing)" if len(missing) > 1 else ""
        raise ShapeDifferenceError(
            f"Chunk {index} of {count}, '{parts[index - 1]}', does not exist{others}: the retime task "
            f"`python -m core retime ... --chunk {index}/{count} -o {parts[index - 1]}` writes it (in "
            f"farm/retime.openjd.yaml, task Chunk={index} of step RetimeChunk). Run that task (again, if "
            "it failed or was cancelled), or check the chunk names and --count, then merge.")


def _retime(args) -> int:
    # the progress lines' seconds count from the start, and the heartbeat covers the reading too:
    # at 100k vertices the OBJ and the keys' samples take 3 s before the first in-between's 1 s
    with Heartbeat("retime", time.monotonic(), args.quiet, every=HEARTBEAT_SECONDS) as progress:
        progress.doing = f"reading '{args.cache}' and '{args.topology}'"
        return _retime_in(args, progress)


def _retime_in(args, progress: Heartbeat) -> int:
    inputs = {args.cache: "the input cache", args.topology: "the topology OBJ"}
    _check_output(args.output, inputs)  # said before the in-betweens, which it would waste
    if args.merged_output is not None:
        if args.chunk is None and args.gaps is None:
            raise ShapeDifferenceError("--merged-output goes with --chunk I/N or --gaps A:B (a part of a job "
                                       "whose chunks are merged into it); a whole retime writes -o itself.")
        _check_output(args.merged_output, {**inputs, args.output: "this chunk's output (-o)"},
                      "--merged-output (the file the chunks will be merged into)")
    cache = read_point_cache(args.cache)
    check_pc2_timing(cache.start if args.start is None else args.start, cache.sampling)  # before any work
    if not (np.isfinite(args.offset) and args.offset >= 0):
        raise ShapeDifferenceError(f"--offset {args.offset:g} must be 0 or positive (it has no effect: "
                                   "in-betweens use no offset surface).")
    if args.offset:
        progress.say("retime: --offset has no effect on in-betweens (ignored)")
    if cache.times is not None and not _even_times(cache.times):
        # said as the core's warnings are (_warnings_as_lines), and counted with them
        warn(f"the frame times of '{args.cache}' are not evenly spaced and increasing (or not finite); its frames "
             "are retimed in the file's order as if they were", "frame_times")
    plan = plan_retime(cache.n_samples, args.step, args.speed)
    if args.chunk is not None:
        gaps = plan.chunk(*args.chunk)
    elif args.gaps is not None:
        gaps = range(*args.gaps)
        if not 0 <= gaps.start <= gaps.stop <= plan.n_gaps:
            raise ShapeDifferenceError(f"--gaps {gaps.start}:{gaps.stop} is outside the {plan.n_gaps} key gaps.")
    else:
        gaps = range(plan.n_gaps)
    # the in-betweens' second process started before the OBJ and the keys' samples are read, where this
    # part's gaps may be shared with it (two or more; not a farm's one-gap chunk): its start overlaps the
    # reading (core.gap_processes)
    start_worker(cache.n_points, len(gaps), args.k_m or None)
    rest, triangles = read_obj(args.topology)
    if len(rest) != cache.n_points:
        raise ShapeDifferenceError(
            f"'{args.topology}' has {len(rest)} vertices but '{args.cache}' has {cache.n_points} points: "
            "export the OBJ from the same mesh, without modifiers that change its vertices."
        )
    read = np.asarray(plan.samples_read, dtype=int)
    samples = _SamplesRead(cache, read)
    broken = read[[not np.isfinite(samples[sample]).all() for sample in read]]
    if broken.size:  # said here in the cache's own samples and frames, not as a key pose's index
        first = int(broken[0])
        raise ShapeDifferenceError(
            f"'{args.cache}' sample {first + 1} (frame {cache.start + first * cache.sampling:g}) has "
            f"non-finite coordinates (NaN or inf; {broken.size} of the samples the retime reads): the "
            "simulation exploded there. Export the cache again without those frames, or pick a --step "
            "whose keys avoid them.")
    outputs = plan.outputs(gaps)
    options = dict(k_M=args.k_m or None, k_N=args.k_n or None, offset=args.offset or None,
                   use_extrinsic=not args.intrinsic, smooth=not args.linear)
    check_working_memory(cache.n_points, "In-betweening this cache", "run it on a node with more memory")
    check_output_memory(len(outputs), cache.n_points, "The output of this retime",
                        "split it across processes with --chunk I/N (and merge the parts), or raise --speed",
                        working=plan.batch(gaps) * cache.n_points * INBETWEEN_BYTES_PER_VERTEX)
    check_disk_space(args.output, pc2_size(cache.n_points, len(outputs)))
    if args.merged_output is not None:
        try:
            check_disk_space(args.merged_output, pc2_size(cache.n_points, plan.n_out))
        except ShapeDifferenceError as error:
            raise ShapeDifferenceError(f"--merged-output (the file the chunks will be merged into): {error}") from None
    poses = np.empty((len(outputs), cache.n_points, 3), dtype=np.float32)
    progress.say(f"retime: read {len(read)} of {cache.n_samples} samples (the keys and what they need), "
                 f"{cache.n_points} points, {progress.seconds()}; in-betweening {len(outputs)} sample(s) "
                 f"(key gaps {gaps.start}:{gaps.stop} of {plan.n_gaps})")

    def named(sample: int) -> str:  # the core's warnings name the keys as the messages here name samples
        return f"sample {sample + 1} (frame {cache.start + sample * cache.sampling:g})"

    def sample(index: int) -> str:
        return f"sample {index + 1}/{plan.n_out} (gap {plan.gaps[index] + 1}/{plan.n_gaps})"

    progress.doing = sample(outputs.start) if len(outputs) else f"writing '{args.output}'"
    for done, (index, pose) in enumerate(iter_retime(samples, triangles, plan, gaps, sample_names=named, **options), 1):
        poses[index - outputs.start] = pose
        progress.say(f"retime: {sample(index)}, {done}/{len(outputs)} of this part, {progress.seconds()}",
                     doing=sample(index + 1) if index + 1 < outputs.stop else f"writing '{args.output}'")
    start = (cache.start if args.start is None else args.start) + outputs.start * cache.sampling
    stamp = None
    if args.chunk is not None or args.gaps is not None:  # a part of a job: merge checks what it is
        stamp = dict(job=_job_fingerprint(cache, samples, read, triangles, args), gaps=[gaps.start, gaps.stop],
                     key_gaps=plan.n_gaps, input=str(args.cache), step=args.step, speed=args.speed)
    write_pc2(args.output, poses, start=start, sampling=cache.sampling, stamp=stamp)
    _say(f"wrote {args.output}: {len(outputs)} of {plan.n_out} samples (key gaps {gaps.start}:{gaps.stop} "
         f"of {plan.n_gaps}), {cache.n_points} points, {progress.seconds()}")
    return 0


def _say(text: str) -> None:
    """Print ``text`` on stdout with what its encoding cannot hold escaped, as Python escapes it on
    stderr: a file name whose bytes are no text in the system's encoding (a Latin-1 name on a UTF-8
    worker) would otherwise end the command with a traceback and status 1 after its file is written."""
    encoding = getattr(sys.stdout, "encoding", None) or "utf-8"
    print(text.encode(encoding, "backslashreplace").decode(encoding))


def _warning(command: str, text: str, kind: str | None = None) -> None:
    """Print the warning ``text`` on stderr as one line a farm's log search finds,
    ``<command>: warning [<kind>]: <text>`` for a warning of that kind (:data:`core.errors.KINDS`;
    ``<command>: warning: <text>`` for a warning without one, which the core does not give): the
    output is written (exit status 0), but worth a look."""
    _line(f"{command}: warning{f' [{kind}]' if kind else ''}: {' '.join(text.split())}")


def _warnings_summary(command: str, shown: list[ShapeDifferenceWarning]) -> str | None:
    """The line that ends a command's warnings ``shown`` (None for none): how many of each kind
    (``other`` for those without one) and the gap whose in-between keeps the most flipped or
    collapsed triangles, ``<command>: 3 warning(s): 3 pose; most flipped or collapsed triangles
    kept: 121, between sample 17 (frame 16) and sample 33 (frame 32)``."""
    if not shown:
        return None
    counts: dict[str, int] = {}
    for warning in shown:
        kind = getattr(warning, "kind", None) or "other"
        counts[kind] = counts.get(kind, 0) + 1
    line = f"{command}: {len(shown)} warning(s): {', '.join(f'{n} {kind}' for kind, n in counts.items())}"
    worst = max(shown, key=lambda w: getattr(w, "defects", 0))  # the first of the most
    if getattr(worst, "defects", 0) > 0:
        gap = getattr(worst, "gap", None)
        line += f"; most flipped or collapsed triangles kept: {worst.defects}" + \
            (f", between {gap[0]} and {gap[1]}" if gap else "")
    return line


@contextmanager
def _warnings_as_lines(command: str):
    """The core's :class:`ShapeDifferenceWarning` (a fallback, a mirrored piece) said as the
    command's own warnings (:func:`_warning`, with the warning's ``kind``) while in the block,
    each message once, whatever Python's warning filters say, and a line of how many of each kind
    there were at its end (:func:`_warnings_summary`): ``PYTHONWARNINGS=error`` in a studio's
    environment would otherwise end a finished retime with a traceback and status 1, and Python's
    own format (a source file, a line number, a line of code) is not what a farm's log search
    looks for."""
    shown = warnings.showwarning
    said: list[ShapeDifferenceWarning] = []  # those shown, for the line that ends them

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, ShapeDifferenceWarning):
            kind = getattr(message, "kind", None)
            _warning(command, str(message), kind)
            said.append(message)
        else:  # Python's own format, whole beside the heartbeat's lines
            whole(shown, message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.simplefilter("default", ShapeDifferenceWarning)
        warnings.showwarning = show
        yield
    summary = _warnings_summary(command, said)
    if summary:
        _line(summary)


class _Cancelled(SystemExit):
    """SIGTERM received: the command stops (:func:`_stop_cleanly_on_sigterm`)."""


def _terminated(signum, _frame):
    raise _Cancelled(128 + signum)


@contextmanager
def _stop_cleanly_on_sigterm():
    """SIGTERM (how a farm cancels a task before it kills it) raised as :class:`SystemExit` while
    in the block, so that a file being written is removed (``core.atomic_files.write_atomically``)
    rather than left half written beside the output, and the exit status is 128 + 15. Python's own
    handling of SIGTERM ends the process on the spot."""
    if threading.current_thread() is not threading.main_thread():  # only the main thread may set handlers
        yield
        return
    previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    with _stop_cleanly_on_sigterm(), _warnings_as_lines(args.command):
        return _run(args)


def _local_path(text: str) -> str:
    """The file name ``text`` given on the command line as this command opens it: a leading ``~``
    (``~/caches/x.pc2``, ``~anna/…``) is the home folder, as in a shell, since a job runner passes
    its arguments without one. Raises :class:`ShapeDifferenceError` for a name no shell or job
    means as it reads: a path relative to a saved .blend (``//caches/x.pc2``, Blender's notation;
    on Linux and macOS it names a folder at the root of the disk), and one with a folder named
    ``~`` that does not exist (a ``~`` not expanded: OpenJD makes ``~/x.pc2`` into
    ``<its working folder>/~/x.pc2``; written, it would make a folder named ``~`` there), and a
    Windows path on Linux or macOS or a ``~user`` of no user (:func:`core.point_cache.foreign_path`)."""
    if os.name != "nt" and text.startswith("//"):  # on Windows, //server/share is a network path
        raise ShapeDifferenceError(
            f"'{text}' is relative to a saved .blend (Blender's '//'), and `python -m core` has no .blend: "
            f"here it would name '/{text.lstrip('/')}' at the root of the disk. Give the path from the working "
            "folder or in full.")
    foreign = foreign_path(text)
    if foreign:
        raise ShapeDifferenceError(f"{foreign}.")
    path = os.path.expanduser(text)
    parts = Path(path).parts
    for index, part in enumerate(parts):
        if part == "~" and not os.path.lexists(os.path.join(*parts[:index + 1])):
            raise ShapeDifferenceError(
                f"'{text}' has a folder named '~' that does not exist: the '~' was not made the home folder "
                "(a job template or script passed it without a shell, or without HOME set). Give the path "
                "in full.")
    return path


def _run(args) -> int:
    try:
        for name in ("cache", "topology", "output", "merged_output", "retime", "numbered"):
            if getattr(args, name, None) is not None:
                setattr(args, name, _local_path(getattr(args, name)))
        if args.command == "merge":
            args.parts = [_local_path(part) for part in args.parts]
        if args.command == "retime":
            return _retime(args)
        if args.command == "merge":
            parts = list(args.parts)
            if args.count is not None and not args.numbered:
                raise ShapeDifferenceError("--count N goes with --numbered PATTERN (the parts it numbers)")
            if args.numbered:
                parts += _numbered(args.numbered, args.count)
            # the retime's input and faces are read, never written: an output naming one (a job's
            # OutputCache set to its InputCache) would replace the simulation with its retime
            refuse_overwriting(args.output, {path: what for path, what in (
                (args.retime, "the input cache of the retime (--retime)"), (args.topology, "the topology OBJ"))
                if path is not None})
            _check_output(args.output, {})
            _check_parts_exist(parts)
            began = time.monotonic()
            merge_pc2(parts, args.output, job=_merged_job(args))
            n_points, start, sampling, n_samples = read_pc2_header(args.output)
            _say(f"wrote {args.output}: {n_samples} samples from frame {start:g} every {sampling:g}, "
                 f"{n_points} points, from {len(parts)} part(s), {time.monotonic() - began:.1f} s")
            return 0
        cache = read_point_cache(args.cache)
        if cache.times is None:
            timing = f"start {cache.start:g}, sampling {cache.sampling:g}"
        elif cache.n_samples == 0:
            timing = "MDD"
        else:  # an MDD's own times, in seconds
            times = cache.times
            spacing = (f", every {np.mean(np.diff(times)):.6g} s" if _even_times(times) else
                       ", not evenly spaced and increasing") if times.size > 1 else ""
            timing = f"MDD, times {times[0]:.6g} to {times[-1]:.6g} s{spacing}"
        _say(f"{args.cache}: {cache.n_samples} samples, {cache.n_points} points, {timing}")
        return 0
    except ShapeDifferenceError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"error: {args.command} ran out of memory on this machine: run it on one with more memory"
              + (", or split it with --chunk I/N" if args.command == "retime" else ""), file=sys.stderr)
        return 2
    except OSError as error:  # a file that cannot be read or written: its name and why
        where = f"'{error.filename}': " if error.filename else ""
        print(f"error: {where}{error.strerror or error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl+C: a user's stop, not a failure to report (the writes are atomic)
        print(f"{args.command}: interrupted (Ctrl+C), nothing written", file=sys.stderr)
        return 130
    except _Cancelled as cancelled:  # SIGTERM: a farm's cancel, said in the task's log (the writes are atomic)
        print(f"{args.command}: cancelled (SIGTERM), nothing written", file=sys.stderr, flush=True)
        return cancelled.code
    except Exception as error:  # a defect, not a refusal: its one line before Python's traceback (status 1)
        print(f"{args.command}: {unexpected_failure(error)}", file=sys.stderr, flush=True)
        raise


if __name__ == "__main__":
    sys.exit(main())
