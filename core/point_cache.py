"""Point caches: vertex positions per frame in the PC2 and MDD files that Blender's Mesh Cache
modifier plays and that Maya, Houdini, Cinema 4D and 3ds Max export.

Written by hand with :mod:`struct` and NumPy because both formats are a fixed header followed by
raw float32 samples, and no maintained PyPI package reads them without pulling in a DCC.

- PC2 (little-endian): ``b'POINTCACHE2\\0'``, int32 version (1), int32 point count, float32
  start frame, float32 sampling (frames per sample), int32 sample count; then float32 xyz per
  point per sample.
- MDD (big-endian): int32 frame count, int32 point count, float32 time per frame (seconds), then
  float32 xyz per point per frame.

A bad or truncated file raises :class:`core.MeshError` naming the file and what is wrong.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .atomic_files import write_atomically
from .errors import MeshError
from .validation import real_array

#: Bytes of samples :func:`merge_pc2` reads and writes at a time.
MERGE_BLOCK_BYTES = 16 << 20
#: The largest coordinate a PC2 or MDD file holds: its coordinates are single precision.
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: Added to a chunk's file name for its stamp (:func:`write_pc2`, ``stamp=``): the retime it is part
#: of, its key gaps and the SHA-256 of its bytes, which :func:`merge_pc2` checks.
STAMP_SUFFIX = ".json"
PC2_MAGIC = b"POINTCACHE2\0"
PC2_HEADER = struct.Struct("<12siiffi")
MDD_HEADER = struct.Struct(">ii")


@dataclass(frozen=True)
class PointCache:
    """Positions of one mesh over time.

    ``positions``: float32 ``(samples, points, 3)`` (a read-only memory map for files read from
    disk: index it to load only the samples you need). ``start``/``sampling``: frame of the first
    sample and frames between samples (PC2); ``times``: seconds per sample (MDD only, else None).
    """

    positions: np.ndarray
    start: float = 0.0
    sampling: float = 1.0
    times: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        return self.positions.shape[0]

    @property
    def n_points(self) -> int:
        return self.positions.shape[1]


def _check_samples_shape(shape: tuple) -> None:
    """Raise :class:`MeshError` unless ``shape`` is ``(samples, points, 3)`` with points."""
    if len(shape) != 3 or shape[2] != 3:
        raise MeshError(f"Point cache positions must have shape (samples, points, 3); got {shape}.")
    if shape[1] == 0:
        raise MeshError("A point cache needs at least one point; got 0.")


def _samples(positions) -> tuple[list, int]:
    """The samples of ``positions`` — a float ``(samples, points, 3)`` array, a sequence of
    ``(points, 3)`` poses, or one pose (one sample) — and their point count, checked (shape, one
    point count, finite coordinates) without copying them: the writer converts one sample at a
    time, so an output is not held twice while it is written."""
    what = "point cache positions"
    if isinstance(positions, np.ndarray) or not len(positions) or np.ndim(positions[0]) != 2:
        array = real_array(positions, "The point cache positions", what)
        if array.ndim == 2:
            array = array[None]
        shape = array.shape
        _check_samples_shape(shape)
        samples = list(array)  # views of the array
    else:
        samples = [real_array(pose, f"Point cache sample {index}", what) for index, pose in enumerate(positions)]
        shapes = {sample.shape for sample in samples}
        if len(shapes) > 1:
            raise MeshError(f"Point cache samples must all have one shape (points, 3); got {sorted(shapes)}.")
        shape = (len(samples), *samples[0].shape)
        _check_samples_shape(shape)
    for index, sample in enumerate(samples):
        if not np.isfinite(sample).all():
            raise MeshError(f"Point cache sample {index} has non-finite coordinates (NaN or inf).")
        # written as float32: beyond its range a coordinate would be stored as inf (reduced without a
        # temporary array: one sample is written at a time)
        largest = max(float(sample.max()), -float(sample.min())) if sample.size else 0.0
        if largest > FLOAT32_MAX:
            raise MeshError(f"Point cache sample {index} has a coordinate of {largest:.3g}, "
                            f"beyond the {FLOAT32_MAX:.3g} a PC2 file's single-precision coordinates hold (it "
                            "would be stored as infinite). Scale the positions down.")
    return samples, shape[1]


def refuse_overwriting(path, inputs: dict) -> None:
    """Raise :class:`MeshError` if the output ``path`` is one of the files ``inputs`` ({path: what
    it is}) a job reads: writing it would replace what the job was run on."""
    for source, what in inputs.items():
        try:
            same = Path(path).exists() and Path(source).exists() and os.path.samefile(path, source)
        except OSError:
            same = False
        if same or Path(os.path.abspath(path)) == Path(os.path.abspath(source)):
            raise MeshError(f"The output '{path}' is {what} ('{source}'): writing it would replace the "
                            "data the job reads. Give another output file.")


def pc2_header(n_points: int, n_samples: int, start: float = 0.0, sampling: float = 1.0) -> bytes:
    """The 32-byte PC2 header."""
    return PC2_HEADER.pack(PC2_MAGIC, 1, int(n_points), float(start), float(sampling), int(n_samples))


def check_pc2_timing(start: float, sampling: float) -> None:
    """Raise :class:`MeshError` unless ``start`` and ``sampling`` fit a PC2 header: finite in
    single precision, the sampling positive."""
    with np.errstate(over="ignore"):
        fits = np.isfinite(np.float32(start)) and np.isfinite(np.float32(sampling))
    if not (fits and sampling > 0):
        raise MeshError(f"A PC2 file's start frame must be a finite single-precision number and its sampling "
                        f"positive; got start {start}, sampling {sampling}.")


#: The start of a Windows drive or network path (``C:\\caches``, ``D:/shots``, ``\\\\server\\share``).
WINDOWS_PATH = re.compile(r"^(?:[A-Za-z]:[\\/]|\\\\)")


def foreign_path(text: str, relative_to: str = "the current folder") -> str | None:
    """Why the file name ``text``, as given, names on this machine another place than it says, in
    the user's words, or None: a Windows drive or network path on Linux or macOS (``C:\\caches\\x.pc2``,
    as a .blend or a script made on Windows keeps it, is there a file of that name in the current
    folder), and a leading ``~user`` for a user this machine does not have (``~anna/x.pc2`` is
    then a folder named ``~anna`` in the current folder). Written, either would put the file
    where nobody looks, and report success. ``relative_to``: the folder a relative path is read
    from, as the message names it."""
    if os.name != "nt" and WINDOWS_PATH.match(text):
        return (f"'{text}' is a Windows path, which this system reads as the name of a file in {relative_to}: "
                "give a path of this machine")
    if text.startswith("~") and os.path.expanduser(text) == text:
        user = text[1:].split("/", 1)[0]
        return (f"'{text}' starts in the home folder of '{user}', a user this machine does not have, so it would "
                f"be a folder named '~{user}' in {relative_to}: give the path in full")
    return None


def unwritable(path) -> str | None:
    """Why a new file ``path`` cannot be written (its folders are made as needed), in the user's
    words, or None: the nearest existing folder on its way is a file, not writable, or on a
    read-only file system (where its permissions say it is writable)."""
    existing = _nearest_folder(path)
    if not existing.is_dir():
        return f"'{existing}' is a file, not a folder"
    if not os.access(existing, os.W_OK | os.X_OK):
        # a folder on a read-only mount (a farm's asset share, a snapshot) has its permissions all the same
        if hasattr(os, "statvfs") and os.statvfs(existing).f_flag & os.ST_RDONLY:
            return f"the folder '{existing}' is on a read-only file system"
        return f"the folder '{existing}' is not writable (Permission denied)"
    return None


def _nearest_folder(path) -> Path:
    """The nearest folder on the way to a new file ``path`` that exists (its folders are made as needed)."""
    existing = Path(path).parent
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    return existing


def free_space(folder) -> int | None:
    """Bytes this process may still write on the file system holding ``folder`` (an existing folder),
    or None where the file system reports no size (some network and FUSE mounts say 0 blocks of 0,
    or fail the query: ENOSYS where a FUSE mount does not implement it, ESTALE on a stale NFS
    handle): what is free for ordinary users, all that is free for root, who may use the blocks
    kept back. The space is advisory (:func:`check_disk_space`), so a query that fails leaves the
    write to say what is wrong."""
    try:
        if not hasattr(os, "statvfs"):  # Windows
            usage = shutil.disk_usage(folder)
            return usage.free if usage.total > 0 else None
        stats = os.statvfs(folder)
    except OSError:
        return None
    if stats.f_blocks == 0:
        return None
    free = stats.f_bfree if hasattr(os, "geteuid") and os.geteuid() == 0 else stats.f_bavail
    return free * stats.f_frsize


def pc2_size(n_points: int, n_samples: int) -> int:
    """Bytes of a PC2 file of ``n_samples`` samples of ``n_points`` points."""
    return PC2_HEADER.size + int(n_samples) * int(n_points) * 12


def check_disk_space(path, n_bytes: int) -> None:
    """Raise :class:`MeshError` where the file system that would hold a new file ``path`` of
    ``n_bytes`` has less free space than that, before the work that computes it: a full disk is
    otherwise found when the file is written, after all of that work (minutes of a farm node's CPU).
    The file is written beside any old one and then renamed over it, so its whole size is needed
    also where it replaces a file. Unchecked where the file system reports no size (:func:`free_space`)."""
    folder = _nearest_folder(path)
    free = free_space(folder)
    if free is not None and n_bytes > free:
        raise MeshError(f"Cannot write '{path}': it takes {_size_text(n_bytes)} and the disk holding '{folder}' "
                        f"has {_size_text(free)} free. Free some space there or give an output on another disk.")


def _size_text(n_bytes: int) -> str:
    """``n_bytes`` as a TD reads a file's size: MB to three digits below a gigabyte, GB to a tenth
    from there (a 100k-vertex retime's output is gigabytes: "12.0 GB", not "1.2e+04 MB")."""
    return f"{n_bytes / 1e6:.3g} MB" if n_bytes < 999.5e6 else f"{n_bytes / 1e9:,.1f} GB"  # 999.5 MB: "1e+03" in .3g


def check_pc2_name(path) -> None:
    """Raise :class:`MeshError` for an output name no PC2 can be written to: empty, a folder, or
    named ``.mdd`` (the writers here write PC2, which a reader would take for an MDD by its name).
    The writers call it, and so does a command before its work, which these names would waste."""
    if not str(path).strip():
        raise MeshError("The output file name is empty: give one (such as out.pc2).")
    if str(path).endswith(("/", os.sep)) or Path(path).is_dir():
        raise MeshError(f"'{path}' is a folder, not a file: give the output a file name (such as out.pc2).")
    if Path(path).suffix.lower() == ".mdd":
        raise MeshError(f"'{path}' is named as an MDD file, but the output is PC2: name it .pc2.")


def write_pc2(path, positions, *, start: float = 0.0, sampling: float = 1.0, stamp: dict | None = None,
              exclusive: bool = False) -> Path:
    """Write float ``(samples, points, 3)`` positions (an array or a sequence of ``(points, 3)``
    poses; or one ``(points, 3)`` pose) as a PC2 file, one sample at a time.

    ``start`` is the frame of the first sample, ``sampling`` the frames between samples. The file
    appears complete or not at all. Returns the path.

    ``stamp``: for a chunk of a job, ``{"job": fingerprint, "gaps": [a, b], "key_gaps": n, ...}``,
    written after the file to ``path + STAMP_SUFFIX`` with the SHA-256 of the bytes written here
    (not read back: another job writing the same name meanwhile would be vouched for); where the
    stamp cannot be written (a full disk) the file is removed again, so that a failed or cancelled
    chunk leaves nothing. :func:`merge_pc2` refuses chunks whose stamps disagree.

    ``exclusive``: raise :class:`FileExistsError` rather than replace a file at ``path``, checked
    when the file is complete (:func:`core.atomic_files.write_atomically`).
    """
    samples, n_points = _samples(positions)
    check_pc2_timing(start, sampling)
    check_pc2_name(path)
    digest = hashlib.sha256() if stamp is not None else None

    def blocks():  # the header, then each sample as little-endian float32 (one copy at a time)
        yield pc2_header(n_points, len(samples), start, sampling)
        for sample in samples:
            yield memoryview(np.ascontiguousarray(sample, dtype="<f4")).cast("B")

    def hashed(chunks):  # the chunks as written, their SHA-256 taken on the way
        for chunk in chunks:
            digest.update(chunk)
            yield chunk

    write_atomically(path, blocks() if digest is None else hashed(blocks()), exclusive=exclusive)
    if stamp is not None:
        text = json.dumps({**stamp, "sha256": digest.hexdigest()}, indent=1) + "\n"
        try:
            write_atomically(stamp_path(path), [text.encode()])
        except BaseException:  # a disk full, SIGTERM: a chunk without its stamp is not left as if written
            Path(path).unlink(missing_ok=True)
            raise
    return Path(path)


def stamp_path(path) -> Path:
    """The stamp file of the chunk ``path``."""
    return Path(f"{path}{STAMP_SUFFIX}")


def read_stamp(path) -> dict | None:
    """The stamp of the chunk ``path`` (:func:`write_pc2`), or None where it has none."""
    try:
        text = stamp_path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    try:
        stamp = json.loads(text)
        job, (first, stop), key_gaps, sha256 = stamp["job"], stamp["gaps"], stamp["key_gaps"], stamp["sha256"]
        if not (isinstance(job, str) and isinstance(sha256, str) and 0 <= first <= stop <= key_gaps):
            raise ValueError
    except (ValueError, TypeError, KeyError):
        raise MeshError(f"'{stamp_path(path)}' is not the stamp of a chunk (cut off, or edited?): run the "
                        f"chunk that writes '{path}' again.") from None
    return stamp


def check_stamps(parts, stamps, job: str | None = None) -> None:
    """Raise :class:`MeshError` unless the chunks ``parts`` with their ``stamps`` (None for a file
    without one) are all the chunks of one job, in order: one job fingerprint, key gaps that follow
    one another from the first to the last. Files without stamps (caches not written as chunks)
    are not checked here; a mix of both is refused.

    ``job``: the fingerprint of the retime the merge is for (``python -m core merge --retime``);
    every part must then be a stamped chunk of it. Without it the parts need only agree among
    themselves, which another job's complete set of chunks in a shared folder does."""
    if job is not None:
        for part, stamp in zip(parts, stamps):
            if stamp is None or stamp["job"] != job:
                folder = Path(part).parent
                raise MeshError(
                    f"'{part}' is not a chunk of this job's retime ("
                    + ("it has no stamp" if stamp is None else "another input cache, topology or setting")
                    + f"): another job has written into the chunk folder '{folder}'"
                    + ("" if stamp is None else ", or the input cache or topology was written over since the "
                       "chunk was computed")
                    + ". Give each job a chunk folder of its own (one per shot and take) and run this job's "
                    "chunks again.")
    if all(stamp is None for stamp in stamps):
        return
    unstamped = [part for part, stamp in zip(parts, stamps) if stamp is None]
    if unstamped:
        raise MeshError(f"'{unstamped[0]}' has no stamp ('{stamp_path(unstamped[0])}') as the other parts do: "
                        "it is no chunk of their job. Run its chunk again.")
    first = stamps[0]
    expected = 0
    for part, stamp in zip(parts, stamps):
        if stamp["job"] != first["job"] or stamp["key_gaps"] != first["key_gaps"]:
            raise MeshError(
                f"'{part}' is a chunk of another retime than '{parts[0]}' (another input, topology or "
                "setting): two jobs wrote into one chunk folder? Give each job a chunk folder of its own "
                "and run its chunks again.")
        if stamp["gaps"][0] != expected:
            raise MeshError(f"'{part}' holds key gaps {stamp['gaps'][0]}:{stamp['gaps'][1]}, but the parts "
                            f"before it end at gap {expected}: give every chunk once, in order.")
        expected = stamp["gaps"][1]
    if expected != first["key_gaps"]:
        raise MeshError(f"The parts hold key gaps 0:{expected} of the retime's {first['key_gaps']}: the "
                        "last chunk(s) are missing. Give every chunk, in order.")


def _file_size_check(path: Path, header: int, coordinates: int, what: str, at_least: bool = False,
                     counts: str = "") -> None:
    """Raise :class:`MeshError` unless ``path`` has the ``header`` bytes and the ``coordinates``
    bytes (float32) its header promises (``at_least``: or more). The message says what the size
    points to: a file cut short; coordinates in double precision (twice the bytes: a package's
    float64 export, which PC2 and MDD do not hold); or more data than the header counts
    (``counts``: the header's counts in words, such as "9 samples of 25 points")."""
    expected = header + coordinates
    size = path.stat().st_size
    if size == expected or (size > expected and at_least):
        return
    if size < expected:
        raise MeshError(
            f"'{path}' is not a complete {what}: its header promises {expected} bytes, the file has "
            f"{size}. Export the cache again (the file may have been cut off while copying)."
        )
    if coordinates and size == header + 2 * coordinates:
        raise MeshError(
            f"'{path}' holds its coordinates in double precision (8 bytes each: the file has {size} bytes, "
            f"twice the {coordinates} of its {counts} in single precision), but {what}s hold them in single "
            "precision (float32): export the cache again as float32.")
    raise MeshError(
        f"'{path}' is longer than its header says: {counts} take {expected} bytes, the file has {size}. "
        "The header's counts are wrong (a writer that stopped before updating them?) or the file is of "
        "another kind: export the cache again.")


def read_pc2(path) -> PointCache:
    """Read a PC2 file; positions are a read-only float32 memory map ``(samples, points, 3)``."""
    path = Path(path)
    n_points, start, sampling, n_samples = read_pc2_header(path)
    positions = (np.memmap(path, dtype="<f4", mode="r", offset=PC2_HEADER.size, shape=(n_samples, n_points, 3))
                 if n_samples else np.empty((0, n_points, 3), dtype="<f4"))
    return PointCache(positions, start, sampling)


def read_pc2_header(path, whole: bool = True) -> tuple[int, float, float, int]:
    """``(points, start, sampling, samples)`` of a PC2 file, its header checked against its size
    (``whole=False``: bytes after the samples are allowed, as Blender's Mesh Cache ignores them)."""
    path = Path(path)
    with open(path, "rb") as stream:
        header = stream.read(PC2_HEADER.size)
    if len(header) < PC2_HEADER.size or header[:11] != PC2_MAGIC[:11]:
        raise MeshError(f"'{path}' is not a PC2 point cache (it does not start with 'POINTCACHE2').")
    _magic, version, n_points, start, sampling, n_samples = PC2_HEADER.unpack(header)
    if version != 1 and struct.unpack(">i", header[12:16])[0] == 1:
        raise MeshError(f"'{path}' is a PC2 file written big-endian (its header reads version 1 byte-swapped), but "
                        "PC2 files are little-endian, as Blender, Maya and 3ds Max read and write them: export it "
                        "again as a standard PC2.")
    if version != 1 or n_points <= 0 or n_samples < 0 or not np.isfinite([start, sampling]).all() or sampling <= 0:
        raise MeshError(
            f"'{path}' has an invalid PC2 header (version {version}, {n_points} points, {n_samples} "
            f"samples, start {start}, sampling {sampling})."
        )
    _file_size_check(path, PC2_HEADER.size, 12 * n_points * n_samples, "PC2 file", at_least=not whole,
                     counts=f"{n_samples} samples of {n_points} points")
    return n_points, float(start), float(sampling), n_samples


def read_mdd_header(path, whole: bool = True) -> tuple[int, np.ndarray]:
    """``(points, times)`` of an MDD file: its point count and its frames' times (seconds, float64),
    the header checked against the file's size (``whole=False``: bytes after the frames are
    allowed, as Blender's Mesh Cache ignores them)."""
    path = Path(path)
    with open(path, "rb") as stream:
        header = stream.read(MDD_HEADER.size)
        if len(header) < MDD_HEADER.size:
            raise MeshError(f"'{path}' is not an MDD point cache (shorter than its 8-byte header).")
        n_frames, n_points = MDD_HEADER.unpack(header)
        swapped = struct.unpack("<ii", header)
        if not _mdd_fits(path, n_frames, n_points, whole) and _mdd_fits(path, *swapped, whole):
            raise MeshError(f"'{path}' is an MDD file written little-endian (its header fits the file only read "
                            f"so: {swapped[0]} frames of {swapped[1]} points), but MDD files are big-endian, as "
                            "Blender, Maya and LightWave read and write them: export it again as a standard MDD.")
        if n_frames < 0 or n_points <= 0:
            raise MeshError(f"'{path}' has an invalid MDD header ({n_frames} frames, {n_points} points).")
        _file_size_check(path, MDD_HEADER.size + 4 * n_frames, 12 * n_points * n_frames, "MDD file",
                         at_least=not whole, counts=f"{n_frames} frames of {n_points} points")
        return n_points, np.frombuffer(stream.read(4 * n_frames), dtype=">f4").astype(np.float64)


def _mdd_fits(path: Path, n_frames: int, n_points: int, whole: bool) -> bool:
    """Whether an MDD header of ``n_frames`` frames of ``n_points`` points fits the size of ``path``."""
    if n_frames < 0 or n_points <= 0:
        return False
    expected, size = MDD_HEADER.size + 4 * n_frames + 12 * n_points * n_frames, path.stat().st_size
    return size == expected or (size > expected and not whole)


def read_mdd(path) -> PointCache:
    """Read an MDD file (big-endian); ``times`` are its per-frame times in seconds and
    ``positions`` float32 ``(frames, points, 3)`` in native byte order."""
    path = Path(path)
    n_points, times = read_mdd_header(path)
    n_frames = len(times)
    with open(path, "rb") as stream:
        stream.seek(MDD_HEADER.size + 4 * n_frames)
        positions = np.frombuffer(stream.read(), dtype=">f4").reshape(n_frames, n_points, 3).astype("<f4")
    return PointCache(positions, times=times)


def has_pc2_signature(path) -> bool:
    """Whether the file ``path`` starts as a PC2 does (``'POINTCACHE2'``; MDD has no signature)."""
    with open(path, "rb") as stream:
        return stream.read(11) == PC2_MAGIC[:11]


def read_point_cache(path) -> PointCache:
    """Read a PC2 or MDD file, told apart by the PC2 signature (MDD has none); a file named
    ``.pc2`` without the signature, an empty one, or one that is neither, raises :class:`MeshError`."""
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"'{path}' does not exist or is not a file.")
    if path.stat().st_size == 0:
        raise MeshError(f"'{path}' is empty: export the cache again.")
    if has_pc2_signature(path):
        return read_pc2(path)
    if path.suffix.lower() == ".pc2":  # named PC2 but not one: say so rather than read it as MDD
        raise MeshError(f"'{path}' is not a PC2 point cache (it does not start with 'POINTCACHE2'): "
                        "export it again as PC2, or give an MDD file its .mdd name.")
    try:
        return read_mdd(path)
    except MeshError:
        if path.suffix.lower() == ".mdd":
            raise
        # neither kind (an OBJ or Alembic file given as the cache): say that, not an MDD header's size
        raise MeshError(f"'{path}' is not a point cache: neither PC2 (it does not start with 'POINTCACHE2') "
                        "nor MDD (its header does not match its size). Give a .pc2 or .mdd file.") from None


def merge_pc2(parts, path, job: str | None = None) -> Path:
    """Concatenate PC2 files whose samples follow one another (chunks of one job) into ``path``.

    Every part must have the same point count and sampling, and each must start where the one
    before ends (within a hundredth of a sample and one single-precision step at the frame's size:
    the starts are single precision, a missing part is a whole sample or more); parts without
    samples are allowed. Chunks written with stamps
    (``python -m core retime --chunk``) must be every chunk of one job, in order
    (:func:`check_stamps`), each with the bytes its stamp names; given the ``job`` fingerprint,
    chunks of that job only. The samples are copied byte for byte, :data:`MERGE_BLOCK_BYTES` at a
    time.
    """
    check_pc2_name(path)
    refuse_overwriting(path, {part: "one of the parts to merge" for part in parts})
    headers = [(Path(part), *read_pc2_header(part)) for part in parts]  # (path, points, start, sampling, samples)
    stamps = [read_stamp(part) for part in parts]
    check_stamps(parts, stamps, job)
    if not headers:
        raise MeshError("Nothing to merge: give at least one PC2 file.")
    first_path, n_points, first_start, sampling, _ = headers[0]
    expected_start = first_start
    for (part, points, start, part_sampling, samples), stamp in zip(headers, stamps):
        if points != n_points or part_sampling != sampling:
            raise MeshError(
                f"'{part}' has {points} points at sampling {part_sampling}, but '{first_path}' has "
                f"{n_points} at {sampling}: these are not chunks of one cache."
            )
        # Both starts are single-precision roundings of their frames (this one's, and the part
        # before's, from which the expected one is counted), so they may differ by one
        # single-precision step at their size (0.0078 at frame 100,000) on top of the hundredth of
        # a sample the sampling's own rounding adds up to; a missing or repeated sample is a whole one.
        step = float(np.spacing(np.float32(max(abs(start), abs(expected_start)))))
        slack = 0.01 * sampling + step
        if abs(start - expected_start) > slack:
            raise MeshError(
                f"'{part}' starts at frame {start:.8g}, expected {expected_start:.8g} (where the part before "
                "ends): give the chunks in order, with none missing."
            )
        if stamp is None and sampling - step <= slack:  # a sample missing would be within the slack
            raise MeshError(
                f"'{part}' starts at frame {start:.8g}, where a PC2's single-precision start frame cannot tell "
                f"one sample from the next (every {sampling:.8g} frames), so whether a part is missing cannot "
                "be checked: merge the chunks `retime --chunk` writes (with their stamps), or retime with an "
                "earlier --start.")
        expected_start = start + samples * sampling
    header = pc2_header(n_points, sum(samples for *_, samples in headers), first_start, sampling)

    def blocks():  # the parts' samples read a block at a time: never the whole output in memory
        yield header
        for (part, *_), stamp in zip(headers, stamps):
            digest = hashlib.sha256()
            with open(part, "rb") as stream:
                digest.update(stream.read(PC2_HEADER.size))
                while block := stream.read(MERGE_BLOCK_BYTES):
                    digest.update(block)
                    yield block
            if stamp is not None and digest.hexdigest() != stamp["sha256"]:  # the output is not kept
                raise MeshError(f"'{part}' is not the file its stamp '{stamp_path(part)}' describes: it was "
                                "written again since (by another job sharing the chunk folder?). Give each "
                                "job a chunk folder of its own and run its chunks again.")

    write_atomically(path, blocks())
    return Path(path)
